// apply_calibration.test: the apply node (see apply_calibration_checks.h and the .test file).
constexpr bool kStartAsNodelet = false;
#include "apply_calibration_checks.h"

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "apply_calibration_test");
  return RUN_ALL_TESTS();
}
