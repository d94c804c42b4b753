// Fault injection: see test/ros/never_settle.test and fault_checks.h.
#include "fault_checks.h"

TEST(FaultInjection, never_settle) {
  fault_checks::check_case();
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "never_settle_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
