// The ros_joint gimbal driver (ros_joint_gimbal.h).
#include "accel_intrinsics/drivers/ros_joint_gimbal.h"

#include <algorithm>
#include <cmath>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/text_format.h"

namespace accel_intrinsics {

namespace {

using core::fixed;

bool positive(double v) {
  return std::isfinite(v) && v > 0.0;
}

}  // namespace

void RosJointOptions::validate() const {
  if (joint_states_topic.empty()) throw std::invalid_argument("joint_states_topic is empty");
  if (axes.empty())
    throw std::invalid_argument("axes is missing ({X: {joint: NAME, command_topic: TOPIC}, ...})");
  for (const auto& a : axes) {
    if (a.second.joint.empty())
      throw std::invalid_argument("axes/" + a.first + "/joint is missing");
    if (a.second.command_topic.empty())
      throw std::invalid_argument("axes/" + a.first + "/command_topic is missing");
  }
  if (!positive(tolerance_deg)) throw std::invalid_argument("tolerance_deg must be > 0 deg");
  if (!(std::isfinite(settle_s) && settle_s >= 0.0))
    throw std::invalid_argument("settle_s must be >= 0 s");
  if (!positive(move_timeout_s)) throw std::invalid_argument("move_timeout_s must be > 0 s");
  if (!positive(joint_state_timeout_s))
    throw std::invalid_argument("joint_state_timeout_s must be > 0 s");
  std::vector<std::string> known;
  for (const auto& a : axes) known.push_back(a.first);
  axis_map.validate(known);
}

RosJointGimbal::RosJointGimbal(const RosJointOptions& options) : options_(options) {
  options_.validate();
  for (const std::string& axis : options_.axis_map.axes()) {
    joints_[axis].axis = options_.axes.at(axis);
  }
}

GimbalDriverTopics RosJointGimbal::topics() const {
  GimbalDriverTopics t;
  t.joint_states = options_.joint_states_topic;
  for (const auto& j : joints_) t.command_topics.push_back(j.second.axis.command_topic);
  return t;
}

void RosJointGimbal::on_joint_state(double t_s, const std::vector<std::string>& names,
                                    const std::vector<double>& positions_rad) {
  const std::size_t n = std::min(names.size(), positions_rad.size());
  for (auto& j : joints_) {
    for (std::size_t i = 0; i < n; ++i) {
      if (names[i] != j.second.axis.joint || !std::isfinite(positions_rad[i])) continue;
      j.second.seen = true;
      j.second.position_deg = core::rad_to_deg(positions_rad[i]);
      j.second.seen_s = t_s;
    }
  }
}

std::string RosJointGimbal::describe(const std::string& axis) const {
  return "joint '" + joints_.at(axis).axis.joint + "' (axis " + axis + ")";
}

void RosJointGimbal::command(const std::map<std::string, double>& positions_deg) {
  if (links_ == nullptr) throw GimbalFault("ros_joint: not connected to its command topics");
  for (const auto& p : positions_deg) {
    links_->publish_command(joints_.at(p.first).axis.command_topic, core::deg_to_rad(p.second));
  }
}

void RosJointGimbal::move_to(const GimbalTarget& target, double t_s) {
  target_ = target;
  target_deg_ = options_.axis_map.positions_deg(target.phase, target.angle_rad);
  command(target_deg_);
  moving_ = true;
  move_start_s_ = t_s;
  within_since_s_ = -1.0;
}

void RosJointGimbal::update(double t_s) {
  if (watch_since_s_ < 0.0) watch_since_s_ = t_s;
  for (const auto& j : joints_) {
    const double last_s =
        j.second.seen ? std::max(j.second.seen_s, watch_since_s_) : watch_since_s_;
    if (t_s - last_s > options_.joint_state_timeout_s) {
      throw GimbalFault("ros_joint: no JointState for " + describe(j.first) + " on " +
                        options_.joint_states_topic + " for " + fixed(t_s - last_s, 1) +
                        " s (joint_state_timeout_s = " + fixed(options_.joint_state_timeout_s, 1) +
                        ")");
    }
  }
  if (!moving_) return;
  bool within = true;
  for (const auto& p : target_deg_) {
    const Joint& j = joints_.at(p.first);
    if (!j.seen || std::abs(j.position_deg - p.second) > options_.tolerance_deg) within = false;
  }
  if (!within) {
    within_since_s_ = -1.0;
  } else if (within_since_s_ < 0.0) {
    within_since_s_ = t_s;
  }
  if (within && t_s - within_since_s_ >= options_.settle_s) {
    moving_ = false;
    settled_s_ = std::max(within_since_s_ + options_.settle_s, move_start_s_);
    return;
  }
  if (t_s - move_start_s_ > options_.move_timeout_s) {
    std::string missing;
    for (const auto& p : target_deg_) {
      const Joint& j = joints_.at(p.first);
      if (j.seen && std::abs(j.position_deg - p.second) <= options_.tolerance_deg) continue;
      missing += (missing.empty() ? "" : "; ") + describe(p.first) + " did not arrive at " +
                 fixed(p.second, 3) + " deg (it is at " +
                 (j.seen ? fixed(j.position_deg, 3) + " deg" : std::string("no position")) + ")";
    }
    if (missing.empty()) missing = "the joints did not stay within tolerance for settle_s";
    moving_ = false;
    throw GimbalFault("ros_joint: " + missing +
                      " within move_timeout_s = " + fixed(options_.move_timeout_s, 1) +
                      " s (tolerance_deg = " + fixed(options_.tolerance_deg, 3) + ")");
  }
}

bool RosJointGimbal::settled(double /*t_s*/) const {
  return !moving_;
}

double RosJointGimbal::settled_at(double t_s) const {
  return moving_ ? t_s : std::min(t_s, settled_s_);
}

void RosJointGimbal::stop(double t_s) {
  // Hold where the joints are (best effort: a silent joint keeps its last command).
  std::map<std::string, double> here;
  for (const auto& j : joints_) {
    if (j.second.seen) here[j.first] = j.second.position_deg;
  }
  try {
    if (moving_ && !here.empty()) command(here);
  } catch (const GimbalFault&) {
  }
  moving_ = false;
  settled_s_ = t_s;
}

void RosJointGimbal::recover(double t_s) {
  moving_ = false;
  watch_since_s_ = t_s;  // a fresh joint_state_timeout_s for the joints to speak
}

bool RosJointGimbal::manual_remount(core::Phase phase) const {
  return options_.axis_map.phases[core::index(phase)].manual_remount;
}

std::string RosJointGimbal::status_text() const {
  std::string out;
  for (const auto& j : joints_) {
    out += (out.empty() ? "" : ", ") + j.second.axis.joint + " " +
           (j.second.seen ? fixed(j.second.position_deg, 3) + " deg" : std::string("silent"));
  }
  return out;
}

GimbalTransforms RosJointGimbal::orientation(double /*t_s*/) const {
  // The reported position of the phase's axis read back into alpha (the DUT turns about its own
  // p axis); the commanded alpha until a position is known.
  const std::string& axis = options_.axis_map.phases[core::index(target_.phase)].axis;
  const auto it = joints_.find(axis);
  double alpha = target_.angle_rad;
  if (it != joints_.end() && it->second.seen)
    alpha = options_.axis_map.alpha_rad(target_.phase, it->second.position_deg);
  return gimbal_transforms(target_.phase, alpha, 0.0);
}

}  // namespace accel_intrinsics
