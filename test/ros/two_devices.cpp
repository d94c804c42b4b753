// Two supervised runs of two devices: see test/ros/two_devices.test.
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>

#include "stand_checks.h"

namespace fs = std::filesystem;

namespace {

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Every regular file of a directory, name -> content.
std::map<std::string, std::string> snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file()) files[e.path().filename().string()] = read_text(e.path());
  }
  return files;
}

struct RunFiles {
  fs::path dir;
  nlohmann::json supervise;  // supervise --json's document
};

RunFiles supervise(const std::string& device, const fs::path& output_dir, double timeout_s) {
  const fs::path json = output_dir / ("supervise_" + device + ".json");
  const std::string command = "rosrun accel_intrinsics supervise --quiet --device " + device +
                              " --timeout " + std::to_string(timeout_s) + " --json " +
                              json.string();
  const stand_checks::CommandResult r = stand_checks::run(command);
  EXPECT_EQ(r.exit_code, 0) << command << "\n" << r.output;
  RunFiles run;
  const fs::path latest = output_dir / device / "latest";
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(latest))) << latest;
  if (fs::exists(latest)) run.dir = fs::canonical(latest);
  if (fs::exists(json)) run.supervise = nlohmann::json::parse(read_text(json));
  return run;
}

void expect_complete(const RunFiles& run, const std::string& device, int steps) {
  ASSERT_FALSE(run.dir.empty()) << device;
  // output_dir/<device>/<UTC time, ISO 8601 basic>
  EXPECT_EQ(run.dir.parent_path().filename(), device);
  EXPECT_TRUE(std::regex_match(run.dir.filename().string(), std::regex(R"(\d{8}T\d{6}Z(-\d+)?)")))
      << run.dir;
  for (const char* name :
       {"result.json", "intrinsics.yaml", "position_table.csv", "calibration_state.yaml"}) {
    EXPECT_TRUE(fs::exists(run.dir / name)) << run.dir / name;
  }
  const nlohmann::json result = nlohmann::json::parse(read_text(run.dir / "result.json"));
  // Every dwell of the run in its table: N per phase (config/protocol.yaml has no closing
  // position here), as many as the fit used.
  const std::size_t rows = stand_checks::count_csv_rows((run.dir / "position_table.csv").string());
  EXPECT_GE(rows, static_cast<std::size_t>(3 * steps)) << run.dir;
  EXPECT_EQ(rows, result["positions"]["x"].get<std::size_t>() +
                      result["positions"]["y"].get<std::size_t>() +
                      result["positions"]["z"].get<std::size_t>())
      << run.dir;
  EXPECT_EQ(result["device_serial"], device);
  EXPECT_TRUE(result["quality"]["pass"].get<bool>()) << result["quality"].dump();
  EXPECT_TRUE(std::regex_match(result["time_utc"].get<std::string>(),
                               std::regex(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ)")));
  EXPECT_EQ(result["gimbal_driver"], "simulated");
  EXPECT_EQ(result["imu_topic"], "/imu/data_raw");
  const YAML::Node yaml = YAML::LoadFile((run.dir / "intrinsics.yaml").string());
  EXPECT_EQ(yaml["device_serial"].as<std::string>(), device);
  EXPECT_EQ(yaml["responsivity"]["u"].as<double>(), result["responsivity"]["u"].get<double>());
  // supervise --json prints result.json's document, not a format of its own.
  ASSERT_TRUE(run.supervise.contains("rigs")) << run.supervise.dump();
  const nlohmann::json& rig = run.supervise["rigs"]["/"];
  EXPECT_TRUE(rig["success"].get<bool>()) << rig.dump();
  EXPECT_EQ(rig["result"], result) << "supervise --json differs from " << run.dir / "result.json";
  EXPECT_EQ(fs::path(rig["result_file"].get<std::string>()), run.dir / "result.json");
}

TEST(TwoDevices, EachRunKeepsItsOwnCompleteDirectory) {
  ros::NodeHandle pnh("~");
  std::string output_dir;
  int steps = 6;
  double timeout_s = 180.0;
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  pnh.getParam("steps", steps);
  pnh.getParam("timeout_s", timeout_s);
  // No run of an earlier invocation of this test.
  for (const char* device : {"A", "B"}) fs::remove_all(fs::path(output_dir) / device);
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(60.0)));
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/start", ros::Duration(60.0)));

  const RunFiles a = supervise("A", output_dir, timeout_s);
  expect_complete(a, "A", steps);
  if (HasFatalFailure()) return;
  const std::map<std::string, std::string> a_files = snapshot(a.dir);

  const RunFiles b = supervise("B", output_dir, timeout_s);  // resets the node first
  expect_complete(b, "B", steps);
  if (HasFatalFailure()) return;
  EXPECT_NE(a.dir, b.dir);
  // A's run is whole and unchanged after B's reset and run.
  EXPECT_EQ(snapshot(a.dir), a_files) << a.dir;
  EXPECT_EQ(fs::canonical(fs::path(output_dir) / "A" / "latest"), a.dir);
  // The two results are two fits (two runs), not one file written twice.
  EXPECT_NE(read_text(a.dir / "position_table.csv"), read_text(b.dir / "position_table.csv"));
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "two_devices_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
