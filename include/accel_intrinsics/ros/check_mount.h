// check_mount: the judgement of `supervise --check-mount` (docs/design.md section 15) as a tool.
// supervise drives the gimbal to alpha = 0 and 90 deg of every phase, averages about 1 s of IMU
// at each, and writes the six poses to its standard input, one a line:
//   PHASE ANGLE_DEG N MEAN_U MEAN_V MEAN_W        (e.g. "y 90 100 9.79 0.01 0.05"; # comments)
// It prints "mount correct" or one line per setup mistake ("axis_sign[y]: ...; fix: ...") and
// exits 0 (correct), 4 (a mistake named) or 1 (the input could not be judged).
#pragma once

#include <iosfwd>
#include <string>

#include "accel_intrinsics/core/analysis/mount_check.h"

namespace accel_intrinsics {

constexpr int kMountCorrect = 0;
constexpr int kMountCouldNotRun = 1;
constexpr int kMountMistake = 4;

struct CheckMountArguments {
  double gravity = 9.80665;           // local gravity, m/s^2
  std::string output_unit = "m/s^2";  // the calibration's output_unit
};

// Parses the poses (throws std::invalid_argument naming the line).
std::vector<core::PoseMean> read_poses(std::istream& in);
int run_check_mount(std::istream& in, const CheckMountArguments& args, std::ostream& out,
                    std::ostream& err);

}  // namespace accel_intrinsics
