// calibration: dwells, fit and intrinsic results online (see CalibrationNode).
#include <ros/ros.h>

#include "accel_intrinsics/ros/calibration_node.h"
#include "accel_intrinsics/ros/params.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "calibration");
  ros::NodeHandle nh, pnh("~");
  try {
    const auto options = accel_intrinsics::CalibrationOptions::load(pnh);
    accel_intrinsics::CalibrationNode node(nh, pnh, options);
    ros::spin();
  } catch (const accel_intrinsics::ParamError& e) {
    ROS_FATAL("calibration: refusing to start: %s", e.what());
    return 2;
  }
  return 0;
}
