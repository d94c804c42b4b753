// Faster-than-real-time clock for the simulated stand.
#include "accel_intrinsics/ros/sim_clock.h"

#include <rosgraph_msgs/Clock.h>

#include <cmath>

#include "accel_intrinsics/ros/names.h"
#include "accel_intrinsics/ros/params.h"

namespace accel_intrinsics {

SimClockOptions SimClockOptions::load(const ros::NodeHandle& pnh) {
  SimClockOptions o;
  read_param(pnh, "time_scale", &o.time_scale);
  require(std::isfinite(o.time_scale) && o.time_scale > 0.0 && o.time_scale <= 1000.0, pnh,
          "time_scale", "must be in (0, 1000]");
  read_param(pnh, "rate_hz", &o.rate_hz);
  require(std::isfinite(o.rate_hz) && o.rate_hz >= 1.0 && o.rate_hz <= 10000.0, pnh, "rate_hz",
          "must be in [1, 10000] Hz");
  read_param(pnh, "start_s", &o.start_s);
  require(std::isfinite(o.start_s) && o.start_s > 0.0 && o.start_s < 2e9, pnh, "start_s",
          "must be in (0, 2e9) s");
  read_param(pnh, "wall_epoch_s", &o.wall_epoch_s);
  require(std::isfinite(o.wall_epoch_s) && o.wall_epoch_s >= 0.0 &&
              o.wall_epoch_s <= ros::WallTime::now().toSec(),
          pnh, "wall_epoch_s", "must be 0 (now) or a wall time (s since 1970) not in the future");
  return o;
}

SimClock::SimClock(ros::NodeHandle nh, const SimClockOptions& options)
    : nh_(nh), options_(options) {
  pub_ = nh_.advertise<rosgraph_msgs::Clock>(names::kClockTopic, 10);
  pause_srv_ = ros::NodeHandle("~").advertiseService("pause", &SimClock::on_pause, this);
}

double SimClock::now_s() const {
  const ros::WallTime wall = paused_ ? paused_since_ : ros::WallTime::now();
  return options_.start_s + options_.time_scale * ((wall - wall0_).toSec() - paused_wall_s_);
}

bool SimClock::on_pause(std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res) {
  if (req.data && !paused_) {
    paused_since_ = ros::WallTime::now();
    paused_ = true;
  } else if (!req.data && paused_) {
    paused_wall_s_ += (ros::WallTime::now() - paused_since_).toSec();
    paused_ = false;
  }
  res.success = true;
  res.message =
      std::string(paused_ ? "paused" : "running") + " at " + std::to_string(now_s()) + " s";
  ROS_INFO("sim_clock: %s", res.message.c_str());
  return true;
}

void SimClock::run() {
  ROS_INFO("sim_clock: /clock from %.1f s at %.2fx real time, %.0f Hz%s", options_.start_s,
           options_.time_scale, options_.rate_hz,
           options_.wall_epoch_s > 0.0 ? " (timeline continued from wall_epoch_s)" : "");
  wall0_ =
      options_.wall_epoch_s > 0.0 ? ros::WallTime(options_.wall_epoch_s) : ros::WallTime::now();
  ros::WallRate rate(options_.rate_hz);
  while (ros::ok()) {
    ros::spinOnce();  // ~pause
    rosgraph_msgs::Clock msg;
    msg.clock.fromSec(now_s());
    pub_.publish(msg);
    rate.sleep();
  }
}

}  // namespace accel_intrinsics
