// Simulated gimbal backend and the tf chain that realizes DESIGN.md eq. (4).
#include "accel_intrinsics/ros/gimbal_driver.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>
#include <utility>

#include "accel_intrinsics/core/constants.h"
#include "accel_intrinsics/core/model.h"

namespace accel_intrinsics {

namespace {

bool finite_non_negative(double v) { return std::isfinite(v) && v >= 0.0; }

// Smooth start and stop: zero velocity at both ends of a move.
double smooth_profile(double s) {
  s = std::min(1.0, std::max(0.0, s));
  return 0.5 - 0.5 * std::cos(core::kPi * s);
}

}  // namespace

// R_gimbal_dut. With f_gimbal = (sin tau, cos tau sin theta, cos tau cos theta) (the world up
// axis seen from a frame turned by theta about its x axis, which is raised by tau), the DUT sees
// f_dut = R_gimbal_dut^T f_gimbal:
//   x: identity, theta = alpha                      -> (sin tau, c sin a, c cos a)
//   y: x_dut = -y_g, y_dut = x_g, theta = -alpha     -> (c sin a, sin tau, c cos a)
//   z: x_dut = y_g, y_dut = z_g, z_dut = x_g, theta = alpha -> (c sin a, c cos a, sin tau)
// (c = cos tau); each is eq. (4) with the tilt term of model.h. All three are proper rotations.
Eigen::Matrix3d mount_rotation(core::Phase phase) {
  Eigen::Matrix3d P;  // f_dut = P f_gimbal, so R_gimbal_dut = P^T
  switch (phase) {
    case core::Phase::X:
      P.setIdentity();
      break;
    case core::Phase::Y:
      P << 0, -1, 0, 1, 0, 0, 0, 0, 1;
      break;
    case core::Phase::Z:
    default:
      P << 0, 1, 0, 0, 0, 1, 1, 0, 0;
      break;
  }
  return P.transpose();
}

double gimbal_angle(core::Phase phase, double true_angle_rad) {
  return phase == core::Phase::Y ? -true_angle_rad : true_angle_rad;
}

GimbalTransforms gimbal_transforms(core::Phase phase, double true_angle_rad, double tilt_rad) {
  // The gimbal axis (gimbal x) along world x raised by tau toward world z: R_y(-tau) e_x =
  // (cos tau, 0, sin tau). Then the turn by theta about that axis.
  const Eigen::Quaterniond tilt(Eigen::AngleAxisd(-tilt_rad, Eigen::Vector3d::UnitY()));
  const Eigen::Quaterniond turn(
      Eigen::AngleAxisd(gimbal_angle(phase, true_angle_rad), Eigen::Vector3d::UnitX()));
  GimbalTransforms out;
  out.world_gimbal = (tilt * turn).normalized();
  out.gimbal_dut = Eigen::Quaterniond(mount_rotation(phase)).normalized();
  return out;
}

void SimulatedGimbalOptions::validate() const {
  if (!finite_non_negative(move_s)) throw std::invalid_argument("move_s must be finite and >= 0");
  if (!finite_non_negative(phase_change_s))
    throw std::invalid_argument("phase_change_s must be finite and >= 0");
  if (!finite_non_negative(settle_s))
    throw std::invalid_argument("settle_s must be finite and >= 0");
  if (!std::isfinite(ringing_rad) || std::abs(ringing_rad) > 0.5)
    throw std::invalid_argument("ringing_rad must be finite with |ringing_rad| <= 0.5 rad");
  if (!finite_non_negative(ringing_hz))
    throw std::invalid_argument("ringing_hz must be finite and >= 0");
  if (never_settle_phase != "x" && never_settle_phase != "y" && never_settle_phase != "z")
    throw std::invalid_argument("never_settle_phase must be x, y or z");
  std::set<std::pair<int, int>> seen;
  for (const core::Effect& e : effects) {
    if (!core::is_gimbal_effect(e.kind)) {
      throw std::invalid_argument("effects: " + e.label() +
                                  " acts on the sensor; configure it on the accelerometer");
    }
    if (!std::isfinite(e.value))
      throw std::invalid_argument("effects: " + e.label() + " is not finite");
    if (!seen.insert({static_cast<int>(e.kind), e.target}).second) {
      throw std::invalid_argument("effects: " + e.label() + " is given twice");
    }
    if (e.kind == core::EffectKind::AxisTilt && std::abs(e.value) >= core::kPi / 2) {
      throw std::invalid_argument("effects: " + e.label() + " must be below pi/2 in magnitude");
    }
  }
}

SimulatedGimbalDriver::SimulatedGimbalDriver(const SimulatedGimbalOptions& options)
    : options_(options) {
  options_.validate();
  for (const core::Effect& e : options_.effects) values_.push_back(e.value);
  // At rest at phase x, alpha = 0 (DUT z up) until the first move.
  target_ = GimbalTarget{};
  from_ = to_ = pose_of(target_);
}

double SimulatedGimbalDriver::true_angle(const GimbalTarget& target) const {
  core::DwellGeometry geom;
  geom.phase = target.phase;
  geom.angle_rad = target.angle_rad;
  geom.approach = target.approach;
  return core::true_angle(options_.effects, values_.data(), geom);
}

double SimulatedGimbalDriver::tilt(core::Phase phase) const {
  double tau = 0.0;
  for (std::size_t i = 0; i < options_.effects.size(); ++i) {
    const core::Effect& e = options_.effects[i];
    if (e.kind == core::EffectKind::AxisTilt && e.target == core::index(phase)) tau += values_[i];
  }
  return tau;
}

Eigen::Quaterniond SimulatedGimbalDriver::pose_of(const GimbalTarget& target) const {
  const GimbalTransforms t =
      gimbal_transforms(target.phase, true_angle(target), tilt(target.phase));
  return (t.world_gimbal * t.gimbal_dut).normalized();
}

void SimulatedGimbalDriver::move_to(const GimbalTarget& target, double t_s) {
  const bool phase_change = moved_ ? target.phase != target_.phase : target.phase != core::Phase::X;
  from_ = Eigen::Quaterniond(orientation(t_s).world_dut());
  to_ = pose_of(target);
  target_ = target;
  stopped_ = false;
  move_start_s_ = t_s;
  move_end_s_ = t_s + options_.move_s + (phase_change ? options_.phase_change_s : 0.0);
  moved_ = true;
}

bool SimulatedGimbalDriver::settled(double t_s) const {
  if (moved_ && !stopped_ && options_.never_settle_at_step >= 0 &&
      static_cast<int>(target_.step) == options_.never_settle_at_step &&
      options_.never_settle_phase == core::phase_name(target_.phase)) {
    return false;  // injected fault
  }
  return !moved_ || stopped_ || t_s >= move_end_s_ + options_.settle_s;
}

void SimulatedGimbalDriver::stop(double t_s) {
  const Eigen::Quaterniond here(orientation(t_s).world_dut());
  from_ = to_ = here;
  move_start_s_ = move_end_s_ = t_s;
  stopped_ = true;
}

GimbalTransforms SimulatedGimbalDriver::orientation(double t_s) const {
  Eigen::Quaterniond world_dut = to_;
  if (moved_ && t_s < move_end_s_) {
    const double duration = move_end_s_ - move_start_s_;
    const double s = duration > 0.0 ? (t_s - move_start_s_) / duration : 1.0;
    world_dut = from_.slerp(smooth_profile(s), to_);
  } else if (moved_ && !stopped_ && options_.ringing_rad != 0.0 && options_.settle_s > 0.0) {
    // Decaying oscillation about the rotation axis after the motion stops.
    const double dt = t_s - move_end_s_;
    const double r = options_.ringing_rad * std::exp(-dt / (options_.settle_s / 5.0)) *
                     std::sin(2.0 * core::kPi * options_.ringing_hz * dt);
    Eigen::Vector3d axis = Eigen::Vector3d::Zero();
    axis(core::index(target_.phase)) = 1.0;
    world_dut = to_ * Eigen::Quaterniond(Eigen::AngleAxisd(r, axis));
  }
  GimbalTransforms out;
  out.gimbal_dut = Eigen::Quaterniond(mount_rotation(target_.phase)).normalized();
  out.world_gimbal = (world_dut.normalized() * out.gimbal_dut.conjugate()).normalized();
  return out;
}

}  // namespace accel_intrinsics
