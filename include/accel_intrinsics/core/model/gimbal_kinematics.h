// Where the gimbal holds the device under test: the one motion profile of a move, the commanded
// pose along a schedule, and the stage kinematics of every gimbal driver (docs/design.md sections
// 1, 10 and 15). One definition for the simulator, every gimbal driver, the simulated
// accelerometer and the timing-lag estimator.
//
// Stage kinematics (docs/design.md section 15): a two-axis stage with the outer axis X along the
// world x axis and the inner axis Y on it holds the DUT at R_world_dut = Rx(X) Rz(Y) in a world
// frame with z up (REP 103). The default axis map puts the DUT of phase p at
//   x: (X, Y) = (alpha, 0), y: (alpha, 90 deg), z: (90 deg, alpha),
// where the specific force R^T (0, 0, g) is section 1's eq. (4) exactly:
//   x: g (0, sin a, cos a), y: g (sin a, 0, cos a), z: g (sin a, cos a, 0).
// A lab's own axis map (sign, zero, other axes) realises these same poses on its own stage; the
// drivers read the stage back into alpha and report the pose through these functions.
#pragma once

#include <Eigen/Core>
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

// Stage angles of the two-axis stage, rad: X the outer axis (about world x), Y the inner one.
struct StageAngles {
  double x_rad = 0.0;
  double y_rad = 0.0;
};
// R_world_dut = Rx(X) Rz(Y): maps DUT-frame vectors to world-frame vectors.
Eigen::Matrix3d stage_rotation(const StageAngles& stage);
// The default axis map: the stage angles that turn the DUT to alpha about its own p axis.
StageAngles default_stage_angles(Phase phase, double alpha_rad);
// The DUT's pose for (phase, alpha) through the default axis map, with the turning axis (the
// DUT's p axis, horizontal) raised by tilt_rad toward world z (the axis_tilt effect of model.h:
// the p component of the specific force becomes g sin(tilt), the others scale by cos(tilt)).
Eigen::Matrix3d phase_pose(Phase phase, double alpha_rad, double tilt_rad = 0.0);
// The specific force in the DUT frame, R_world_dut^T (0, 0, g) (REP 103: +g on the up axis).
Eigen::Vector3d specific_force_in_dut(const Eigen::Matrix3d& R_world_dut, double g);

}  // namespace core
}  // namespace accel_intrinsics
