// A servo joint's motion for the joint controller emulator (joint_motion.h).
#include "accel_intrinsics/emulators/joint_motion.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace accel_intrinsics {

namespace {

constexpr double kPi = 3.14159265358979323846;

bool positive(double v) {
  return std::isfinite(v) && v > 0.0;
}

}  // namespace

void JointMotionOptions::validate() const {
  if (!positive(natural_frequency_hz))
    throw std::invalid_argument("natural_frequency_hz must be > 0 Hz");
  if (!(positive(damping_ratio) && damping_ratio <= 2.0))
    throw std::invalid_argument("damping_ratio must be in (0, 2]");
  if (!positive(max_speed_deg_s)) throw std::invalid_argument("max_speed_deg_s must be > 0 deg/s");
  if (!positive(max_step_s)) throw std::invalid_argument("max_step_s must be > 0 s");
  // Semi-implicit Euler stays close to the continuous motion only for steps well below 1 / wn.
  if (max_step_s * 2.0 * kPi * natural_frequency_hz > 0.1)
    throw std::invalid_argument("max_step_s must be below 0.1 / (2 pi natural_frequency_hz)");
}

double JointMotionOptions::small_step_overshoot() const {
  if (damping_ratio >= 1.0) return 0.0;
  return std::exp(-kPi * damping_ratio / std::sqrt(1.0 - damping_ratio * damping_ratio));
}

JointMotion::JointMotion(const JointMotionOptions& options, double position_rad)
    : options_(options), position_rad_(position_rad), command_rad_(position_rad) {
  options_.validate();
  wn_rad_s_ = 2.0 * kPi * options_.natural_frequency_hz;
  max_speed_rad_s_ = options_.max_speed_deg_s * kPi / 180.0;
}

void JointMotion::advance(double dt_s) {
  if (!(dt_s > 0.0) || !std::isfinite(dt_s)) return;
  const int n = static_cast<int>(std::ceil(dt_s / options_.max_step_s));
  const double h = dt_s / n;
  for (int i = 0; i < n; ++i) step(h);
}

void JointMotion::step(double h) {
  const double a = wn_rad_s_ * wn_rad_s_ * (command_rad_ - position_rad_) -
                   2.0 * options_.damping_ratio * wn_rad_s_ * velocity_rad_s_;
  velocity_rad_s_ = std::clamp(velocity_rad_s_ + a * h, -max_speed_rad_s_, max_speed_rad_s_);
  position_rad_ += velocity_rad_s_ * h;
}

}  // namespace accel_intrinsics
