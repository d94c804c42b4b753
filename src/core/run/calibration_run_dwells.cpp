// CalibrationRun (calibration_run.h): accepted dwells, faults and their retries, resume, the
// watchdogs.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "accel_intrinsics/core/run/calibration_run.h"
#include "calibration_run_internal.h"

namespace accel_intrinsics {
namespace core {

using namespace run_detail;

void CalibrationRun::accept_rows(const CompletedRows& rows) {
  // The assembler has returned: a row that raises a fault may restart it.
  for (const DwellRecord& row : rows) accept_row(row);
}

void CalibrationRun::accept_row(const DwellRecord& row) {
  for (Announced& a : announced_) {
    if (a.begin_s + options_.assembler.settle_discard_s == row.t_start_s) a.recorded = true;
  }
  const std::string label = std::string(phase_name(row.phase)) + " " +
                            std::to_string(row.step + 1) + "/" + std::to_string(steps_seen_);
  if (in_blackout(row.t_start_s, row.t_end_s)) {
    ++rows_discarded_;
    log(RunAction::Level::Info,
        "dwell " + label + (is_closing_step(row.step, steps_seen_) ? " (closing position)" : "") +
            " measured before the rewind: discarded");
    return;
  }
  if (!fault_.empty()) return;
  if (options_.min_samples_per_dwell > 0 && row.n < options_.min_samples_per_dwell) {
    const int approach = approach_of_next_row(row.phase, row.step);
    std::ostringstream what;
    what << "dwell " << position_label(row.phase, row.step, approach) << " has " << row.n
         << " samples (fewer than min_samples_per_dwell = " << options_.min_samples_per_dwell
         << ")";
    raise_fault(what.str(), row.phase, row.step, approach,
                row.t_start_s - options_.assembler.settle_discard_s);
    return;
  }
  table_.rows.push_back(row);
  RunAction a;
  a.kind = RunAction::Kind::DwellAccepted;
  a.row = row;
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(5);
  s << "dwell " << label
    << (is_closing_step(row.step, steps_seen_) ? " (closing position, 360 deg)" : "")
    << ": n = " << row.n << ", mean (" << row.mean(0) << ", " << row.mean(1) << ", " << row.mean(2)
    << ") m/s^2";
  a.text = s.str();
  actions_.push_back(std::move(a));
}

int CalibrationRun::approach_of_next_row(Phase phase, std::uint32_t step) const {
  return approach_of_appended_row(table_, phase, step_angle(step, std::max(steps(), 1u)));
}

void CalibrationRun::raise_fault(const std::string& what, Phase phase, std::uint32_t step,
                                 int approach, double dwell_start_s) {
  last_fault_ = what;
  std::uint32_t& tries = retries_[std::make_tuple(index(phase), step, approach)];
  if (options_.retry_on_fault && tries < options_.max_retries) {
    ++tries;
    ++retries_total_;
    log(RunAction::Level::Warn, what + "; measuring it again (retry " + std::to_string(tries) +
                                    " of " + std::to_string(options_.max_retries) + ")");
    Blackout b;
    b.begin_s = dwell_start_s;
    blackouts_.push_back(b);
    pending_ = Pending::Resume;
    request_ = ControllerRequest();
    request_.phase = phase;
    request_.step = step;
    request_.approach = approach;
    request_.after = false;
    request_.reason = what;
    request_after_s_ = -std::numeric_limits<double>::infinity();
    done_stamp_s_.reset();
    restart_assembler();
    apply(RunEvent::FaultRetried);
    return;
  }
  std::ostringstream reason;
  reason << what;
  if (options_.retry_on_fault) {
    reason << "; gave up after " << tries << (tries == 1 ? " retry" : " retries")
           << " (max_retries)";
  } else {
    reason << " (on_fault: abort)";
  }
  fault_ = reason.str();
  log(RunAction::Level::Error, "run aborted: " + fault_);
  pending_ = Pending::Abort;
  request_ = ControllerRequest();
  request_.reason = fault_;
  request_after_s_ = -std::numeric_limits<double>::infinity();
  apply(RunEvent::FaultAborted);
  emit(RunAction::Kind::CheckpointState);
}

void CalibrationRun::restart_assembler() {
  // The rewound protocol starts on a fresh assembler: events of the abandoned stretch still
  // buffered are dropped with the old one; its counters carry over.
  add_counters(assembler_.counters(), &counters_before_);
  if (!assembler_.counters().last_warning.empty()) {  // the newest warning wins
    counters_before_.last_warning = assembler_.counters().last_warning;
  }
  assembler_.reset();
  connect_assembler();  // also clears the recorded moves: the lag uses those after the rewind
  // A fault before any row was accepted is in the first dwell (or before it): the rewound
  // protocol measures the long rest again. After that the rest is an accepted row: keep it.
  if (table_.rows.empty()) long_rest_.clear();
  warned_ = AssemblerCounters();
  live_dwell_.reset();
  announced_.clear();
}

void CalibrationRun::begin_resume(const std::string& cause) {
  // Have the controller go to the position after the last recorded dwell (or to the first one),
  // and discard everything measured before its MOVING (a dwell cut short, samples taken while
  // nobody drove the gimbal).
  if (restored_next_ == Restored::Resume) restored_next_ = Restored::None;
  pending_ = Pending::Resume;
  request_ = ControllerRequest();
  request_after_s_ = -std::numeric_limits<double>::infinity();
  blackouts_.push_back(Blackout());  // everything until the rewound MOVING
  moves_.clear();                    // the lag is estimated on the moves after it
  // The rewound protocol begins with its long rest again when no row was accepted.
  if (table_.rows.empty()) long_rest_.clear();
  apply(RunEvent::ResumeRequested);
  if (!table_.rows.empty()) {
    const DwellRecord& last = table_.rows.back();
    request_.phase = last.phase;
    request_.step = last.step;
    request_.approach = dwell_geometries(table_).back().approach;
    request_.after = true;
    request_.reason = cause;
    log(RunAction::Level::Warn,
        cause + ": resuming after " + position_label(last.phase, last.step, request_.approach) +
            " (" + std::to_string(table_.rows.size()) + " dwells recorded)");
  } else {
    request_.reason = cause + ", no dwell recorded";
    log(RunAction::Level::Warn, cause + ": resuming from the first position (no dwell recorded)");
  }
}

bool CalibrationRun::rewind_pending() const {
  if (pending_ != Pending::None) return true;
  for (const Blackout& b : blackouts_) {
    if (!std::isfinite(b.end_s)) return true;
  }
  return false;
}

bool CalibrationRun::in_blackout(double t_start_s, double t_end_s) const {
  for (const Blackout& b : blackouts_) {
    if (t_end_s > b.begin_s && t_start_s < b.end_s) return true;
  }
  return false;
}

void CalibrationRun::check_watchdogs(double now_s) {
  if (!fault_.empty() || rewind_pending()) return;
  // A dwell that ended without a single sample (the assembler records nothing for it).
  const double released = now_s - options_.assembler.reorder_window_s;
  for (const Announced& a : announced_) {
    if (a.recorded || !std::isfinite(a.end_s) || a.end_s > released) continue;
    if (in_blackout(a.begin_s, a.end_s)) continue;
    if (options_.min_samples_per_dwell > 0 || options_.imu_timeout_s > 0.0) {
      const int approach = approach_of_next_row(a.phase, a.step);
      const Announced copy = a;
      announced_.clear();
      raise_fault(
          "dwell " + position_label(copy.phase, copy.step, approach) + " has no samples at all",
          copy.phase, copy.step, approach, copy.begin_s);
      return;
    }
  }
  while (!announced_.empty() &&
         (announced_.front().recorded ||
          (std::isfinite(announced_.front().end_s) && announced_.front().end_s <= released))) {
    announced_.erase(announced_.begin());
  }
  // The IMU stream stopped during a dwell.
  if (options_.imu_timeout_s > 0.0 && live_dwell_) {
    const double dwell_start = live_dwell_->stamp_s;
    const double silent = now_s - std::max(dwell_start, newest_sample_stamp_s_);
    if (silent > options_.imu_timeout_s && !in_blackout(dwell_start, dwell_start + 1e-9)) {
      const Phase phase = live_dwell_->phase;
      const std::uint32_t step = live_dwell_->step;
      const int approach = approach_of_next_row(phase, step);
      std::ostringstream what;
      what.setf(std::ios::fixed);
      what.precision(1);
      what << "IMU stream stopped: no samples for " << silent << " s during dwell "
           << position_label(phase, step, approach)
           << " (imu_timeout_s = " << options_.imu_timeout_s << ")";
      live_dwell_.reset();
      // Dwells before this one are complete: process them before the assembler restarts.
      accept_rows(assembler_.flush_until(dwell_start - 1e-9));
      raise_fault(what.str(), phase, step, approach, dwell_start);
    }
  }
}

void CalibrationRun::warn_on_new_drops() {
  const AssemblerCounters& c = assembler_.counters();
  if (c.dropped_non_finite > warned_.dropped_non_finite) {
    log_repeating("dropped IMU samples with NaN or infinite values (" +
                  std::to_string(c.dropped_non_finite) + " so far)");
  }
  if (c.dropped_backwards > warned_.dropped_backwards) {
    log_repeating("dropped IMU samples whose stamp went backwards (" +
                  std::to_string(c.dropped_backwards) + " so far)");
  }
  if (c.dropped_late > warned_.dropped_late) {
    log_repeating("dropped messages that arrived after the reorder window (" +
                  std::to_string(c.dropped_late) + " so far; raise reorder_window_s?)");
  }
  if (c.commands_out_of_order > warned_.commands_out_of_order) {
    log_repeating("gimbal command out of protocol order (" +
                  std::to_string(c.commands_out_of_order) + " so far): " + c.last_warning);
  }
  warned_ = c;
}

}  // namespace core

}  // namespace accel_intrinsics
