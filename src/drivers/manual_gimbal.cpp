// The manual gimbal driver (manual_gimbal.h).
#include "accel_intrinsics/drivers/manual_gimbal.h"

#include <algorithm>
#include <cmath>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/gimbal_kinematics.h"
#include "accel_intrinsics/core/model/text_format.h"

namespace accel_intrinsics {

namespace {

using core::fixed;

double wrap_2pi(double a) {
  a = std::fmod(a, 2.0 * core::kPi);
  return a < 0.0 ? a + 2.0 * core::kPi : a;
}

std::string pose_words(core::Phase phase, double alpha_rad) {
  return std::string("phase ") + core::phase_name(phase) + " at " +
         fixed(core::rad_to_deg(wrap_2pi(alpha_rad)), 1) + " deg";
}

}  // namespace

double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

PoseMatch nearest_pose(const Eigen::Vector3d& direction, core::Phase prefer) {
  const Eigen::Vector3d d = direction.normalized();
  PoseMatch best;
  bool have = false;
  for (core::Phase p : core::kPhases) {
    // eq. (4): x: (0, sin a, cos a), y: (sin a, 0, cos a), z: (sin a, cos a, 0).
    const int i = core::index(p);
    double alpha = 0.0;
    switch (p) {
      case core::Phase::X: alpha = std::atan2(d.y(), d.z()); break;
      case core::Phase::Y: alpha = std::atan2(d.x(), d.z()); break;
      default: alpha = std::atan2(d.x(), d.y()); break;
    }
    PoseMatch m;
    m.phase = p;
    m.alpha_rad = wrap_2pi(alpha);
    m.off_plane_rad = std::asin(std::min(1.0, std::abs(d(i))));
    const double margin = 1e-9;
    if (!have || m.off_plane_rad < best.off_plane_rad - margin ||
        (std::abs(m.off_plane_rad - best.off_plane_rad) <= margin && p == prefer)) {
      best = m;
      have = true;
    }
  }
  return best;
}

void ManualGimbalOptions::validate() const {
  if (!(std::isfinite(pose_tolerance_deg) && pose_tolerance_deg > 0.0 && pose_tolerance_deg < 90.0))
    throw std::invalid_argument("pose_tolerance_deg must be in (0, 90) deg");
  if (!(std::isfinite(check_s) && check_s > 0.0))
    throw std::invalid_argument("check_s must be > 0 s");
  if (min_samples < 1) throw std::invalid_argument("min_samples must be >= 1");
  if (imu_topic.empty()) throw std::invalid_argument("imu_topic is empty");
  // Every phase is set by hand: consecutive phases may use the same axis without a remount flag.
  AxisMap map = axis_map;
  for (PhaseAxes& p : map.phases) p.manual_remount = true;
  map.validate({});
}

ManualGimbal::ManualGimbal(const ManualGimbalOptions& options) : options_(options) {
  options_.validate();
}

GimbalDriverTopics ManualGimbal::topics() const {
  GimbalDriverTopics t;
  t.imu = options_.imu_topic;
  return t;
}

void ManualGimbal::on_imu(double t_s, const Eigen::Vector3d& outputs) {
  if (!checking_ || t_s < check_from_s_ || !outputs.allFinite()) return;
  sum_ += outputs;
  ++samples_;
}

void ManualGimbal::move_to(const GimbalTarget& target, double /*t_s*/) {
  first_of_phase_ = !moved_ || target.phase != target_.phase;
  moved_ = true;
  target_ = target;
  waiting_ = true;
  checking_ = false;
  settled_ = false;
  complaint_.clear();
}

void ManualGimbal::operator_continue(double t_s) {
  waiting_ = false;
  checking_ = true;
  check_from_s_ = t_s;
  sum_.setZero();
  samples_ = 0;
}

void ManualGimbal::update(double t_s) {
  if (!checking_ || t_s - check_from_s_ < options_.check_s || samples_ < options_.min_samples)
    return;
  checking_ = false;
  const Eigen::Vector3d measured = sum_ / static_cast<double>(samples_);
  const Eigen::Vector3d expected =
      core::specific_force_in_dut(core::phase_pose(target_.phase, target_.angle_rad), 1.0);
  const double off = angle_between(measured, expected);
  if (measured.norm() > 0.0 && off <= core::deg_to_rad(options_.pose_tolerance_deg)) {
    settled_ = true;
    settled_s_ = t_s;
    complaint_.clear();
    return;
  }
  const PoseMatch seen = nearest_pose(measured, target_.phase);
  complaint_ = "the IMU sees " + pose_words(seen.phase, seen.alpha_rad) +
               (seen.off_plane_rad > core::deg_to_rad(options_.pose_tolerance_deg)
                    ? " (" + fixed(core::rad_to_deg(seen.off_plane_rad), 1) + " deg off its plane)"
                    : std::string()) +
               ", not " + pose_words(target_.phase, target_.angle_rad) + " (" +
               fixed(core::rad_to_deg(off), 1) +
               " deg apart, pose_tolerance_deg = " + fixed(options_.pose_tolerance_deg, 1) + ")";
  waiting_ = true;
}

void ManualGimbal::stop(double t_s) {
  waiting_ = false;
  checking_ = false;
  settled_ = true;
  settled_s_ = t_s;
}

std::string ManualGimbal::operator_request() const {
  std::string out = std::string("phase ") + core::phase_name(target_.phase) + ": set ";
  const PhaseAxes& p = options_.axis_map.phases[core::index(target_.phase)];
  const std::map<std::string, double> deg = operator_targets_deg();
  // The turning axis first, then the held ones when the phase begins (they stay put within it).
  out += p.axis + " to " + fixed(deg.at(p.axis), 1) + " deg";
  for (const auto& a : deg) {
    if (a.first != p.axis && first_of_phase_)
      out += ", " + a.first + " to " + fixed(a.second, 1) + " deg";
  }
  return out;
}

std::map<std::string, double> ManualGimbal::operator_targets_deg() const {
  std::map<std::string, double> deg =
      options_.axis_map.positions_deg(target_.phase, target_.angle_rad);
  // An indexing head reads 0..360.
  for (auto& a : deg) {
    a.second = std::fmod(a.second, 360.0);
    if (a.second < 0.0) a.second += 360.0;
    if (std::abs(a.second) < 5e-7 || std::abs(a.second - 360.0) < 5e-7) a.second = 0.0;
  }
  return deg;
}

std::string ManualGimbal::status_text() const {
  if (!complaint_.empty()) return complaint_;
  if (checking_) return "checking the pose (" + std::to_string(samples_) + " IMU samples)";
  if (waiting_) return "waiting for the operator";
  return "";
}

GimbalTransforms ManualGimbal::orientation(double /*t_s*/) const {
  // Commanded: the hand's path is not known.
  return gimbal_transforms(target_.phase, target_.angle_rad, 0.0);
}

}  // namespace accel_intrinsics
