// A clock for the simulated stand: publishes /clock (rosgraph_msgs/Clock) running time_scale
// times faster than the wall clock, so that with use_sim_time the whole stand (controller,
// accelerometer, calibration) runs faster than real time. The service ~pause (std_srvs/SetBool)
// holds simulated time (data: true; /clock keeps coming, with the held time) and lets it run on
// from there (false): the stand stops wherever it is, e.g. for a test that restarts a node
// inside a dwell.
#pragma once

#include <ros/ros.h>
#include <std_srvs/SetBool.h>

namespace accel_intrinsics {

struct SimClockOptions {
  double time_scale = 1.0;  // simulated seconds per wall second
  double rate_hz = 200.0;   // /clock messages per wall second
  double start_s = 100.0;   // simulated time of the first message, s (> 0: 0 means "no time")
  // Wall time (s since the epoch) at which simulated time was start_s; 0: this process's start.
  // A clock restarted with the same wall_epoch_s continues its timeline instead of going back
  // to start_s (a stand PC or the whole lab restarted mid-run, docs/design.md section 14).
  double wall_epoch_s = 0.0;

  // Reads the private parameters; throws ParamError naming the parameter.
  static SimClockOptions load(const ros::NodeHandle& pnh);
};

class SimClock {
 public:
  SimClock(ros::NodeHandle nh, const SimClockOptions& options);
  // Publishes until ROS shuts down.
  void run();

 private:
  bool on_pause(std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res);
  double now_s() const;  // simulated time now

  ros::NodeHandle nh_;
  SimClockOptions options_;
  ros::Publisher pub_;
  ros::ServiceServer pause_srv_;
  ros::WallTime wall0_;
  double paused_wall_s_ = 0.0;  // wall time spent paused before the current pause
  bool paused_ = false;
  ros::WallTime paused_since_;
};

}  // namespace accel_intrinsics
