#include "accel_intrinsics/core/model/gimbal_kinematics.h"

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

double move_fraction(double t_s, double move_start_s, double settled_s) {
  const double travel_s = settled_s - move_start_s;
  if (!(travel_s > 0.0)) return 1.0;
  const double x = std::min(1.0, std::max(0.0, (t_s - move_start_s) / travel_s));
  return 0.5 - 0.5 * std::cos(x * kPi);
}

}  // namespace core
}  // namespace accel_intrinsics
