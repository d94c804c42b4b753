// replay_equals_offline.test: a run of the simulated stand recorded with record.launch;
// offline_fit on that bag equals the calibration node's online result to the last digit, and its
// JSON has the keys and values of the node's intrinsics.yaml (one writer, io/result_document.h).
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>

#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "offline_compare.h"
#include "run_dirs.h"

namespace oc = offline_compare;

TEST(ReplayEqualsOffline, RecordedRunRefitsToTheOnlineResult) {
  ros::NodeHandle pnh("~");
  std::string bag, recorder = "/recorder", online_dir;
  double timeout_s = 200.0;
  ASSERT_TRUE(pnh.getParam("bag", bag));
  pnh.getParam("recorder", recorder);
  pnh.getParam("online_dir", online_dir);
  pnh.getParam("timeout_s", timeout_s);
  // budget_node.test: the node has budget_file = this file, offline_fit gets --budget.
  std::string budget;
  pnh.getParam("budget", budget);
  // noise_model_node.test: the run has a long rest under a slow bias.
  bool expect_noise_model = false;
  pnh.getParam("expect_noise_model", expect_noise_model);
  std::remove(bag.c_str());
  std::remove((bag + ".active").c_str());

  // The recorder and the calibration node must hear the run from its first command.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(60.0);
  while (ros::WallTime::now() < deadline &&
         !(oc::subscribed(recorder, {"/gimbal/command", "/imu/data_raw"}) &&
           oc::subscribed("/calibration", {"/gimbal/command", "/imu/data_raw"}) &&
           ros::service::exists("/gimbal_controller/start", false))) {
    ros::WallDuration(0.2).sleep();
  }
  ASSERT_TRUE(oc::subscribed(recorder, {"/gimbal/command", "/imu/data_raw"}))
      << "recorder not subscribed";
  ros::WallDuration(0.5).sleep();

  std_srvs::Trigger start;
  ASSERT_TRUE(ros::service::call("/gimbal_controller/start", start));
  ASSERT_TRUE(start.response.success) << start.response.message;

  accel_intrinsics::IntrinsicResult online;
  std::string message;
  ASSERT_TRUE(oc::wait_for_result("/calibration/get_intrinsics", timeout_s, &online, &message))
      << message;
  // Keep recording a little past the result (the bag then holds the latched result too).
  ros::WallDuration(1.0).sleep();
  ASSERT_TRUE(oc::shutdown_node(recorder));
  const ros::WallTime closed_by = ros::WallTime::now() + ros::WallDuration(30.0);
  while (ros::WallTime::now() < closed_by &&
         (!oc::file_exists(bag) || oc::file_exists(bag + ".active"))) {
    ros::WallDuration(0.2).sleep();
  }
  ASSERT_TRUE(oc::file_exists(bag)) << "the recorder did not close " << bag;

  const std::string json_path = bag + ".json";
  const std::string csv_path = bag + ".csv";
  std::vector<std::string> args = {"--bag", bag, "--json", json_path, "--csv-out", csv_path};
  if (!budget.empty()) {
    args.push_back("--budget");
    args.push_back(budget);
  }
  const oc::ToolRun r = oc::run_offline_fit(args, bag + ".err");
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(oc::read_file(json_path));
  EXPECT_EQ(j["complete"], true) << j["warnings"].dump();
  EXPECT_EQ(j["input"]["dropped_late"], 0);
  EXPECT_EQ(j["positions"]["x"], 6);
  oc::expect_equal(online, j);
  EXPECT_EQ(j.contains("uncertainty_budget"), !budget.empty());
  // The noise model (compared with the node's below, with the rest of the document): estimated
  // from the long rest when the run has one, else white.
  if (expect_noise_model) {
    ASSERT_TRUE(j["noise_model"].is_object()) << j["noise_model"].dump();
    EXPECT_NE(j["noise_model"]["kind"], "white");
    EXPECT_GT(j["noise_model"]["rest"]["samples"].get<int>(), 3000) << j["noise_model"].dump();
  } else {
    EXPECT_EQ(j["noise_model"], "white");
  }

  // The node's result file: the same document as offline_fit's JSON (contract keys,
  // fitted_effects, certificate_model, ...), value for value; only stamp and samples (node) and
  // input, complete, warnings (offline_fit) are one side's own.
  if (!online_dir.empty()) {
    const std::string yaml_path = run_dirs::latest(online_dir) + "/intrinsics.yaml";
    const ros::WallTime written_by = ros::WallTime::now() + ros::WallDuration(10.0);
    while (ros::WallTime::now() < written_by && !oc::file_exists(yaml_path))
      ros::WallDuration(0.1).sleep();
    ASSERT_TRUE(oc::file_exists(yaml_path));
    const YAML::Node node_result = YAML::LoadFile(yaml_path);
    for (const char* key :
         {"model", "responsivity", "angles_deg", "vectors", "offset", "offset_per_phase",
          "cross_sensitivity", "local_gravity", "reduced_chi2", "residual_rms", "positions",
          "fitted_effects", "certificate_model", "certificate_policy", "model_label"}) {
      EXPECT_TRUE(j.contains(key)) << key;
    }
    EXPECT_TRUE(node_result["stamp"] && node_result["samples"]["used"]);
    oc::expect_same_document(j, node_result);
    EXPECT_EQ(node_result["samples"]["used"].as<std::uint64_t>(),
              j["input"]["samples_used"].get<std::uint64_t>());
  }

  // The dwells themselves: the node's checkpoint file and offline_fit's table, byte for byte.
  if (!online_dir.empty()) {
    const std::string online_csv =
        oc::read_file(run_dirs::latest(online_dir) + "/position_table.csv");
    ASSERT_FALSE(online_csv.empty());
    EXPECT_EQ(online_csv, oc::read_file(csv_path));
  }
  // Passed: remove this run's files (kept on failure, to look at).
  if (!HasFailure() && std::getenv("KEEP_TEST_FILES") == nullptr) {
    for (const std::string& path : {bag, json_path, csv_path, bag + ".err"})
      std::remove(path.c_str());
    if (!online_dir.empty()) std::system(("rm -rf '" + online_dir + "'").c_str());
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "replay_equals_offline_test");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
