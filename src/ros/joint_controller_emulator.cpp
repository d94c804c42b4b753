// The joint controller emulator (joint_controller_emulator.h).
#include "accel_intrinsics/ros/joint_controller_emulator.h"

#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64.h>

#include <any>
#include <cmath>
#include <stdexcept>

#include "accel_intrinsics/drivers/gimbal_driver_table.h"
#include "accel_intrinsics/drivers/ros_joint_gimbal.h"
#include "accel_intrinsics/ros/params.h"
#include "accel_intrinsics/ros/ros_driver_params.h"

namespace accel_intrinsics {

JointControllerEmulatorOptions JointControllerEmulatorOptions::load(const ros::NodeHandle& pnh) {
  JointControllerEmulatorOptions o;
  const GimbalDriverRow* row = find_gimbal_driver("ros_joint");
  if (row == nullptr) throw ParamError("the driver table has no ros_joint row");
  RosJointOptions driver;
  try {
    driver = std::any_cast<RosJointOptions>(row->read_options(RosDriverParams(pnh), {}));
  } catch (const std::invalid_argument& e) {
    throw ParamError(std::string(e.what()) + " (load config/ros_joint_gimbal.yaml into the " +
                     "emulator too)");
  }
  o.joint_states_topic = driver.joint_states_topic;
  for (const auto& axis : driver.axes)
    o.command_topics[axis.second.joint] = axis.second.command_topic;

  read_param(pnh, "rate_hz", &o.rate_hz);
  require(std::isfinite(o.rate_hz) && o.rate_hz >= 1.0 && o.rate_hz <= 1000.0, pnh, "rate_hz",
          "must be in [1, 1000] Hz");
  read_param(pnh, "natural_frequency_hz", &o.motion.natural_frequency_hz);
  read_param(pnh, "damping_ratio", &o.motion.damping_ratio);
  read_param(pnh, "max_speed_deg_s", &o.motion.max_speed_deg_s);
  try {
    o.motion.validate();
  } catch (const std::invalid_argument& e) {
    throw ParamError("parameter " + param_name(pnh, "") + "/" + e.what());
  }
  return o;
}

JointControllerEmulator::JointControllerEmulator(ros::NodeHandle nh,
                                                 const JointControllerEmulatorOptions& options)
    : nh_(nh), options_(options) {
  names_.reserve(options_.command_topics.size());
  joints_.reserve(options_.command_topics.size());
  for (const auto& joint : options_.command_topics) {
    names_.push_back(joint.first);
    joints_.emplace_back(options_.motion, 0.0);
  }
  for (std::size_t i = 0; i < names_.size(); ++i) {
    command_subs_.push_back(
        nh_.subscribe<std_msgs::Float64>(options_.command_topics.at(names_[i]), 10,
                                         [this, i](const std_msgs::Float64::ConstPtr& msg) {
                                           if (std::isfinite(msg->data))
                                             joints_[i].command(msg->data);
                                         }));
  }
  joint_state_pub_ = nh_.advertise<sensor_msgs::JointState>(options_.joint_states_topic, 10);
  timer_ = nh_.createTimer(ros::Duration(1.0 / options_.rate_hz),
                           &JointControllerEmulator::on_timer, this);
  std::string joints;
  for (std::size_t i = 0; i < names_.size(); ++i) {
    joints += (joints.empty() ? "" : ", ") + names_[i] + " <- " +
              nh_.resolveName(options_.command_topics.at(names_[i]));
  }
  ROS_INFO(
      "joint_controller_emulator: %s; JointState on %s at %.0f Hz; %.2f Hz, damping %.2f "
      "(overshoot %.1f %%), at most %.0f deg/s",
      joints.c_str(), nh_.resolveName(options_.joint_states_topic).c_str(), options_.rate_hz,
      options_.motion.natural_frequency_hz, options_.motion.damping_ratio,
      100.0 * options_.motion.small_step_overshoot(), options_.motion.max_speed_deg_s);
}

void JointControllerEmulator::on_timer(const ros::TimerEvent&) {
  update(ros::Time::now());
}

void JointControllerEmulator::update(const ros::Time& now) {
  if (now.isZero()) return;  // simulated time before the first /clock
  // One message per stamp: a simulated clock that advances in steps coarser than the timer
  // period fires the timer several times at one time. A clock that went back restarts the count.
  if (!last_.isZero() && now == last_) return;
  const double dt_s = last_.isZero() || now < last_ ? 0.0 : (now - last_).toSec();
  last_ = now;
  sensor_msgs::JointState msg;
  msg.header.stamp = now;
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    joints_[i].advance(dt_s);
    msg.name.push_back(names_[i]);
    msg.position.push_back(joints_[i].position_rad());
    msg.velocity.push_back(joints_[i].velocity_rad_s());
  }
  joint_state_pub_.publish(msg);
}

}  // namespace accel_intrinsics
