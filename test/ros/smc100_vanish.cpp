// A serial port that vanishes mid-run: see test/ros/smc100_vanish.test and fault_checks.h.
#include "fault_checks.h"

TEST(SerialFault, smc100_vanish) {
  fault_checks::check_case();
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "smc100_vanish_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
