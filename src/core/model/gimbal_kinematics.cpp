#include "accel_intrinsics/core/model/gimbal_kinematics.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "accel_intrinsics/core/model/constants.h"

namespace accel_intrinsics {
namespace core {

GimbalPose gimbal_pose_at(const std::vector<ScheduledPosition>& schedule, double t_s) {
  GimbalPose pose;
  if (schedule.empty()) return pose;
  // The last position whose move has started.
  auto it =
      std::upper_bound(schedule.begin(), schedule.end(), t_s,
                       [](double t, const ScheduledPosition& p) { return t < p.move_start_s; });
  if (it == schedule.begin()) {
    pose.phase = schedule.front().phase;
    pose.angle_rad = schedule.front().angle_rad;
    pose.approach = schedule.front().approach;
    pose.at_rest = true;
    return pose;
  }
  const std::size_t i = static_cast<std::size_t>(std::distance(schedule.begin(), it)) - 1;
  const ScheduledPosition& target = schedule[i];
  pose.phase = target.phase;
  pose.approach = target.approach;
  pose.angle_rad = target.angle_rad;
  pose.at_rest = t_s >= target.settled_s;
  // Between MOVING and SETTLED the gimbal travels (within a phase) along a smooth profile.
  const bool same_phase = i > 0 && schedule[i - 1].phase == target.phase;
  if (same_phase && t_s < target.settled_s) {
    const double from = schedule[i - 1].angle_rad;
    pose.angle_rad = from + (target.angle_rad - from) *
                                move_fraction(t_s, target.move_start_s, target.settled_s);
  }
  return pose;
}

DwellGeometry geometry_of(const GimbalPose& pose, double time_s) {
  DwellGeometry geom;
  geom.phase = pose.phase;
  geom.angle_rad = pose.angle_rad;
  geom.time_s = time_s;
  geom.approach = pose.approach;
  return geom;
}

Eigen::Matrix3d stage_rotation(const StageAngles& stage) {
  return (Eigen::AngleAxisd(stage.x_rad, Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(stage.y_rad, Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

StageAngles default_stage_angles(Phase phase, double alpha_rad) {
  StageAngles s;
  switch (phase) {
    case Phase::X: s.x_rad = alpha_rad; break;
    case Phase::Y:
      s.x_rad = alpha_rad;
      s.y_rad = kPi / 2.0;
      break;
    case Phase::Z:
    default:
      s.x_rad = kPi / 2.0;
      s.y_rad = alpha_rad;
      break;
  }
  return s;
}

Eigen::Matrix3d phase_pose(Phase phase, double alpha_rad, double tilt_rad) {
  const Eigen::Matrix3d R = stage_rotation(default_stage_angles(phase, alpha_rad));
  if (tilt_rad == 0.0) return R;
  // The turning axis u = R e_p is horizontal (x: +x, y: -x, z: -y in the world). A rotation by
  // tilt about k = u x e_z takes u to cos(tilt) u + sin(tilt) e_z and scales the vertical part of
  // every vector normal to u by cos(tilt): f_p = g sin(tilt), f_q = cos(tilt) f_q(untilted).
  const Eigen::Vector3d u = R.col(index(phase));
  const Eigen::Vector3d k = u.cross(Eigen::Vector3d::UnitZ()).normalized();
  return Eigen::AngleAxisd(tilt_rad, k).toRotationMatrix() * R;
}

Eigen::Vector3d specific_force_in_dut(const Eigen::Matrix3d& R_world_dut, double g) {
  return R_world_dut.transpose() * Eigen::Vector3d(0.0, 0.0, g);
}

double move_fraction(double t_s, double move_start_s, double settled_s) {
  const double travel_s = settled_s - move_start_s;
  if (!(travel_s > 0.0)) return 1.0;
  const double x = std::min(1.0, std::max(0.0, (t_s - move_start_s) / travel_s));
  return 0.5 - 0.5 * std::cos(x * kPi);
}

}  // namespace core
}  // namespace accel_intrinsics
