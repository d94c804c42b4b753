// The bytes a calibration run holds, by part (docs/noise.md, issue 38).
#pragma once

#include <cstddef>

namespace accel_intrinsics {
namespace core {

// Bytes a run holds, by part (CalibrationRun::memory()): what grows with the run and what must
// not grow with a dwell's length or the IMU rate (issue 38; docs/noise.md).
struct RunMemory {
  std::size_t assembler = 0;    // reorder buffer (window x rate) and the assembler's table
  std::size_t long_rest = 0;    // the first dwell's statistics (constant)
  std::size_t clock_check = 0;  // 32 bytes per 10 ms of IMU time: grows with the run
  std::size_t moves = 0;        // samples around the moves (record_moves only)
  std::size_t table = 0;        // accepted rows
};

}  // namespace core
}  // namespace accel_intrinsics
