// Conversions between ROS messages and the ROS-free core types (conversions.h).
#include "accel_intrinsics/ros/conversions.h"

#include <algorithm>

namespace accel_intrinsics {

namespace {

core::Phase phase_from_msg(std::uint8_t phase) {
  switch (phase) {
    case GimbalCommand::PHASE_X:
      return core::Phase::X;
    case GimbalCommand::PHASE_Y:
      return core::Phase::Y;
    default:
      return core::Phase::Z;
  }
}

geometry_msgs::Vector3 to_vector3(const Eigen::Vector3d& v) {
  geometry_msgs::Vector3 out;
  out.x = v.x();
  out.y = v.y();
  out.z = v.z();
  return out;
}

}  // namespace

core::GimbalEvent to_core(const GimbalCommand& msg) {
  core::GimbalEvent event;
  event.stamp_s = msg.header.stamp.toSec();
  event.phase = phase_from_msg(msg.phase);
  event.step = msg.step;
  event.steps = msg.steps;
  event.angle_rad = msg.angle;
  switch (msg.state) {
    case GimbalCommand::SETTLED:
      event.state = core::GimbalState::Settled;
      break;
    case GimbalCommand::DONE:
      event.state = core::GimbalState::Done;
      break;
    default:
      event.state = core::GimbalState::Moving;
      break;
  }
  return event;
}

GimbalCommand to_msg(const core::GimbalEvent& event) {
  GimbalCommand msg;
  msg.header.stamp.fromSec(std::max(0.0, event.stamp_s));
  msg.phase = static_cast<std::uint8_t>(core::index(event.phase));
  msg.step = event.step;
  msg.steps = event.steps;
  msg.angle = event.angle_rad;
  msg.state = static_cast<std::uint8_t>(event.state);
  return msg;
}

core::ImuSample to_core(const sensor_msgs::Imu& msg) {
  core::ImuSample sample;
  sample.stamp_s = msg.header.stamp.toSec();
  sample.outputs = Eigen::Vector3d(msg.linear_acceleration.x, msg.linear_acceleration.y,
                                   msg.linear_acceleration.z);
  return sample;
}

sensor_msgs::Imu to_msg(const core::ImuSample& sample, const std::string& frame_id,
                        double variance_per_axis) {
  sensor_msgs::Imu msg;
  msg.header.stamp.fromSec(std::max(0.0, sample.stamp_s));
  msg.header.frame_id = frame_id;
  // Orientation and angular velocity are not provided (REP 145, sensor_msgs/Imu comments).
  msg.orientation.w = 1.0;
  msg.orientation_covariance.fill(0.0);
  msg.orientation_covariance[0] = -1.0;
  msg.angular_velocity_covariance.fill(0.0);
  msg.angular_velocity_covariance[0] = -1.0;
  msg.linear_acceleration.x = sample.outputs.x();
  msg.linear_acceleration.y = sample.outputs.y();
  msg.linear_acceleration.z = sample.outputs.z();
  msg.linear_acceleration_covariance.fill(0.0);
  for (int i = 0; i < 3; ++i) msg.linear_acceleration_covariance[4 * i] = variance_per_axis;
  return msg;
}

IntrinsicResult to_msg(const core::FitResult& result) {
  IntrinsicResult msg;
  msg.model = result.model_label();
  const core::Intrinsics& in = result.intrinsics;
  for (int i = 0; i < 3; ++i) {
    msg.responsivity[i] = in.responsivity(i);
    msg.responsivity_std[i] = in.responsivity_std(i);
    msg.angles_deg[i] = core::rad_to_deg(in.angles_rad(i));
    msg.angles_std_deg[i] = core::rad_to_deg(in.angles_std_rad(i));
    msg.offset[i] = result.O(i);
    msg.offset_std[i] = result.O_std(i);
    msg.positions[i] = static_cast<std::uint32_t>(std::max(0, result.positions[i]));
  }
  msg.u = to_vector3(result.S.row(0).transpose());
  msg.v = to_vector3(result.S.row(1).transpose());
  msg.w = to_vector3(result.S.row(2).transpose());
  // offset_per_phase: u_x u_y u_z v_x ... = row-major of (accelerometer x phase).
  for (int s = 0; s < 3; ++s) {
    for (int p = 0; p < 3; ++p) {
      msg.offset_per_phase[3 * s + p] = result.offset_per_phase(s, p);
      msg.cross_sensitivity[3 * s + p] = result.cross_sensitivity(s, p);
    }
  }
  msg.local_gravity = result.local_gravity;
  msg.reduced_chi2 = result.reduced_chi2;
  msg.residual_rms = result.residual_rms;
  for (std::size_t i = 0; i < result.effects.size(); ++i) {
    msg.effect_names.push_back(result.effects[i].name());
    msg.effect_targets.push_back(result.effects[i].target_name());
    msg.effect_values.push_back(result.effects[i].value);
    msg.effect_std.push_back(i < result.effects_std.size() ? result.effects_std[i] : 0.0);
  }
  return msg;
}

}  // namespace accel_intrinsics
