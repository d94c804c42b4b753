// supervise --yes on a one-axis stage: see test/ros/smc100_supervise_yes.test.
#include "stand_checks.h"

TEST(Smc100SuperviseYes, ContinuesAfterEachRemount) {
  ros::NodeHandle pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  double timeout_s = 240.0;
  std::string output_dir;
  pnh.getParam("timeout_s", timeout_s);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(90.0)));
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/start", ros::Duration(90.0)));
  const std::string command = "rosrun accel_intrinsics supervise --yes --timeout " +
                              std::to_string(timeout_s) + " --max-sigma " +
                              std::to_string(limits.max_sigma) + " --json " + output_dir +
                              "/supervise.json";
  const stand_checks::CommandResult r = stand_checks::run(command);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // Both remounts were shown to the operator and continued.
  for (const char* phase : {"REMOUNT phase y", "REMOUNT phase z"}) {
    EXPECT_NE(r.output.find(phase), std::string::npos) << phase << " not in:\n" << r.output;
  }
  std::size_t continued = 0;
  for (std::size_t at = r.output.find("continuing with phase"); at != std::string::npos;
       at = r.output.find("continuing with phase", at + 1)) {
    ++continued;
  }
  EXPECT_EQ(continued, 2u) << r.output;
  const accel_intrinsics::GetIntrinsics::Response res = stand_checks::get_intrinsics("");
  ASSERT_TRUE(res.success) << res.message;
  stand_checks::Truth truth;
  ASSERT_TRUE(stand_checks::load_truth("", &truth));
  stand_checks::expect_matches_truth(res.result, truth, limits, "supervise --yes");
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "smc100_supervise_yes_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
