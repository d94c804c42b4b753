// joint_controller_emulator: a ros_control gimbal without hardware, for the ros_joint driver
// (docs/hardware.md "Emulators"). Behaves like a JointPositionController per joint on a pan-tilt:
// subscribes to one std_msgs/Float64 position command (rad) per joint, moves each joint as a servo
// does (emulators/joint_motion.h: second-order approach with a small overshoot and a speed limit)
// and publishes sensor_msgs/JointState (positions and velocities in rad, rad/s) at rate_hz.
//
// It reads the joints from the same parameters as the gimbal controller's ros_joint driver
// (~ros_joint/joint_states_topic, ~ros_joint/axes/<A>/{joint, command_topic}; load
// config/ros_joint_gimbal.yaml into both), so the two agree by construction; topics are relative to
// the node's namespace, as the gimbal controller's are. Time is the node clock (simulated time
// under /clock). Built into its executable only, not into the ROS library (the production nodes
// never link the emulators).
#pragma once

#include <ros/ros.h>

#include <map>
#include <string>
#include <vector>

#include "accel_intrinsics/emulators/joint_motion.h"

namespace accel_intrinsics {

struct JointControllerEmulatorOptions {
  std::string joint_states_topic = "joint_states";
  // joint name -> its command topic (every axis of ~ros_joint/axes).
  std::map<std::string, std::string> command_topics;
  double rate_hz = 50.0;  // JointState messages per second of the node clock
  JointMotionOptions motion;

  // Reads ~ros_joint/... (through the driver table's ros_joint reader) and the emulator's own
  // ~rate_hz, ~natural_frequency_hz, ~damping_ratio, ~max_speed_deg_s; every joint starts at
  // 0 rad. Throws ParamError naming the parameter.
  static JointControllerEmulatorOptions load(const ros::NodeHandle& pnh);
};

class JointControllerEmulator {
 public:
  JointControllerEmulator(ros::NodeHandle nh, const JointControllerEmulatorOptions& options);

  // Advances every joint to `now` and publishes one JointState stamped `now` (the timer's work;
  // public for tests).
  void update(const ros::Time& now);

 private:
  void on_timer(const ros::TimerEvent&);

  ros::NodeHandle nh_;
  JointControllerEmulatorOptions options_;
  std::vector<std::string> names_;
  std::vector<JointMotion> joints_;  // same order as names_
  std::vector<ros::Subscriber> command_subs_;
  ros::Publisher joint_state_pub_;
  ros::Timer timer_;
  ros::Time last_;
};

}  // namespace accel_intrinsics
