// apply_calibration: corrects imu/data_raw into imu/data_calibrated (see ApplyCalibrationNode).
#include <ros/ros.h>

#include "accel_intrinsics/ros/apply_calibration_node.h"
#include "accel_intrinsics/ros/params.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "apply_calibration");
  ros::NodeHandle nh, pnh("~");
  try {
    accel_intrinsics::io::ApplyCalibration calibration;
    const auto options = accel_intrinsics::ApplyCalibrationOptions::load(pnh, &calibration);
    accel_intrinsics::ApplyCalibrationNode node(nh, options, calibration);
    ros::spin();
  } catch (const accel_intrinsics::ParamError& e) {
    ROS_FATAL("apply_calibration: refusing to start: %s", e.what());
    return 2;
  }
  return 0;
}
