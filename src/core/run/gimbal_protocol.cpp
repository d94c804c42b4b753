// The gimbal controller's protocol state machine (gimbal_protocol.h).
#include "accel_intrinsics/core/run/gimbal_protocol.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "accel_intrinsics/core/model/text_format.h"
namespace accel_intrinsics {
namespace core {

namespace {

ProtocolAction log_action(ProtocolAction::Level level, const std::string& text) {
  ProtocolAction a;
  a.kind = ProtocolAction::Kind::Log;
  a.level = level;
  a.text = text;
  return a;
}

void append(ProtocolActions* out, const ProtocolActions& more) {
  out->insert(out->end(), more.begin(), more.end());
}

}  // namespace

GimbalTarget target_of(const ScheduledPosition& position) {
  GimbalTarget target;
  target.phase = position.phase;
  target.step = position.step;
  target.steps = position.steps;
  target.angle_rad = position.angle_rad;
  target.approach = position.approach;
  return target;
}

const char* protocol_state_name(ProtocolState state) {
  switch (state) {
    case ProtocolState::Idle: return "IDLE";
    case ProtocolState::Starting: return "STARTING";
    case ProtocolState::Moving: return "MOVING";
    case ProtocolState::Dwelling: return "SETTLED";
    case ProtocolState::Remount: return "REMOUNT";
    case ProtocolState::Done: return "DONE";
    case ProtocolState::Aborted: return "ABORTED";
    case ProtocolState::WaitOperator: return "WAIT_OPERATOR";
  }
  return "?";
}

void GimbalProtocolOptions::validate() const {
  core::validate(protocol);
  if (!(std::isfinite(start_delay_s) && start_delay_s >= 0.0))
    throw std::invalid_argument("start_delay_s must be finite and >= 0 s");
  if (!(std::isfinite(settle_timeout_s) && settle_timeout_s > 0.0))
    throw std::invalid_argument("settle_timeout_s must be > 0 s");
  if (!(std::isfinite(progress_hz) && progress_hz > 0.0))
    throw std::invalid_argument("progress_hz must be > 0 Hz");
}

GimbalProtocol::GimbalProtocol(const GimbalProtocolOptions& options, GimbalMotion* gimbal)
    : options_(options), gimbal_(gimbal) {
  options_.validate();
  if (gimbal_ == nullptr) throw std::invalid_argument("GimbalProtocol needs a gimbal");
  schedule_ = build_schedule(options_.protocol);
  if (schedule_.empty()) throw std::invalid_argument("the protocol has no positions");
  autostart_pending_ = options_.autostart;
}

bool GimbalProtocol::running() const {
  return state_ == ProtocolState::Moving || state_ == ProtocolState::Dwelling ||
         state_ == ProtocolState::Remount || state_ == ProtocolState::WaitOperator;
}

void GimbalProtocol::start_next_run_at(std::size_t index) {
  start_index_ = std::min(index, schedule_.size() - 1);
}

std::size_t GimbalProtocol::find_position(Phase phase, std::uint32_t step, int approach,
                                          bool after) const {
  for (std::size_t i = 0; i < schedule_.size(); ++i) {
    const ScheduledPosition& p = schedule_[i];
    if (p.phase == phase && p.step == step && p.approach == approach) return after ? i + 1 : i;
  }
  return schedule_.size();
}

void GimbalProtocol::command(double stamp_s, GimbalState state, ProtocolActions* out) const {
  const ScheduledPosition& p = schedule_[index_];
  ProtocolAction a;
  a.kind = ProtocolAction::Kind::Command;
  a.command.stamp_s = stamp_s;
  a.command.phase = p.phase;
  a.command.step = p.step;
  a.command.steps = p.steps;
  a.command.angle_rad = p.angle_rad;
  a.command.state = state;
  out->push_back(a);
}

void GimbalProtocol::progress(double now_s, bool log, ProtocolActions* out) {
  last_progress_s_ = now_s;
  ProtocolAction a;
  a.kind = ProtocolAction::Kind::Progress;
  a.log = log;
  a.status = status(now_s);
  out->push_back(a);
}

ProtocolReply GimbalProtocol::start(double now_s) {
  ProtocolReply r;
  if (state_ == ProtocolState::Starting || running()) {
    std::ostringstream s;
    s << "already running (" << protocol_state_name(state_) << " phase "
      << phase_name(schedule_[index_].phase) << " step " << schedule_[index_].step << ")";
    r.message = s.str();
    return r;
  }
  if (!recover_gimbal(now_s, &r.actions)) {
    r.message = "start refused: " + last_error_;
    return r;
  }
  state_ = ProtocolState::Starting;
  state_since_s_ = now_s;
  start_at_s_ = now_s + options_.start_delay_s;
  index_ = start_index_;
  start_index_ = 0;  // the resume_* parameters place the first run only
  last_error_.clear();
  r.success = true;
  r.message = "started: " + std::to_string(schedule_.size()) + " positions, about " +
              fixed(time_left_s(now_s), 0) + " s";
  r.actions.push_back(log_action(ProtocolAction::Level::Info, r.message));
  progress(now_s, false, &r.actions);
  return r;
}

ProtocolReply GimbalProtocol::abort(double now_s, const std::string& reason) {
  ProtocolReply r;
  if (state_ != ProtocolState::Starting && !running()) {
    r.message = std::string("not running (") + protocol_state_name(state_) + ")";
    return r;
  }
  const bool had_commands = state_ != ProtocolState::Starting;
  gimbal_->stop(now_s);
  // DONE ends the run and closes the open dwell; the calibration node then reports what is
  // missing. The progress topic says ABORTED.
  if (had_commands) command(now_s, GimbalState::Done, &r.actions);
  state_ = ProtocolState::Aborted;
  state_since_s_ = now_s;
  last_error_ = reason;
  r.success = true;
  r.message = "aborted: " + reason;
  r.actions.push_back(log_action(ProtocolAction::Level::Warn, r.message));
  progress(now_s, false, &r.actions);
  return r;
}

ProtocolReply GimbalProtocol::continue_after_remount(double now_s) {
  ProtocolReply r;
  if (state_ == ProtocolState::WaitOperator) {
    // The operator has set the stage: the gimbal checks the pose (MOVING until it settles).
    gimbal_->operator_continue(now_s);
    state_ = ProtocolState::Moving;
    state_since_s_ = now_s;
    r.success = true;
    r.message = std::string("checking the pose of phase ") + phase_name(schedule_[index_].phase) +
                " step " + std::to_string(schedule_[index_].step);
    r.actions.push_back(log_action(ProtocolAction::Level::Info, r.message));
    progress(now_s, false, &r.actions);
    return r;
  }
  if (state_ != ProtocolState::Remount) {
    r.message = std::string("not waiting for a remount (") + protocol_state_name(state_) + ")";
    return r;
  }
  const Phase phase = schedule_[index_].phase;
  state_ = ProtocolState::Moving;
  state_since_s_ = now_s;
  // The move again: the settling time starts now, after the operator's hands left the DUT.
  if (!drive(now_s, &r.actions)) {
    r.message = "continue failed: " + last_error_;
    return r;
  }
  r.success = true;
  r.message = std::string("continuing with phase ") + phase_name(phase);
  r.actions.push_back(log_action(ProtocolAction::Level::Info, "remount done, " + r.message));
  progress(now_s, false, &r.actions);
  return r;
}

ProtocolReply GimbalProtocol::resume(double now_s, std::size_t index, const std::string& reason) {
  ProtocolReply r;
  ++resumes_;
  if (!recover_gimbal(now_s, &r.actions)) {
    r.message = "resume refused: " + last_error_;
    return r;
  }
  std::ostringstream s;
  s.precision(17);
  if (index >= schedule_.size()) {
    // Nothing left after that position: the protocol is complete.
    if (running()) gimbal_->stop(now_s);
    index_ = schedule_.size() - 1;
    command(now_s, GimbalState::Done, &r.actions);
    state_ = ProtocolState::Done;
    state_since_s_ = now_s;
    s << "resume (" << reason << "): nothing left, DONE stamp=" << now_s;
  } else {
    begin_move(index, now_s, &r.actions);
    const ScheduledPosition& p = schedule_[index];
    s << "resume (" << reason << "): moving to phase " << phase_name(p.phase) << " step " << p.step
      << (p.approach < 0 ? " (return sweep)" : "") << ", position " << index + 1 << " of "
      << schedule_.size() << ", MOVING stamp=" << now_s;
  }
  last_error_.clear();
  r.success = true;
  r.message = s.str();
  r.actions.push_back(log_action(ProtocolAction::Level::Warn, r.message));
  progress(now_s, false, &r.actions);
  return r;
}

void GimbalProtocol::begin_move(std::size_t index, double now_s, ProtocolActions* out) {
  index_ = index;
  // The command goes out first with this stamp; the gimbal starts moving at the same instant,
  // so every sample stamped before it was taken at rest.
  command(now_s, GimbalState::Moving, out);
  state_ = ProtocolState::Moving;
  state_since_s_ = now_s;
  drive(now_s, out);
}

bool GimbalProtocol::drive(double now_s, ProtocolActions* out) {
  try {
    gimbal_->move_to(target_of(schedule_[index_]), now_s);
  } catch (const GimbalFault& e) {
    driver_fault(now_s, e.what(), out);
    return false;
  }
  return true;
}

bool GimbalProtocol::recover_gimbal(double now_s, ProtocolActions* out) {
  if (!faulted_) return true;
  try {
    gimbal_->recover(now_s);
  } catch (const GimbalFault& e) {
    last_error_ = std::string("could not recover the gimbal after its fault: ") + e.what();
    out->push_back(log_action(ProtocolAction::Level::Error, last_error_));
    progress(now_s, false, out);
    return false;
  }
  faulted_ = false;
  out->push_back(log_action(ProtocolAction::Level::Warn,
                            "the " + gimbal_->name() + " gimbal recovered from its fault"));
  return true;
}

void GimbalProtocol::driver_fault(double now_s, const std::string& what, ProtocolActions* out) {
  faulted_ = true;
  const ProtocolReply aborted = abort(now_s, "gimbal fault: " + what);
  append(out, aborted.actions);
  if (!aborted.success) last_error_ = "gimbal fault: " + what;
  out->push_back(log_action(ProtocolAction::Level::Error, last_error_));
}

ProtocolActions GimbalProtocol::tick(double now_s) {
  ProtocolActions out;
  if (autostart_pending_) {
    autostart_pending_ = false;
    append(&out, start(now_s).actions);
  }
  // The hardware first: status polls, which may find a fault. A faulted device is left alone
  // until a start or resume recovers it (a silent one would block every tick).
  try {
    if (!faulted_) gimbal_->update(now_s);
  } catch (const GimbalFault& e) {
    if (state_ == ProtocolState::Starting || running()) {
      driver_fault(now_s, e.what(), &out);
    } else {
      ProtocolAction a = log_action(ProtocolAction::Level::Warn, e.what());
      a.repeating = true;
      out.push_back(a);
    }
  }
  bool changed = false;
  switch (state_) {
    case ProtocolState::Starting:
      if (now_s >= start_at_s_) {
        begin_move(index_, now_s, &out);
        changed = true;
      }
      break;
    case ProtocolState::Moving:
      if (gimbal_->needs_operator(now_s)) {
        // A gimbal turned by hand: wait for the operator (no settle timeout).
        state_ = ProtocolState::WaitOperator;
        state_since_s_ = now_s;
        ++operator_waits_;
        const std::string complaint = gimbal_->operator_complaint();
        out.push_back(log_action(
            complaint.empty() ? ProtocolAction::Level::Info : ProtocolAction::Level::Warn,
            (complaint.empty() ? "" : complaint + "; ") + gimbal_->operator_request() +
                ", then call " + options_.continue_service));
        changed = true;
      } else if (gimbal_->settled(now_s)) {
        // Stamped when the gimbal settled, which the driver may know better than this tick
        // (the simulated one does; the timing-lag estimator reads the move from these stamps).
        double stamp_s = now_s;
        const double settled_s = gimbal_->settled_at(now_s);
        if (std::isfinite(settled_s) && settled_s > state_since_s_ && settled_s < now_s)
          stamp_s = settled_s;
        command(stamp_s, GimbalState::Settled, &out);
        state_ = ProtocolState::Dwelling;
        state_since_s_ = stamp_s;
        changed = true;
      } else if (now_s - state_since_s_ > options_.settle_timeout_s) {
        const ScheduledPosition& p = schedule_[index_];
        std::ostringstream reason;
        reason << "the gimbal did not settle at phase " << phase_name(p.phase) << " step " << p.step
               << " within settle_timeout_s = " << options_.settle_timeout_s << " s";
        const std::string device = gimbal_->status_text();
        if (!device.empty()) reason << " (" << gimbal_->name() << " reports " << device << ")";
        const ProtocolReply aborted = abort(now_s, reason.str());
        append(&out, aborted.actions);
        out.push_back(log_action(ProtocolAction::Level::Error, aborted.message));
      }
      break;
    case ProtocolState::Dwelling:
      // The first position's dwell is the long rest (initial_rest_s), also when a rewind
      // measures it again.
      if (now_s - state_since_s_ >= dwell_duration_s(options_.protocol, index_)) {
        if (index_ + 1 < schedule_.size()) {
          const Phase from = schedule_[index_].phase;
          begin_move(index_ + 1, now_s, &out);
          const Phase to = schedule_[index_].phase;
          if (state_ == ProtocolState::Moving && to != from && gimbal_->manual_remount(to)) {
            // MOVING went out (the dwell is closed) and the stage turns to the phase's first
            // position; the operator remounts the DUT there and calls continue.
            state_ = ProtocolState::Remount;
            out.push_back(log_action(ProtocolAction::Level::Warn,
                                     std::string("remount the DUT for phase ") + phase_name(to) +
                                         " (it turns about its own " + phase_name(to) +
                                         " axis), then call " + options_.continue_service));
          }
        } else {
          command(now_s, GimbalState::Done, &out);
          state_ = ProtocolState::Done;
          state_since_s_ = now_s;
          out.push_back(
              log_action(ProtocolAction::Level::Info,
                         "protocol done (" + std::to_string(schedule_.size()) + " positions)"));
        }
        changed = true;
      }
      break;
    default: break;
  }
  const bool periodic = now_s - last_progress_s_ >= 1.0 / options_.progress_hz;
  if (changed || periodic || now_s < last_progress_s_) progress(now_s, periodic, &out);
  return out;
}

double GimbalProtocol::time_left_s(double now_s) const {
  const double total = schedule_.back().dwell_end_s;
  const double since = std::isnan(state_since_s_) ? 0.0 : std::max(0.0, now_s - state_since_s_);
  const ScheduledPosition& p = schedule_[index_];
  switch (state_) {
    case ProtocolState::Idle: return total + options_.start_delay_s;
    case ProtocolState::Starting: return total + std::max(0.0, start_at_s_ - now_s);
    case ProtocolState::Moving:
    case ProtocolState::Remount:
    case ProtocolState::WaitOperator:
      return std::max(0.0, total - std::min(p.settled_s, p.move_start_s + since));
    case ProtocolState::Dwelling:
      return std::max(0.0, total - std::min(p.dwell_end_s, p.settled_s + since));
    default: return 0.0;
  }
}

ProtocolStatus GimbalProtocol::status(double now_s) const {
  ProtocolStatus st;
  st.state = state_;
  st.running = running();
  st.position = schedule_[std::min(index_, schedule_.size() - 1)];
  st.positions = schedule_.size();
  // 1-based number of the position being visited; all of them once done.
  st.position_number =
      state_ == ProtocolState::Done ? schedule_.size() : (st.running ? index_ + 1 : 0);
  st.time_left_s = time_left_s(now_s);
  const double total = schedule_.back().dwell_end_s;
  st.fraction = state_ == ProtocolState::Done
                    ? 1.0
                    : std::min(1.0, std::max(0.0, 1.0 - st.time_left_s / total));
  st.in_state_s = std::isnan(state_since_s_) ? 0.0 : now_s - state_since_s_;
  st.slow_to_settle =
      state_ == ProtocolState::Moving && st.in_state_s > 0.5 * options_.settle_timeout_s;
  st.resumes = resumes_;
  st.last_error = last_error_;
  st.operator_waits = operator_waits_;
  if (state_ == ProtocolState::WaitOperator) {
    st.operator_request = gimbal_->operator_request();
    st.operator_complaint = gimbal_->operator_complaint();
    st.stage_deg = gimbal_->operator_targets_deg();
  }
  st.level = state_ == ProtocolState::Aborted ? ProtocolStatus::Level::Error
             : state_ == ProtocolState::Remount || state_ == ProtocolState::WaitOperator
                 ? ProtocolStatus::Level::Warn
                 : ProtocolStatus::Level::Ok;
  const ScheduledPosition& p = st.position;
  std::ostringstream text;
  text << protocol_state_name(state_);
  if (st.running) {
    text << " phase " << phase_name(p.phase) << " step " << p.step + 1 << "/" << p.steps;
    if (is_closing_step(p.step, p.steps)) text << " (closing position, 360 deg)";
  }
  if (state_ == ProtocolState::Aborted) text << ": " << last_error_;
  if (state_ == ProtocolState::Remount) {
    text << ": remount the DUT to turn about its own " << phase_name(p.phase) << " axis, then call "
         << options_.continue_service;
  }
  if (state_ == ProtocolState::WaitOperator) {
    text << ": ";
    if (!st.operator_complaint.empty()) text << st.operator_complaint << "; ";
    text << st.operator_request << ", then call " << options_.continue_service;
  }
  st.text = text.str();
  return st;
}

}  // namespace core
}  // namespace accel_intrinsics
