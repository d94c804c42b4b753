// The mount check before a run (docs/design.md section 15, `supervise --check-mount`): the IMU's
// mean reading over about 1 s at alpha = 0 and 90 deg of every phase, judged against section 1 by
// the one judgement of setup mistakes (setup_mistakes.h). ROS-free: supervise collects the six
// means and hands them to the check_mount tool, which calls this.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "accel_intrinsics/core/analysis/setup_mistakes.h"
#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {

// One pose: the commanded phase and angle, and the IMU's mean over the samples averaged there.
struct PoseMean {
  Phase phase = Phase::X;
  double angle_rad = 0.0;
  std::uint64_t n = 0;  // samples averaged (0: the IMU said nothing there)
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();  // outputs, output unit
};

// The poses the check visits, in order: x 0, x 90, y 0, y 90, z 0, z 90 deg.
std::vector<PoseMean> mount_check_poses();

struct MountCheck {
  std::vector<SetupMistake> mistakes;  // empty: the mount agrees with section 1
  bool correct() const { return mistakes.empty(); }
};

// Throws std::invalid_argument when a phase lacks its pose at 0 or at 90 deg (within 1 deg).
SetupObservation observe_poses(const std::vector<PoseMean>& poses);
MountCheck check_mount(const std::vector<PoseMean>& poses, const SetupOptions& options = {});

}  // namespace core
}  // namespace accel_intrinsics
