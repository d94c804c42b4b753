// joint_controller_emulator: a ros_control pan-tilt for the ros_joint driver without hardware
// (see JointControllerEmulator).
#include "accel_intrinsics/ros/joint_controller_emulator.h"

#include <ros/ros.h>

#include "accel_intrinsics/ros/params.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "joint_controller_emulator");
  ros::NodeHandle nh, pnh("~");
  try {
    accel_intrinsics::JointControllerEmulator emulator(
        nh, accel_intrinsics::JointControllerEmulatorOptions::load(pnh));
    ros::spin();
  } catch (const accel_intrinsics::ParamError& e) {
    ROS_FATAL("joint_controller_emulator: refusing to start: %s", e.what());
    return 2;
  }
  return 0;
}
