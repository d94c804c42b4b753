// A clock for the simulated stand: publishes /clock (rosgraph_msgs/Clock) running time_scale
// times faster than the wall clock, so that with use_sim_time the whole stand (controller,
// accelerometer, calibration) runs faster than real time.
#pragma once

#include <ros/ros.h>

namespace accel_intrinsics {

struct SimClockOptions {
  double time_scale = 1.0;  // simulated seconds per wall second
  double rate_hz = 200.0;   // /clock messages per wall second
  double start_s = 100.0;   // simulated time of the first message, s (> 0: 0 means "no time")

  // Reads the private parameters; throws ParamError naming the parameter.
  static SimClockOptions load(const ros::NodeHandle& pnh);
};

class SimClock {
 public:
  SimClock(ros::NodeHandle nh, const SimClockOptions& options);
  // Publishes until ROS shuts down.
  void run();

 private:
  ros::NodeHandle nh_;
  SimClockOptions options_;
  ros::Publisher pub_;
};

}  // namespace accel_intrinsics
