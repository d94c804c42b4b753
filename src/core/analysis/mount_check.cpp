// The mount check (mount_check.h, docs/design.md section 15).
#include "accel_intrinsics/core/analysis/mount_check.h"

#include <cmath>
#include <stdexcept>

#include "accel_intrinsics/core/model/constants.h"

namespace accel_intrinsics {
namespace core {

namespace {

const PoseMean* find_pose(const std::vector<PoseMean>& poses, Phase phase, double angle_rad) {
  for (const PoseMean& p : poses) {
    if (p.phase != phase) continue;
    // The angle modulo a full turn, within 1 deg.
    const double d = std::remainder(p.angle_rad - angle_rad, 2.0 * kPi);
    if (std::abs(d) <= deg_to_rad(1.0)) return &p;
  }
  return nullptr;
}

}  // namespace

std::vector<PoseMean> mount_check_poses() {
  std::vector<PoseMean> poses;
  for (Phase p : kPhases) {
    for (double a : {0.0, kPi / 2.0}) {
      PoseMean pose;
      pose.phase = p;
      pose.angle_rad = a;
      poses.push_back(pose);
    }
  }
  return poses;
}

SetupObservation observe_poses(const std::vector<PoseMean>& poses) {
  SetupObservation obs;
  std::size_t silent = 0;
  for (Phase p : kPhases) {
    const PoseMean* at_0 = find_pose(poses, p, 0.0);
    const PoseMean* at_90 = find_pose(poses, p, kPi / 2.0);
    if (at_0 == nullptr || at_90 == nullptr)
      throw std::invalid_argument(std::string("mount check: phase ") + phase_name(p) +
                                  " needs a pose at 0 and at 90 deg");
    for (const PoseMean* pose : {at_0, at_90}) {
      if (pose->n > 0) continue;
      ++silent;
      obs.silent.push_back(std::string("phase ") + phase_name(p) + " at " +
                           (pose == at_0 ? "0" : "90") + " deg");
    }
    if (at_0->n == 0 || at_90->n == 0) continue;
    PhaseResponse& r = obs.phases[index(p)];
    r.present = true;
    r.at_0 = at_0->mean;
    r.at_90 = at_90->mean;
    r.level = 0.5 * (at_0->mean + at_90->mean);
  }
  obs.all_silent = silent == 2 * kNumPhases;
  return obs;
}

MountCheck check_mount(const std::vector<PoseMean>& poses, const SetupOptions& options) {
  MountCheck check;
  check.mistakes = judge_setup(observe_poses(poses), options);
  return check;
}

}  // namespace core
}  // namespace accel_intrinsics
