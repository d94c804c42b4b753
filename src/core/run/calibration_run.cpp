#include "accel_intrinsics/core/run/calibration_run.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "calibration_run_internal.h"

namespace accel_intrinsics {
namespace core {

using namespace run_detail;

void CalibrationRun::apply(RunEvent event) {
  if (event == RunEvent::Reset) events_.clear();
  events_.push_back(event);
  const RunTransition* t = run_transition(state_, event);
  if (t == nullptr) return;  // ignored in this state (run_transition_table())
  if (!t->collecting) {
    state_ = t->to;
  } else if (done_stamp_s_ || fitting_) {
    state_ = RunState::Fitting;  // a DONE waits for its window, or a fit still runs
  } else if (commands_in_run_ == 0) {
    state_ = RunState::Idle;
  } else {
    state_ = live_dwell_ ? RunState::Dwelling : RunState::Running;
  }
}

CalibrationRun::CalibrationRun(const RunOptions& options)
    : options_(options), assembler_(options.assembler), clock_check_(options.clock) {
  connect_assembler();
}

void CalibrationRun::connect_assembler() {
  moves_.clear();
  // The long rest starts where the assembler starts the dwell: after the settle discard.
  long_rest_.set_settle_discard_s(options_.assembler.settle_discard_s);
  // Events and samples in stamp order: the moves (timing lag) when asked, the long rest always.
  const bool record_moves = options_.record_moves;
  assembler_.set_release_observers(
      [this, record_moves](const GimbalEvent& e) {
        if (record_moves) moves_.add_command(e);
        long_rest_.add_command(e);
      },
      [this, record_moves](const ImuSample& s) {
        if (record_moves) moves_.add_sample(s);
        long_rest_.add_sample(s);
      });
}

std::optional<NoiseModel> CalibrationRun::noise_model(std::string* why) const {
  try {
    return long_rest_.noise_model(table_, 0.0);
  } catch (const std::invalid_argument& e) {
    if (why != nullptr) *why = e.what();
    return std::nullopt;
  }
}

void CalibrationRun::log(RunAction::Level level, const std::string& text) {
  RunAction a;
  a.kind = RunAction::Kind::Log;
  a.level = level;
  a.text = text;
  actions_.push_back(std::move(a));
}

void CalibrationRun::emit(RunAction::Kind kind) {
  RunAction a;
  a.kind = kind;
  actions_.push_back(std::move(a));
}

void CalibrationRun::log_repeating(const std::string& text) {
  log(RunAction::Level::Warn, text);
  actions_.back().repeating = true;
}

RunActions CalibrationRun::take_actions() {
  RunActions out;
  out.swap(actions_);
  return out;
}

void CalibrationRun::emit_fit() {
  if (options_.check_clock) {
    ClockCheckResult clock = clock_check_.result();
    if (clock.offset_found) {
      // Name the offset to set in total, on top of the one already applied.
      clock.offset_s -= options_.imu_time_offset_s;
      fit_error_ = clock.message("imu_time_offset_s");
      log(RunAction::Level::Error, "no fit: " + fit_error_);
      apply(RunEvent::ClockMismatch);
      return;
    }
  }
  RunAction a;
  a.kind = RunAction::Kind::FitNow;
  a.table = table_;
  if (options_.record_moves) {
    a.move_commands = moves_.commands();
    a.move_samples = moves_.samples();
  }
  a.counters = counters();
  std::string why_not;
  a.noise_model = noise_model(&why_not);
  if (a.noise_model) {
    std::ostringstream m;
    m << "noise model " << a.noise_model->kind() << " from " << a.noise_model->source << " ("
      << a.noise_model->rest_samples << " samples)";
    log(RunAction::Level::Info, m.str());
  } else if (!why_not.empty()) {
    log(RunAction::Level::Warn, "no noise model from the long rest (white weights): " + why_not);
  }
  a.fit_ticket = ++fit_ticket_;
  fitting_ = true;
  apply(RunEvent::FitStarted);
  actions_.push_back(std::move(a));
}

AssemblerCounters CalibrationRun::counters() const {
  AssemblerCounters c = assembler_.counters();
  add_counters(counters_before_, &c);
  return c;
}

// ---- Inputs ------------------------------------------------------------------------------------

RunActions CalibrationRun::on_command(const GimbalEvent& event) {
  ++commands_received_;
  ++commands_in_run_;
  const bool run_start =
      event.state == GimbalState::Moving && event.phase == Phase::X && event.step == 0;
  if (restored_next_ == Restored::Resume) {
    // First command after a restart from a checkpoint: a fresh run, or the one to continue.
    if (run_start) {
      restored_next_ = Restored::None;
      log(RunAction::Level::Warn, "a new run starts; the checkpoint of " +
                                      std::to_string(table_.rows.size()) + " dwells is discarded");
      for (RunAction& a : reset("a new run starts over the checkpoint")) {
        actions_.push_back(std::move(a));
      }
      ++commands_in_run_;
    } else {
      begin_resume("calibration node restarted from its checkpoint");
    }
  }
  const bool previous_run_over = done_stamp_s_ || assembler_.done() || has_result() || fitting_ ||
                                 !fit_error_.empty() || !fault_.empty();
  if (run_start && previous_run_over && !rewind_pending()) {
    if (done_stamp_s_ && fault_.empty()) {
      // The previous run's DONE is still in the reorder window: finish it first.
      accept_rows(assembler_.flush());
      done_stamp_s_.reset();
      emit_fit();
    }
    // The previous run's fit (just handed out, or still running) goes out all the same.
    if (fitting_) superseded_fit_ticket_ = fit_ticket_;
    RunActions after_reset = reset("a new run starts (MOVING to phase x step 0 after DONE)");
    for (RunAction& a : after_reset) actions_.push_back(std::move(a));
    ++commands_in_run_;
  }
  clock_check_.add_command(event);
  if (!std::isfinite(table_.time_origin_s)) {
    table_.time_origin_s = event.stamp_s;  // t0 of the drift term: the first command of the run
    steps_seen_ = event.steps;
    emit(RunAction::Kind::CheckpointState);
  }
  steps_seen_ = event.steps;
  if (event.state != GimbalState::Done) {  // a DONE of an abort names the position it ended
    last_event_ = event;
  }
  // Live view (arrival order) for the IMU watchdog, and the announced dwells (stamp order).
  if (event.state == GimbalState::Settled) {
    live_dwell_ = event;
  } else {
    live_dwell_.reset();
  }
  if (!announced_.empty() && !std::isfinite(announced_.back().end_s)) {
    announced_.back().end_s = event.stamp_s;
  }
  if (event.state == GimbalState::Settled) {
    announced_.push_back(
        {event.phase, event.step, event.stamp_s, std::numeric_limits<double>::infinity(), false});
  }
  if (event.state == GimbalState::Done) {
    // A DONE inside an open blackout belongs to the protocol before the rewind: drop it.
    for (const Blackout& b : blackouts_) {
      if (event.stamp_s >= b.begin_s && event.stamp_s < b.end_s) {
        std::ostringstream s;
        s.setf(std::ios::fixed);
        s.precision(3);
        s << "DONE at " << event.stamp_s << " s ignored (waiting for the rewound protocol)";
        log(RunAction::Level::Info, s.str());
        apply(RunEvent::Moving);  // not in a dwell any more
        return take_actions();
      }
    }
  }
  accept_rows(source_.add_command(event));
  if (event.state == GimbalState::Done) {
    done_stamp_s_ = event.stamp_s;
    log(RunAction::Level::Info, "DONE received, fitting after the reorder window");
    apply(RunEvent::DoneReceived);
  } else {
    apply(event.state == GimbalState::Settled ? RunEvent::Settled : RunEvent::Moving);
  }
  warn_on_new_drops();
  return take_actions();
}

RunActions CalibrationRun::on_sample(const ImuSample& received) {
  ImuSample sample = received;
  sample.stamp_s += options_.imu_time_offset_s;
  if (sample.stamp_s > newest_sample_stamp_s_) newest_sample_stamp_s_ = sample.stamp_s;
  const CompletedRows rows = source_.add_sample(sample);
  clock_check_.add_sample(sample);
  if (!rows.empty()) accept_rows(rows);
  const AssemblerCounters& c = assembler_.counters();
  if (c.dropped_non_finite != warned_.dropped_non_finite ||
      c.dropped_backwards != warned_.dropped_backwards || c.dropped_late != warned_.dropped_late) {
    warn_on_new_drops();
  }
  return take_actions();
}

RunActions CalibrationRun::on_channel_sample(const ChannelSample& received) {
  ChannelSample reading = received;
  reading.stamp_s += options_.imu_time_offset_s;  // the IMU's clock
  accept_rows(source_.add_channel_sample(reading));
  return take_actions();
}

RunActions CalibrationRun::on_controller_state(const std::string& state,
                                               const std::string& message) {
  // A running controller never goes back to IDLE by itself: a new process has taken its place
  // (respawned after a crash). The run it drove is still open here: continue it (at tick()).
  const bool was_running = controller_state_ == "MOVING" || controller_state_ == "SETTLED" ||
                           controller_state_ == "REMOUNT" || controller_state_ == "WAIT_OPERATOR";
  if (state == "IDLE" && was_running && !done_stamp_s_ && !assembler_.done() && !has_result() &&
      fault_.empty() && controller_abort_.empty()) {
    controller_restarted_ = true;
    log(RunAction::Level::Warn, "the gimbal controller restarted in the middle of the run");
  }
  controller_state_ = state;
  if (state == "ABORTED") {
    // "ABORTED: <reason>"
    const std::size_t colon = message.find(": ");
    const std::string reason = colon == std::string::npos ? message : message.substr(colon + 2);
    const bool ours = !fault_.empty() || pending_ == Pending::Abort;  // we asked for it
    if (reason != controller_abort_ && !ours && options_.retry_on_fault && last_event_ &&
        !controller_fault_ && !has_result() && !rewind_pending() && !fitting_) {
      // A fault of the gimbal itself at the position of the latest command: measure it again
      // (at tick(), after the reorder window, so that the dwells before it are complete).
      ControllerFault f;
      f.reason = "the gimbal controller aborted: " + reason;
      f.phase = last_event_->phase;
      f.step = last_event_->step;
      f.in_dwell = last_event_->state == GimbalState::Settled;
      f.stamp_s = last_event_->stamp_s;
      controller_fault_ = f;
      log(RunAction::Level::Warn, f.reason);
      apply(RunEvent::ControllerFault);
    } else if (reason != controller_abort_ && !controller_fault_) {
      controller_abort_ = reason;
      if (fault_.empty()) log(RunAction::Level::Error, "the gimbal controller aborted: " + reason);
    }
  } else if (state == "STARTING" || state == "MOVING" || state == "SETTLED" || state == "REMOUNT" ||
             state == "WAIT_OPERATOR") {
    controller_abort_.clear();
  }
  return take_actions();
}

RunActions CalibrationRun::on_streams_idle() {
  if (!done_stamp_s_) return take_actions();
  log(RunAction::Level::Info, "no messages or clock ticks since DONE: fitting now");
  return tick(*done_stamp_s_ + options_.assembler.reorder_window_s);
}

void CalibrationRun::retry_controller_fault() {
  const ControllerFault f = *controller_fault_;
  controller_fault_.reset();
  // Everything before the faulted position is complete: its rows go to the table before the
  // assembler restarts. A dwell the fault cut short is measured again (blackout from its
  // SETTLED); after a fault in a move, from the MOVING that ended the previous dwell.
  if (f.in_dwell) {
    accept_rows(assembler_.flush_until(f.stamp_s - 1e-9));
  } else {
    accept_rows(assembler_.flush_until(f.stamp_s));
  }
  const int approach = approach_of_next_row(f.phase, f.step);
  // Retried (rewind at the position) or, after max_retries, the run is aborted with the
  // controller's words.
  raise_fault(f.reason + " at " + position_label(f.phase, f.step, approach), f.phase, f.step,
              approach, f.stamp_s);
}

RunActions CalibrationRun::tick(double now_s) {
  if (controller_fault_ &&
      now_s >= controller_fault_->stamp_s + options_.assembler.reorder_window_s) {
    retry_controller_fault();
  }
  if (controller_restarted_ && !rewind_pending()) {
    controller_restarted_ = false;
    begin_resume("the gimbal controller restarted mid-run");
  }
  const bool idle_stand = options_.resume_idle_controller && controller_state_ == "IDLE";
  if (restored_next_ == Restored::Resume && (controller_state_ == "DONE" || idle_stand)) {
    // No gimbal command since the restart and the controller finished the protocol meanwhile
    // (this node died in the last dwells): resume after a grace period. An idle controller
    // (a fresh stand over an old checkpoint) is started from here only with
    // resume_idle_controller (the whole stand PC restarted; a lab's unattended stand).
    if (std::isnan(resume_deadline_s_)) {
      resume_deadline_s_ = now_s + std::max(2.0, 2.0 * options_.assembler.reorder_window_s);
    } else if (now_s >= resume_deadline_s_) {
      begin_resume(idle_stand ? "stand restarted (calibration node and an idle gimbal "
                                "controller) from its checkpoint"
                              : "calibration node restarted from its checkpoint");
    }
  }
  if (restored_next_ == Restored::Fit) {
    // The checkpoint holds a finished run: its result again.
    restored_next_ = Restored::None;
    emit_fit();
  }
  const double window = options_.assembler.reorder_window_s;
  if (done_stamp_s_ && now_s >= *done_stamp_s_ + window && !controller_fault_) {
    accept_rows(assembler_.flush());
    done_stamp_s_.reset();
    warn_on_new_drops();
    check_watchdogs(now_s);
    if (aborted()) {
      // An aborted run gives no certificate, whatever it has measured.
      log(RunAction::Level::Error, "the run was aborted; no fit: " + missing_message());
      apply(RunEvent::DoneDiscarded);
    } else if (!rewind_pending()) {
      emit_fit();
    } else {
      log(RunAction::Level::Warn, "DONE but a position is to be measured again; no fit yet");
    }
  } else if (now_s > window) {
    accept_rows(assembler_.flush_until(now_s - window));
    warn_on_new_drops();
  }
  check_watchdogs(now_s);
  // A due request to the gimbal controller.
  if (pending_ != Pending::None && now_s >= request_after_s_) {
    RunAction a;
    a.kind = pending_ == Pending::Resume ? RunAction::Kind::ResumeAt : RunAction::Kind::Abort;
    a.request = request_;
    a.request.run_generation = run_generation_;
    pending_ = Pending::None;
    actions_.push_back(std::move(a));
  }
  return take_actions();
}

void CalibrationRun::ask_again(Pending kind, const ControllerRequest& request, double now_s) {
  // The controller is not there (yet): ask again in a moment (unless a newer request replaced
  // this one meanwhile).
  if (!unreached_warned_) {
    log(RunAction::Level::Warn, std::string("gimbal_controller/") +
                                    (kind == Pending::Resume ? "resume" : "abort") +
                                    " not available; retrying");
    unreached_warned_ = true;
  }
  if (pending_ == Pending::None) {
    pending_ = kind;
    request_ = request;
    if (kind == Pending::Resume) apply(RunEvent::ResumeRequested);
  }
  request_after_s_ = now_s + options_.request_retry_s;
}

RunActions CalibrationRun::on_resume_reply(const ControllerRequest& request, bool reached,
                                           bool success, const std::string& message,
                                           double moving_stamp_s, double now_s) {
  if (request.run_generation != run_generation_) return take_actions();  // of a reset run
  if (!reached) {
    ask_again(Pending::Resume, request, now_s);
    return take_actions();
  }
  unreached_warned_ = false;
  if (!success || !(std::isfinite(moving_stamp_s) && moving_stamp_s > 0.0)) {
    fault_ = "the gimbal controller refused to resume at " +
             position_label(request.phase, request.step, request.approach) +
             (request.after ? " (after)" : "") + ": " + message;
    log(RunAction::Level::Error, fault_);
    blackouts_.clear();
    apply(RunEvent::ResumeRefused);
    emit(RunAction::Kind::CheckpointState);
    return take_actions();
  }
  for (Blackout& b : blackouts_) {
    if (!std::isfinite(b.end_s)) b.end_s = moving_stamp_s;
  }
  log(RunAction::Level::Warn, "gimbal controller: " + message);
  if (!rewind_pending() && !controller_fault_) apply(RunEvent::ResumeConfirmed);
  return take_actions();
}

RunActions CalibrationRun::on_abort_reply(const ControllerRequest& request, bool reached,
                                          const std::string& message, double now_s) {
  if (request.run_generation != run_generation_) return take_actions();  // of a reset run
  if (!reached) {
    ask_again(Pending::Abort, request, now_s);
    return take_actions();
  }
  unreached_warned_ = false;
  log(RunAction::Level::Error, "asked the gimbal controller to abort: " + message);
  return take_actions();
}

bool CalibrationRun::fit_may_publish(std::uint64_t fit_ticket) const {
  if (fit_ticket != 0 && fit_ticket == superseded_fit_ticket_) return true;
  return fit_ticket == fit_ticket_ && fitting_ && fault_.empty() && !rewind_pending();
}

RunActions CalibrationRun::on_fit_finished(std::uint64_t fit_ticket, bool published,
                                           const std::string& error) {
  if (fit_ticket != fit_ticket_ || !fitting_) return take_actions();  // reset or superseded
  fitting_ = false;
  if (published) {
    fit_error_.clear();
    apply(RunEvent::FitPublished);
    emit(RunAction::Kind::CheckpointState);
  } else if (!error.empty()) {
    fit_error_ = error;
    apply(RunEvent::FitFailed);
    log(RunAction::Level::Error, "no result after DONE: " + missing_message());
  } else {
    apply(RunEvent::FitWithheld);
    // A watchdog fired after the fit: no certificate from this one.
    log(RunAction::Level::Warn, "a fault came while the fit ran; its result is not published");
  }
  return take_actions();
}

RunActions CalibrationRun::restore(const PositionTable& table, const CheckpointState& state) {
  if (state_ != RunState::Idle || commands_received_ > 0 || restored_) {
    throw std::logic_error(
        std::string("CalibrationRun::restore: only a fresh run is restored (this one is ") +
        run_state_name(CalibrationRun::state()) + ")");
  }
  table_ = table;
  table_.time_origin_s = state.time_origin_s;
  steps_seen_ = state.steps;
  restored_ = true;
  fault_ = state.fault;
  if (!fault_.empty()) {
    log(RunAction::Level::Warn, "resume: the checkpointed run was aborted (" + fault_ + ")");
    apply(RunEvent::RestoredAborted);
  } else if (state.done) {
    restored_next_ = Restored::Fit;
    apply(RunEvent::RestoredDone);
  } else {
    restored_next_ = Restored::Resume;  // rewind the controller when it shows up
    apply(RunEvent::RestoredMidRun);
  }
  std::ostringstream s;
  s.precision(17);
  s << "resume: restored " << table_.rows.size() << " dwells (N = " << state.steps
    << ", t0 = " << state.time_origin_s << " s)" << (state.done ? ", run complete" : "");
  log(RunAction::Level::Warn, s.str());
  return take_actions();
}

RunActions CalibrationRun::reset(const std::string& reason) {
  const std::size_t dwells = table_.rows.size();
  assembler_.reset();
  clock_check_.reset();
  long_rest_.clear();
  connect_assembler();
  done_stamp_s_.reset();
  fitting_ = false;
  ++fit_ticket_;  // a fit still running belongs to the discarded run
  fit_error_.clear();
  warned_ = AssemblerCounters();
  counters_before_ = AssemblerCounters();
  commands_rejected_ = 0;
  commands_in_run_ = 0;
  ++run_generation_;
  table_ = PositionTable();
  rows_discarded_ = 0;
  restored_ = false;
  restored_next_ = Restored::None;
  resume_deadline_s_ = std::numeric_limits<double>::quiet_NaN();
  controller_restarted_ = false;
  blackouts_.clear();
  pending_ = Pending::None;
  request_ = ControllerRequest();
  fault_.clear();
  controller_abort_.clear();
  controller_fault_.reset();
  last_event_.reset();
  last_fault_.clear();
  retries_.clear();
  retries_total_ = 0;
  live_dwell_.reset();
  announced_.clear();
  newest_sample_stamp_s_ = -std::numeric_limits<double>::infinity();
  apply(RunEvent::Reset);
  emit(RunAction::Kind::ClearCheckpoint);
  log(RunAction::Level::Info,
      "reset (" + reason + "); discarded " + std::to_string(dwells) + " dwells");
  return take_actions();
}

}  // namespace core

}  // namespace accel_intrinsics
