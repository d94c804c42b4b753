// Fault injection: see test/ros/few_samples.test and fault_checks.h.
#include "fault_checks.h"

TEST(FaultInjection, few_samples) {
  fault_checks::check_case();
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "few_samples_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
