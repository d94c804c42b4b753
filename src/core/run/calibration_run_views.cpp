// CalibrationRun (calibration_run.h): the views (state, status, checkpoint, what is missing).
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "accel_intrinsics/core/run/calibration_run.h"

namespace accel_intrinsics {
namespace core {

RunState CalibrationRun::state() const {
  if (state_ != RunState::Done && !controller_abort_.empty()) return RunState::Aborted;
  return state_;
}

RunStatus CalibrationRun::status(double now_s) const {
  RunStatus s;
  s.state = state();
  s.dwells_per_phase = positions_per_phase(table_);
  s.steps = steps();
  s.counters = counters();
  s.commands_received = commands_received_;
  s.commands_rejected = commands_rejected_;
  s.fault = !fault_.empty() ? fault_ : controller_abort_;
  s.last_fault = last_fault_;
  s.fit_error = fit_error_;
  s.retries = retries_total_;
  s.dwells_discarded = rows_discarded_;
  s.restored = restored_;
  s.in_dwell = assembler_.current_dwell(&s.dwell_phase, &s.dwell_step, &s.dwell_samples);
  s.imu_silent =
      options_.imu_timeout_s > 0.0 && live_dwell_ &&
      now_s - std::max(live_dwell_->stamp_s, newest_sample_stamp_s_) > options_.imu_timeout_s;
  s.newest_sample_stamp_s = newest_sample_stamp_s_;
  return s;
}

RunMemory CalibrationRun::memory() const {
  RunMemory m;
  m.assembler = assembler_.memory_bytes();
  m.long_rest = long_rest_.memory_bytes();
  m.clock_check = clock_check_.memory_bytes();
  m.moves = moves_.commands().capacity() * sizeof(GimbalEvent) +
            moves_.samples().capacity() * sizeof(ImuSample);
  m.table = table_.rows.capacity() * sizeof(DwellRecord);
  return m;
}

CheckpointState CalibrationRun::checkpoint_state() const {
  CheckpointState c;
  c.time_origin_s = table_.time_origin_s;
  c.steps = steps_seen_;
  c.rows = table_.rows.size();
  c.done = has_result();
  c.fault = fault_;
  return c;
}

std::string CalibrationRun::missing_message() const {
  const std::array<int, 3> counts = positions_per_phase(table_);
  const std::uint32_t n = steps();
  const int needed = n ? static_cast<int>(n) : options_.min_positions_per_phase;
  std::ostringstream s;
  if (!fault_.empty()) {
    s << "run aborted: " << fault_ << "; ";
  } else if (!controller_abort_.empty()) {
    s << "run aborted by the gimbal controller: " << controller_abort_ << "; ";
  }
  s << "no result yet: ";
  if (!fit_error_.empty()) s << "the fit failed (" << fit_error_ << "); ";
  // Which phases are missing dwells, and how many.
  bool first = true;
  for (Phase p : kPhases) {
    if (counts[index(p)] >= needed) continue;
    s << (first ? "missing " : ", ") << "phase " << phase_name(p) << " (" << counts[index(p)]
      << " of " << (n ? std::to_string(n) : ">= " + std::to_string(needed)) << " dwells)";
    first = false;
  }
  if (first) s << "all phases have their dwells";
  if (commands_received_ == 0) s << "; no gimbal command received yet";
  Phase phase;
  std::uint32_t step = 0;
  std::uint64_t samples = 0;
  if (assembler_.current_dwell(&phase, &step, &samples)) {
    s << "; in dwell phase " << phase_name(phase) << " step " << step << " (" << samples
      << " samples)";
  }
  if (done_stamp_s_) s << "; DONE received, fitting after the reorder window";
  if (fitting_) s << "; fitted, the discrepancy analysis is running (result after it)";
  if (rewind_pending()) s << "; waiting for the gimbal controller to resume";
  if (retries_total_ > 0) s << "; " << retries_total_ << " position(s) measured again";
  const AssemblerCounters c = counters();
  s << "; samples used " << c.samples_used << ", dropped outside dwells "
    << c.dropped_outside_dwell;
  return s.str();
}

}  // namespace core

}  // namespace accel_intrinsics
