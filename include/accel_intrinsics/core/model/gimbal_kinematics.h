// Where the gimbal holds the device under test: the one motion profile of a move and the
// commanded pose along a schedule (docs/design.md sections 1 and 10). One definition for the
// simulator, the simulated gimbal driver and the timing-lag estimator.
#pragma once

#include <vector>

#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {

// The one motion profile of a move within a phase (simulator, ROS stand's simulated gimbal,
// timing-lag estimator): the fraction of the angle step done at time t, a raised cosine from 0 at
// the MOVING stamp to 1 at the SETTLED stamp (zero angular velocity at both ends); clamped to
// [0, 1] outside, 1 when the interval is empty.
double move_fraction(double t_s, double move_start_s, double settled_s);

// Commanded gimbal angle along the schedule at time t (seconds since the first MOVING): the
// phase, the angle (smooth move between steps, move_fraction), and whether the gimbal is at
// rest. A move that changes phase (remount) has no trajectory: the target angle at once.
struct GimbalPose {
  Phase phase = Phase::X;
  double angle_rad = 0.0;
  int approach = +1;
  bool at_rest = false;
};
GimbalPose gimbal_pose_at(const std::vector<ScheduledPosition>& schedule, double t_s);
// The model's geometry of a pose, time_s after t0 (the drift term's clock).
DwellGeometry geometry_of(const GimbalPose& pose, double time_s);

}  // namespace core
}  // namespace accel_intrinsics
