// accelerometer: publishes imu/data_raw from an accelerometer source (see AccelerometerNode).
#include <ros/ros.h>

#include "accel_intrinsics/ros/accelerometer_node.h"
#include "accel_intrinsics/ros/params.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "accelerometer");
  ros::NodeHandle nh, pnh("~");
  try {
    const auto options = accel_intrinsics::AccelerometerOptions::load(pnh);
    accel_intrinsics::AccelerometerNode node(nh, pnh, options);
    ros::spin();
  } catch (const accel_intrinsics::ParamError& e) {
    ROS_FATAL("accelerometer: refusing to start: %s", e.what());
    return 2;
  }
  return 0;
}
