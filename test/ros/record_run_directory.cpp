// record_run_directory.test: record.launch's bag lands in the run's own directory.
#include <dirent.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>

#include <cstdlib>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "offline_compare.h"
#include "run_dirs.h"

namespace oc = offline_compare;

namespace {

// The names in `dir` (without "." and "..").
std::vector<std::string> entries(const std::string& dir) {
  std::vector<std::string> names;
  DIR* d = opendir(dir.c_str());
  if (d == nullptr) return names;
  while (const dirent* e = readdir(d)) {
    const std::string name = e->d_name;
    if (name != "." && name != "..") names.push_back(name);
  }
  closedir(d);
  return names;
}

TEST(RecordRunDirectory, TheBagIsInTheRunsDirectory) {
  ros::NodeHandle pnh("~");
  std::string online_dir;
  double timeout_s = 200.0;
  ASSERT_TRUE(pnh.getParam("online_dir", online_dir));
  pnh.getParam("timeout_s", timeout_s);

  // The recorder's rosbag (<ns>/recorder_bag) and the calibration node hear the run from its
  // first command.
  const std::vector<std::string> topics = {"/gimbal/command", "/imu/data_raw"};
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(60.0);
  while (ros::WallTime::now() < deadline &&
         !(oc::subscribed("/recorder_bag", topics) && oc::subscribed("/calibration", topics) &&
           oc::subscribed("/recorder", {"/calibration/run_directory"}) &&
           ros::service::exists("/gimbal_controller/start", false))) {
    ros::WallDuration(0.2).sleep();
  }
  ASSERT_TRUE(oc::subscribed("/recorder_bag", topics)) << "rosbag not subscribed";
  ASSERT_TRUE(oc::subscribed("/recorder", {"/calibration/run_directory"}));
  ros::WallDuration(0.5).sleep();
  // Before the run: the bag waits in output_dir, no run directory yet.
  bool recording = false;
  const ros::WallTime opened_by = ros::WallTime::now() + ros::WallDuration(10.0);
  while (!recording && ros::WallTime::now() < opened_by) {
    for (const std::string& name : entries(online_dir))
      recording = recording || name.rfind(".recording-", 0) == 0;
    if (!recording) ros::WallDuration(0.2).sleep();
  }
  EXPECT_TRUE(recording) << "no .recording-*.bag in " << online_dir;
  EXPECT_FALSE(oc::file_exists(online_dir + "/unnamed")) << "a run directory before the run";

  std_srvs::Trigger start;
  ASSERT_TRUE(ros::service::call("/gimbal_controller/start", start));
  ASSERT_TRUE(start.response.success) << start.response.message;
  accel_intrinsics::IntrinsicResult online;
  std::string message;
  ASSERT_TRUE(oc::wait_for_result("/calibration/get_intrinsics", timeout_s, &online, &message))
      << message;
  ros::WallDuration(1.0).sleep();
  // What `rosnode kill` does. The answer is not checked: the recorder (rospy) may end before it
  // answers; the bag below says whether it stopped.
  oc::shutdown_node("/recorder");

  const std::string run = run_dirs::latest(online_dir);
  const std::string bag = run + "/run.bag";
  const ros::WallTime moved_by = ros::WallTime::now() + ros::WallDuration(30.0);
  while (ros::WallTime::now() < moved_by && !oc::file_exists(bag)) ros::WallDuration(0.2).sleep();
  ASSERT_TRUE(oc::file_exists(bag)) << "no " << bag;
  EXPECT_TRUE(oc::file_exists(run + "/result.json"));
  // Nothing left beside the device directory: only "unnamed".
  EXPECT_EQ(entries(online_dir), std::vector<std::string>{"unnamed"});

  // The bag holds the whole run: offline_fit fits it.
  const std::string json_path = online_dir + "/offline.json";
  const oc::ToolRun r =
      oc::run_offline_fit({"--bag", bag, "--json", json_path}, online_dir + "/offline.err");
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(oc::read_file(json_path));
  EXPECT_EQ(j["complete"], true) << j["warnings"].dump();
  EXPECT_EQ(j["positions"]["x"], 6);
  if (!HasFailure() && std::getenv("KEEP_TEST_FILES") == nullptr)
    std::system(("rm -rf '" + online_dir + "'").c_str());
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "record_run_directory_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
