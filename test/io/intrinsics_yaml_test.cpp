// intrinsics.yaml as a user's program reads it with yaml-cpp (docs/design.md section 15, "One
// result document"): the unit of every number (units block, output_unit), the ISO 8601 UTC time,
// the device serial, the IMU topic, the gimbal driver and the source of g; the same document as
// result.json (one writer).
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <nlohmann/json.hpp>
#include <regex>
#include <string>

#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {
namespace {

core::CalibrationReport report(const std::string& output_unit) {
  core::SimulationOptions sim;
  sim.seed = 11;
  core::CalibrateOptions options;
  options.output_unit = output_unit;
  return core::calibrate(core::simulate_position_table(sim), nullptr, options);
}

io::ResultContext node_context() {
  io::ResultContext c;
  c.stamp_s = 1234.5;
  c.device_serial = "SN-0042 \"left\"";  // a serial as users type them, quoted in YAML
  c.imu_topic = "/rig1/imu/data_raw";
  c.gimbal_driver = "smc100";
  c.time_utc = "2026-11-27T14:15:02Z";
  c.gravity_source = "parameter local_gravity";
  return c;
}

TEST(IntrinsicsYaml, CarriesUnitsTimeSerialTopicDriverAndGSource) {
  const YAML::Node y = YAML::Load(io::result_yaml_text(report("m/s^2"), node_context()));
  EXPECT_EQ(y["device_serial"].as<std::string>(), "SN-0042 \"left\"");
  EXPECT_EQ(y["imu_topic"].as<std::string>(), "/rig1/imu/data_raw");
  EXPECT_EQ(y["gimbal_driver"].as<std::string>(), "smc100");
  EXPECT_EQ(y["local_gravity_source"].as<std::string>(), "parameter local_gravity");
  const std::string t = y["time_utc"].as<std::string>();
  EXPECT_TRUE(std::regex_match(t, std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)"))) << t;
  // Quoted: a YAML 1.1 reader (PyYAML's safe_load, the archive's) would read a bare ISO time as
  // a date, which JSON cannot hold.
  EXPECT_NE(io::result_yaml_text(report("m/s^2"), node_context())
                .find("time_utc: \"2026-11-27T14:15:02Z\""),
            std::string::npos);
  EXPECT_EQ(y["output_unit"].as<std::string>(), "m/s^2");
  const YAML::Node units = y["units"];
  ASSERT_TRUE(units.IsMap());
  EXPECT_EQ(units["responsivity"].as<std::string>(), "m/s^2/(m/s^2)");
  EXPECT_EQ(units["offset"].as<std::string>(), "m/s^2");
  EXPECT_EQ(units["angles_deg"].as<std::string>(), "deg");
  EXPECT_EQ(units["local_gravity"].as<std::string>(), "m/s^2");
  // Every number group the units block names is in the document.
  for (auto it = units.begin(); it != units.end(); ++it) {
    const std::string key = it->first.as<std::string>();
    if (key == "noise_density" || key == "sample_rate_hz") continue;  // when the dwells tell
    EXPECT_TRUE(y[key]) << key << " has a unit but is not in the document";
  }
  EXPECT_GT(y["responsivity"]["u"].as<double>(), 0.5);
}

TEST(IntrinsicsYaml, UnitsFollowTheOutputUnit) {
  const YAML::Node y = YAML::Load(io::result_yaml_text(report("counts"), node_context()));
  EXPECT_EQ(y["output_unit"].as<std::string>(), "counts");
  EXPECT_EQ(y["units"]["responsivity"].as<std::string>(), "counts/(m/s^2)");
  EXPECT_EQ(y["units"]["offset"].as<std::string>(), "counts");
  EXPECT_EQ(y["units"]["cross_sensitivity"].as<std::string>(), "(m/s^2)/counts");
}

TEST(IntrinsicsYaml, TheSameDocumentAsResultJson) {
  const core::CalibrationReport r = report("m/s^2");
  const nlohmann::json j = nlohmann::json::parse(io::result_json_text(r, node_context()));
  const YAML::Node y = YAML::Load(io::result_yaml_text(r, node_context()));
  std::size_t keys = 0;
  for (auto it = y.begin(); it != y.end(); ++it) {
    EXPECT_TRUE(j.contains(it->first.as<std::string>())) << it->first.as<std::string>();
    ++keys;
  }
  EXPECT_EQ(keys, j.size());
  EXPECT_EQ(j["device_serial"], "SN-0042 \"left\"");
  EXPECT_DOUBLE_EQ(j["responsivity"]["v"].get<double>(), y["responsivity"]["v"].as<double>());
}

}  // namespace
}  // namespace accel_intrinsics
