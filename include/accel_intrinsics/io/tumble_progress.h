// The live tumble's progress as JSON (the calibration node's calibration/tumble_progress topic in
// mode: tumble; scripts/supervise --tumble reads it):
//   {"rests", "rejected", "samples", "still_s", "fitted", "fit_error", "coverage": {"complete",
//    "missing": [...]}, "relative_std": {name: value}, "largest_relative_std", "largest_name",
//    "next_pose": {"up": [x, y, z], "words"}, "target_reached", "message"}
#pragma once

#include <string>

#include "accel_intrinsics/core/run/tumble_session.h"

namespace accel_intrinsics {
namespace io {

std::string tumble_progress_json(const core::TumbleProgress& progress);

}  // namespace io
}  // namespace accel_intrinsics
