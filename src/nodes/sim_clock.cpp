// sim_clock: /clock at time_scale times real time for the simulated stand (see SimClock).
#include "accel_intrinsics/ros/sim_clock.h"

#include <ros/ros.h>

#include "accel_intrinsics/ros/params.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "sim_clock");
  ros::NodeHandle nh, pnh("~");
  try {
    accel_intrinsics::SimClock clock(nh, accel_intrinsics::SimClockOptions::load(pnh));
    clock.run();
  } catch (const accel_intrinsics::ParamError& e) {
    ROS_FATAL("sim_clock: refusing to start: %s", e.what());
    return 2;
  }
  return 0;
}
