// A serial fault retried: see test/ros/grbl_error_retry.test and fault_checks.h.
#include "fault_checks.h"
#include "serial_checks.h"

TEST(SerialFault, grbl_error_retry) {
  fault_checks::check_case();
  // The controller recovered the gimbal with a second soft reset before the retried move.
  std::string output_dir;
  ASSERT_TRUE(ros::NodeHandle("~").getParam("output_dir", output_dir));
  const auto log = serial_checks::read_lines(output_dir + "/grbl_commands.log");
  EXPECT_EQ(std::count(log.begin(), log.end(), "^X"), 2);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "grbl_error_retry_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
