// End to end on the simulated stand (test/ros/end_to_end.test).
#include <diagnostic_msgs/DiagnosticStatus.h>

#include <map>

#include "stand_checks.h"

TEST(EndToEnd, SuperviseThenServiceMatchTruth) {
  ros::NodeHandle pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  double timeout_s = 240.0;
  int steps = 12;
  std::string output_dir;
  pnh.getParam("timeout_s", timeout_s);
  pnh.getParam("steps", steps);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(60.0)));

  // The supervisor: start, progress, get_intrinsics, table against the truth, JSON.
  stand_checks::supervise_and_check({""}, limits, timeout_s, output_dir + "/supervise.json");

  // The service directly.
  const accel_intrinsics::GetIntrinsics::Response res = stand_checks::get_intrinsics("");
  ASSERT_TRUE(res.success) << res.message;
  stand_checks::Truth truth;
  ASSERT_TRUE(stand_checks::load_truth("", &truth));
  stand_checks::expect_matches_truth(res.result, truth, limits, "stand");
  EXPECT_EQ(res.result.model, "joint");
  for (int p = 0; p < 3; ++p) EXPECT_EQ(res.result.positions[p], static_cast<unsigned>(steps));
  EXPECT_LT(res.result.reduced_chi2, 3.0);

  // The latched result topic carries the same numbers.
  const auto latched = ros::topic::waitForMessage<accel_intrinsics::IntrinsicResult>(
      "/calibration/result", ros::Duration(10.0));
  ASSERT_TRUE(latched);
  EXPECT_EQ(latched->responsivity, res.result.responsivity);

  // Checkpoints and result files.
  EXPECT_EQ(stand_checks::count_csv_rows(output_dir + "/position_table.csv"),
            static_cast<std::size_t>(3 * steps));
  std::ifstream yaml(output_dir + "/intrinsics.yaml");
  EXPECT_TRUE(yaml.good());

  // No bad samples on a healthy stand.
  const auto status = ros::topic::waitForMessage<diagnostic_msgs::DiagnosticStatus>(
      "/calibration/status", ros::Duration(10.0));
  ASSERT_TRUE(status);
  std::map<std::string, std::string> v;
  for (const auto& kv : status->values) v[kv.key] = kv.value;
  EXPECT_EQ(v["dropped_non_finite"], "0");
  EXPECT_EQ(v["dropped_backwards"], "0");
  EXPECT_EQ(v["commands_out_of_order"], "0");
  EXPECT_GT(std::stoll(v["samples_used"]), 3LL * steps * 150);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "end_to_end_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
