// Two rigs in two namespaces at once (test/ros/two_rigs.test).
#include "stand_checks.h"

TEST(TwoRigs, BothMatchTheirOwnTruth) {
  ros::NodeHandle pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  std::vector<std::string> namespaces;
  double timeout_s = 300.0;
  std::string output_dir;
  ASSERT_TRUE(pnh.getParam("namespaces", namespaces));
  ASSERT_EQ(namespaces.size(), 2u);
  pnh.getParam("timeout_s", timeout_s);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  for (const std::string& ns : namespaces) {
    ASSERT_TRUE(ros::service::waitForService(
        stand_checks::join_ns(ns, "calibration/get_intrinsics"), ros::Duration(60.0)));
  }
  // Both at once, one supervisor.
  stand_checks::supervise_and_check(namespaces, limits, timeout_s, output_dir + "/supervise.json");

  std::vector<stand_checks::Truth> truths(2);
  for (std::size_t i = 0; i < namespaces.size(); ++i) {
    ASSERT_TRUE(stand_checks::load_truth(namespaces[i], &truths[i]));
    const accel_intrinsics::GetIntrinsics::Response res =
        stand_checks::get_intrinsics(namespaces[i]);
    ASSERT_TRUE(res.success) << namespaces[i] << ": " << res.message;
    stand_checks::expect_matches_truth(res.result, truths[i], limits, namespaces[i]);
    EXPECT_EQ(
        stand_checks::count_csv_rows(output_dir + "/" + namespaces[i] + "/position_table.csv"),
        3u * res.result.positions[0]);
  }
  // The truths differ by far more than the uncertainty, so a mix-up could not pass.
  EXPECT_GT(std::abs(truths[0].responsivity[0] - truths[1].responsivity[0]), 0.01);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "two_rigs_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
