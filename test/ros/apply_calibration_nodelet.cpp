// apply_calibration_nodelet.test: the apply nodelet, standalone (see apply_calibration_checks.h).
constexpr bool kStartAsNodelet = true;
#include "apply_calibration_checks.h"

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "apply_calibration_nodelet_test");
  return RUN_ALL_TESTS();
}
