// calibration: dwells, fit and intrinsic results online (see CalibrationNode).
#include <ros/ros.h>

#include <string>

#include "accel_intrinsics/ros/calibration_node.h"
#include "accel_intrinsics/ros/params.h"
#include "accel_intrinsics/ros/tumble_calibration_node.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "calibration");
  ros::NodeHandle nh, pnh("~");
  try {
    // ~mode: gimbal (default: dwells from the gimbal controller's commands) or tumble (a hand
    // tumble: rests found in the IMU stream, docs/design.md section 11).
    const std::string mode = pnh.param<std::string>("mode", "gimbal");
    if (mode == "tumble") {
      accel_intrinsics::TumbleCalibrationNode node(nh, pnh,
                                                   accel_intrinsics::TumbleNodeOptions::load(pnh));
      ros::spin();
      return 0;
    }
    if (mode != "gimbal")
      throw accel_intrinsics::ParamError("parameter ~mode: '" + mode + "' (gimbal or tumble)");
    const auto options = accel_intrinsics::CalibrationOptions::load(pnh);
    accel_intrinsics::CalibrationNode node(nh, pnh, options);
    ros::spin();
  } catch (const accel_intrinsics::ParamError& e) {
    ROS_FATAL("calibration: refusing to start: %s", e.what());
    return 2;
  }
  return 0;
}
