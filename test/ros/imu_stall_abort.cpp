// Fault injection: see test/ros/imu_stall_abort.test and fault_checks.h.
#include "fault_checks.h"

TEST(FaultInjection, imu_stall_abort) {
  fault_checks::check_case();
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "imu_stall_abort_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
