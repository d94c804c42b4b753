// A serial fault retried on the SMC100: see test/ros/smc100_alarm_retry.test, fault_checks.h.
#include "fault_checks.h"
#include "serial_checks.h"

TEST(SerialFault, smc100_alarm_retry) {
  fault_checks::check_case();
  // The recovery reset the faulted controller and homed it again: one RS, two OR for address 1.
  std::string output_dir;
  ASSERT_TRUE(ros::NodeHandle("~").getParam("output_dir", output_dir));
  const auto log = serial_checks::read_lines(output_dir + "/smc100_commands.log");
  EXPECT_EQ(std::count(log.begin(), log.end(), "1RS"), 1);
  EXPECT_EQ(std::count(log.begin(), log.end(), "1OR"), 2);
  EXPECT_EQ(std::count(log.begin(), log.end(), "2OR"), 1);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "smc100_alarm_retry_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
