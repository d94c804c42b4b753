// gimbal_controller: runs the rotation protocol (see GimbalControllerNode).
#include <ros/ros.h>

#include "accel_intrinsics/ros/gimbal_controller_node.h"
#include "accel_intrinsics/ros/params.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "gimbal_controller");
  ros::NodeHandle nh, pnh("~");
  try {
    const auto options = accel_intrinsics::GimbalControllerOptions::load(pnh);
    accel_intrinsics::GimbalControllerNode node(nh, pnh, options,
                                                accel_intrinsics::make_gimbal_driver(options));
    ros::spin();
  } catch (const accel_intrinsics::ParamError& e) {
    ROS_FATAL("gimbal_controller: refusing to start: %s", e.what());
    return 2;
  }
  return 0;
}
