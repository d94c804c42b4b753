// Simulated gimbal backend and the tf chain that realizes docs/design.md eq. (4).
#include "accel_intrinsics/drivers/gimbal_driver.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>
#include <utility>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/gimbal_kinematics.h"
#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {

namespace {

bool finite_non_negative(double v) {
  return std::isfinite(v) && v >= 0.0;
}

}  // namespace

GimbalTransforms split_at_inner_axis(const Eigen::Matrix3d& world_dut, core::Phase phase,
                                     double alpha_rad) {
  GimbalTransforms out;
  out.gimbal_dut = Eigen::Quaterniond(Eigen::AngleAxisd(
      core::default_stage_angles(phase, alpha_rad).y_rad, Eigen::Vector3d::UnitZ()));
  out.world_gimbal =
      (Eigen::Quaterniond(world_dut).normalized() * out.gimbal_dut.conjugate()).normalized();
  return out;
}

GimbalTransforms gimbal_transforms(core::Phase phase, double true_angle_rad, double tilt_rad) {
  return split_at_inner_axis(core::phase_pose(phase, true_angle_rad, tilt_rad), phase,
                             true_angle_rad);
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

double SimulatedGimbalDriver::commanded_angle(double t_s) const {
  if (stopped_) return stopped_angle_;
  if (!moved_ || !in_phase_move_) return target_.angle_rad;
  return from_angle_ +
         (target_.angle_rad - from_angle_) * core::move_fraction(t_s, move_start_s_, settled_s_);
}

void SimulatedGimbalDriver::move_to(const GimbalTarget& target, double t_s) {
  // Within a phase the gimbal turns along the core motion profile (the one the simulator and the
  // timing-lag estimator use) from where it is commanded now; a phase change is a remount,
  // which has no such trajectory (the DUT is carried over by the shortest rotation).
  // The first move mounts the DUT, as the schedule has it (build_schedule: phase_change_s).
  const bool same_phase = moved_ && target.phase == target_.phase;
  from_angle_ = commanded_angle(t_s);
  in_phase_move_ = same_phase && on_path_;
  from_ = Eigen::Quaterniond(orientation(t_s).world_dut());
  to_ = pose_of(target);
  target_ = target;
  stopped_ = false;
  on_path_ = true;
  move_start_s_ = t_s;
  motion_end_s_ = t_s + (same_phase ? options_.move_s : options_.phase_change_s);
  settled_s_ = motion_end_s_ + options_.settle_s;
  moved_ = true;
}

bool SimulatedGimbalDriver::settled(double t_s) const {
  if (moved_ && !stopped_ && options_.never_settle_at_step >= 0 &&
      static_cast<int>(target_.step) == options_.never_settle_at_step &&
      options_.never_settle_phase == core::phase_name(target_.phase)) {
    return false;  // injected fault
  }
  return !moved_ || stopped_ || t_s >= settled_s_;
}

double SimulatedGimbalDriver::settled_at(double t_s) const {
  if (!settled(t_s)) return t_s;
  return std::min(t_s, stopped_ || !moved_ ? t_s : settled_s_);
}

void SimulatedGimbalDriver::stop(double t_s) {
  const Eigen::Quaterniond here(orientation(t_s).world_dut());
  // Stopped in the middle of a remount the DUT is off every angle of the phase: the next move
  // is then carried out as a remount too.
  on_path_ = !moved_ || in_phase_move_ || t_s >= motion_end_s_;
  stopped_angle_ = commanded_angle(t_s);
  from_ = to_ = here;
  move_start_s_ = motion_end_s_ = settled_s_ = t_s;
  stopped_ = true;
}

GimbalTransforms SimulatedGimbalDriver::orientation(double t_s) const {
  Eigen::Quaterniond world_dut = to_;
  if (moved_ && !stopped_ && t_s < settled_s_) {
    if (in_phase_move_) {
      GimbalTarget along = target_;
      along.angle_rad = commanded_angle(t_s);
      world_dut = pose_of(along);
    } else if (t_s < motion_end_s_) {
      world_dut = from_.slerp(core::move_fraction(t_s, move_start_s_, motion_end_s_), to_);
    }
  }
  if (moved_ && !stopped_ && options_.ringing_rad != 0.0 && options_.settle_s > 0.0 &&
      t_s >= motion_end_s_) {
    // Decaying oscillation about the rotation axis once the drive has done its part of the move.
    const double dt = t_s - motion_end_s_;
    const double r = options_.ringing_rad * std::exp(-dt / (options_.settle_s / 5.0)) *
                     std::sin(2.0 * core::kPi * options_.ringing_hz * dt);
    Eigen::Vector3d axis = Eigen::Vector3d::Zero();
    axis(core::index(target_.phase)) = 1.0;
    world_dut = world_dut * Eigen::Quaterniond(Eigen::AngleAxisd(r, axis));
  }
  return split_at_inner_axis(world_dut.normalized().toRotationMatrix(), target_.phase,
                             target_.angle_rad);
}

}  // namespace accel_intrinsics
