// The budget file (the shipped config and bad files) and the result's `uncertainty_budget` key:
// the structure of docs/design.md section 9, the same in JSON and YAML, read back for comparisons.
#include "accel_intrinsics/io/budget_file.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "../support/random_device.h"
#include "../support/source_dir.h"
#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {
namespace {

using namespace core;

std::string temp_file(const std::string& name, const std::string& text) {
  const std::string path = "/tmp/budget_file_test_" + std::to_string(::getpid()) + "_" + name;
  std::ofstream(path) << text;
  return path;
}

TEST(BudgetFile, ShippedConfigReadsWithItsCertificateBlock) {
  const io::BudgetFile f = io::read_budget_file(accel_intrinsics::test_support::source_dir() +
                                                "/config/uncertainty_budget.yaml");
  // Cross-check with yaml-cpp directly, so the test does not depend on the values chosen.
  const YAML::Node raw = YAML::LoadFile(f.path);
  EXPECT_EQ(f.spec.gravity_std_rel, raw["gravity_std_rel"].as<double>());
  EXPECT_EQ(f.spec.angle_random_std_deg, raw["angle_random_std_deg"].as<double>());
  EXPECT_EQ(f.spec.angle_offset_std_deg, raw["angle_offset_std_deg"].as<double>());
  EXPECT_EQ(f.spec.angle_scale_std, raw["angle_scale_std"].as<double>());
  EXPECT_EQ(f.spec.axis_tilt_std_deg, raw["axis_tilt_std_deg"].as<double>());
  EXPECT_EQ(f.spec.mount_misalignment_std_deg, raw["mount_misalignment_std_deg"].as<double>());
  EXPECT_EQ(f.spec.samples, raw["samples"].as<int>());
  ASSERT_FALSE(f.certificate.empty());
  bool lab = false, serial = false;
  for (const auto& field : f.certificate) {
    lab = lab || (field.first == "lab" && !field.second.empty());
    serial = serial || (field.first == "serial" && !field.second.empty());
  }
  EXPECT_TRUE(lab);
  EXPECT_TRUE(serial);
}

TEST(BudgetFile, BadFilesAreRefusedNamingTheKey) {
  auto message = [](const std::string& text) {
    const std::string path = temp_file("bad.yaml", text);
    try {
      io::read_budget_file(path);
    } catch (const io::IoError& e) {
      std::remove(path.c_str());
      return std::string(e.what());
    }
    std::remove(path.c_str());
    return std::string("no error");
  };
  EXPECT_NE(message("axis_tilt_std_dg: 0.01\n").find("unknown key 'axis_tilt_std_dg'"),
            std::string::npos);
  EXPECT_NE(message("gravity_std_rel: lots\n").find("gravity_std_rel is not a number"),
            std::string::npos);
  EXPECT_NE(message("angle_offset_std_deg: -1\n").find("angle_offset_std_deg"), std::string::npos);
  EXPECT_NE(message("samples: 2.5\n").find("samples"), std::string::npos);
  EXPECT_NE(message("certificate: [1, 2]\n").find("certificate"), std::string::npos);
  EXPECT_NE(message("- 1\n").find("not a map"), std::string::npos);
  const std::string missing = "/nonexistent/budget.yaml";
  try {
    io::read_budget_file(missing);
    FAIL();
  } catch (const io::IoError& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos);
  }
}

core::CalibrationReport report_with_budget() {
  std::mt19937_64 rng(3);
  SimulationOptions sim;
  sim.truth = testing_devices::random_device(rng);
  sim.protocol.steps_per_phase = 12;
  const PositionTable table = simulate_position_table(sim);
  CalibrateOptions options;
  BudgetSpec spec;
  spec.gravity_std_rel = 1e-5;
  spec.angle_random_std_deg = 0.01;
  spec.axis_tilt_std_deg = 0.02;
  spec.samples = 200;
  options.budget = spec;
  return calibrate(table, nullptr, options);
}

void expect_triple(const nlohmann::json& j, const std::vector<std::string>& keys,
                   const Eigen::Vector3d& values, double scale) {
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j.size(), 3u);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(j.at(keys[i]).get<double>(), scale * values(i),
                1e-12 * std::abs(scale * values(i)) + 1e-300);
}

TEST(BudgetFile, ResultHasTheDesignStructureInJsonAndYamlAndReadsBack) {
  const CalibrationReport report = report_with_budget();
  ASSERT_TRUE(report.budget.has_value());
  io::ResultContext context;
  context.certificate = {{"lab", "Test Lab"}, {"serial", "42"}};
  context.gravity_source = "test";
  const nlohmann::json j = nlohmann::json::parse(io::result_json_text(report, context));
  const double deg = 180.0 / kPi;
  const std::vector<std::string> acc = {"u", "v", "w"}, ang = {"uv", "vw", "wu"};
  const nlohmann::json& b = j.at("uncertainty_budget");
  ASSERT_EQ(b.at("sources").size(), 4u);  // type_a, gravity, random angle, tilt
  EXPECT_EQ(b.at("sources")[0].at("name"), "type_a");
  for (std::size_t k = 0; k < report.budget->sources.size(); ++k) {
    const BudgetSource& s = report.budget->sources[k];
    const nlohmann::json& js = b.at("sources")[k];
    EXPECT_EQ(js.at("name"), s.name);
    expect_triple(js.at("responsivity_std"), acc, s.std.responsivity, 1.0);
    expect_triple(js.at("angles_std_deg"), ang, s.std.angles_rad, deg);
    expect_triple(js.at("offset_std"), acc, s.std.offset, 1.0);
  }
  expect_triple(b.at("combined_std").at("responsivity"), acc, report.budget->combined.responsivity,
                1.0);
  expect_triple(b.at("combined_std").at("angles_deg"), ang, report.budget->combined.angles_rad,
                deg);
  expect_triple(b.at("combined_std").at("offset"), acc, report.budget->combined.offset, 1.0);
  EXPECT_EQ(b.at("expanded").at("k"), 2.0);
  expect_triple(b.at("expanded").at("responsivity"), acc, report.budget->expanded.responsivity,
                1.0);
  expect_triple(b.at("expanded").at("angles_deg"), ang, report.budget->expanded.angles_rad, deg);
  expect_triple(b.at("expanded").at("offset"), acc, report.budget->expanded.offset, 1.0);
  // Type A in the budget is the result's own std.
  EXPECT_EQ(b.at("sources")[0].at("responsivity_std"), j.at("responsivity_std"));
  EXPECT_EQ(j.at("certificate").at("lab"), "Test Lab");
  EXPECT_EQ(j.at("local_gravity_source"), "test");

  // YAML: the same tree.
  const YAML::Node y = YAML::Load(io::result_yaml_text(report, context));
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(y["uncertainty_budget"]["expanded"]["angles_deg"][ang[i]].as<double>(),
              b.at("expanded").at("angles_deg").at(ang[i]).get<double>());
  }
  // Read back.
  const std::string path = temp_file("result.json", io::result_json_text(report, context));
  const io::StoredResult stored = io::read_result_file(path);
  std::remove(path.c_str());
  ASSERT_TRUE(stored.expanded.has_value());
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(stored.expanded->responsivity(i), report.budget->expanded.responsivity(i), 1e-15);
    EXPECT_NEAR(stored.expanded->angles_rad(i), report.budget->expanded.angles_rad(i), 1e-15);
    EXPECT_NEAR(stored.expanded->offset(i), report.budget->expanded.offset(i), 1e-15);
  }
  EXPECT_EQ(stored.coverage_factor, 2.0);
}

}  // namespace
}  // namespace accel_intrinsics
