// The gimbal controller's protocol as a state machine, ROS-free (docs/design.md sections 4 and 10).
//
// GimbalProtocol walks the schedule of build_schedule() over a gimbal. Its shell (the
// gimbal_controller node, a core test) feeds it plain calls with the time in seconds and carries
// out the actions it returns; it never calls back into the shell:
//
//   inputs                                  actions (returned by every input)
//   tick(now_s)                   ---->     Command   publish gimbal/command (MOVING, SETTLED,
//   start(now_s)                                      DONE) at its stamp
//   abort(now_s, reason)                    Log       a line for the shell's log
//   continue_after_remount(now_s)           Progress  publish the status it carries

//   resume(now_s, index, reason)
//
// The gimbal is injected: the protocol moves it, polls it, asks whether it settled and recovers
// it after a fault itself (a fault is a GimbalFault thrown by move_to() or update(), whose words
// end in the abort reason). The shell keeps the same gimbal for what the protocol does not need
// (the DUT's orientation on tf).
//
// Why GimbalMotion is declared here and not in drivers/gimbal_driver.h: the drivers library
// links the core, so the core cannot include the drivers' headers. GimbalMotion is the part of a
// gimbal the protocol uses; GimbalDriver (drivers/gimbal_driver.h) derives from it and adds only
// orientation(), so every driver (simulated, GRBL, SMC100) is one, with no adapter between them,
// and a core test fakes a gimbal without the drivers library. GimbalTarget and GimbalFault live
// here for the same reason; the drivers' header names them in its own namespace as before.
//
// Behaviour (the same as the node's before it moved here): start waits start_delay_s, then
// MOVING for the first position; SETTLED when the gimbal reports settled (stamped when it
// settled, if the gimbal knows); after dwell_s the next MOVING, after the last dwell DONE. A
// move that does not settle within settle_timeout_s aborts with the gimbal's status. A gimbal
// fault aborts (DONE closes the open dwell; state ABORTED with the device's words) and the
// gimbal is left alone until a start or resume recovers it; a failed recovery refuses the call.
// Before a phase that needs a manual remount the protocol publishes MOVING for the phase's first
// position (closing the last dwell), turns the stage there and waits in REMOUNT (no settle
// timeout) until continue_after_remount(); then the move is issued again and settles.
// Retries of a faulty position are the calibration run's (CalibrationRun, max_retries): it
// calls resume() for each; the protocol counts them (status().resumes).
//
// Time: every now_s and stamp is in seconds of the stand's clock. Thread safety: none.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {

// Where the protocol sends the gimbal: one position of the schedule.
struct GimbalTarget {
  Phase phase = Phase::X;
  std::uint32_t step = 0;
  std::uint32_t steps = 0;
  double angle_rad = 0.0;  // commanded alpha
  int approach = +1;       // +1 from below (increasing angle), -1 from above
};
// The target of one position of the schedule.
GimbalTarget target_of(const ScheduledPosition& position);

// A fault of a hardware gimbal; what() carries the device's own words. The protocol aborts the
// run with it.
class GimbalFault : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The gimbal as the protocol drives it (see the top of this file for why it is declared here).
class GimbalMotion {
 public:
  virtual ~GimbalMotion() = default;
  // Short description for logs and diagnostics ("simulated").
  virtual std::string name() const = 0;
  // Starts a move to `target` at time t_s (seconds on the node's clock).
  virtual void move_to(const GimbalTarget& target, double t_s) = 0;
  // True once the gimbal has reached the last target and settled.
  virtual bool settled(double t_s) const = 0;
  // When settled(t_s): the time it settled (<= t_s), the stamp of SETTLED. A driver that only
  // notices settling when asked returns t_s.
  virtual double settled_at(double t_s) const { return t_s; }
  // Stops where it is (abort).
  virtual void stop(double t_s) = 0;
  // Talks to the hardware (status polls); the protocol calls it every tick before settled().
  // May throw GimbalFault, as may move_to(); stop() never throws.
  virtual void update(double /*t_s*/) {}
  // True when the DUT is remounted by hand before `phase` (a one-axis stage): the protocol
  // pauses at the phase change until continue_after_remount().
  virtual bool manual_remount(Phase /*phase*/) const { return false; }
  // After a GimbalFault: brings the device back (reconnect, reset, homing as configured) so that
  // the protocol can continue; throws GimbalFault with the device's words when it cannot.
  virtual void recover(double /*t_s*/) {}
  // The device's latest status in its own words ("" when it has none), for messages.
  virtual std::string status_text() const { return ""; }

  // A gimbal turned by hand (the manual driver, docs/design.md section 15): true while the
  // operator must set the stage to the last target. The protocol then waits in WAIT_OPERATOR (no
  // settle timeout) until operator_continue(), and again whenever this turns true while MOVING
  // (the pose check found another pose).
  virtual bool needs_operator(double /*t_s*/) const { return false; }
  // The operator says the stage is set (gimbal_controller/continue).
  virtual void operator_continue(double /*t_s*/) {}
  // What the operator is asked ("phase x: set X to 60.0 deg"), and why again when the last
  // pose was wrong (operator_complaint); the stage positions of the target, deg per axis.
  virtual std::string operator_request() const { return ""; }
  virtual std::string operator_complaint() const { return ""; }
  virtual std::map<std::string, double> operator_targets_deg() const { return {}; }
};

enum class ProtocolState { Idle, Starting, Moving, Dwelling, Remount, Done, Aborted, WaitOperator };
// IDLE, STARTING, MOVING, SETTLED (Dwelling), REMOUNT, DONE, ABORTED, WAIT_OPERATOR: the progress
// topic's words.
const char* protocol_state_name(ProtocolState state);

struct GimbalProtocolOptions {
  ProtocolOptions protocol;        // the schedule: steps, move, settle, dwell, two_way, ...
  bool autostart = false;          // start at the first tick without a start call
  double start_delay_s = 1.0;      // from start (or autostart) to the first MOVING, s
  double settle_timeout_s = 60.0;  // abort when a move has not settled in this time, s
  double progress_hz = 1.0;        // periodic Progress (logged) at most this often, Hz
  // The continue call as the operator knows it, named in the remount messages.
  std::string continue_service = "gimbal_controller/continue";

  // Throws std::invalid_argument naming the field.
  void validate() const;
};

// What progress and diagnostics report.
struct ProtocolStatus {
  enum class Level { Ok, Warn, Error };
  ProtocolState state = ProtocolState::Idle;
  bool running = false;             // Moving, Dwelling or Remount: position is meaningful
  ScheduledPosition position;       // the position being visited (the last one when not running)
  std::size_t position_number = 0;  // 1-based; all of them once done; 0 when not running
  std::size_t positions = 0;
  double fraction = 0.0;  // of the run's nominal time
  double time_left_s = 0.0;
  double in_state_s = 0.0;
  bool slow_to_settle = false;  // moving for more than half of settle_timeout_s
  std::uint64_t resumes = 0;
  std::string last_error;
  // WAIT_OPERATOR: what the operator is asked, why again (the pose check), the target's stage
  // positions (deg per axis) and how many waits the run has had (a new one each time).
  std::string operator_request;
  std::string operator_complaint;
  std::map<std::string, double> stage_deg;
  std::uint64_t operator_waits = 0;
  Level level = Level::Ok;
  std::string text;  // "MOVING phase x step 3/24", "ABORTED: <reason>", the remount request
};

struct ProtocolAction {
  enum class Kind {
    Command,   // command: publish it (stamp_s, position, MOVING/SETTLED/DONE)
    Log,       // level, text
    Progress,  // publish `status` (as it was then); log it when `log` (the periodic one)
  };
  enum class Level { Info, Warn, Error };
  Kind kind = Kind::Log;
  GimbalEvent command;
  Level level = Level::Info;
  std::string text;
  bool repeating = false;  // Log that may come every tick (a fault while idle): throttle it
  bool log = false;        // Progress
  ProtocolStatus status;   // Progress
};
using ProtocolActions = std::vector<ProtocolAction>;

// The answer to a call of the shell's services.
struct ProtocolReply {
  bool success = false;
  std::string message;
  ProtocolActions actions;
};

class GimbalProtocol {
 public:
  // `gimbal` must outlive the protocol. Throws std::invalid_argument for invalid options.
  GimbalProtocol(const GimbalProtocolOptions& options, GimbalMotion* gimbal);

  // One step at time now_s (the shell's timer).
  ProtocolActions tick(double now_s);
  // Begins a run; refused while one is starting or running, or when a faulted gimbal does not
  // recover.
  ProtocolReply start(double now_s);
  // Stops a run; publishes DONE to close the open dwell (not while still starting).
  ProtocolReply abort(double now_s, const std::string& reason);
  // Ends a manual remount: the stage moves to the phase's first position again and settles. In
  // WAIT_OPERATOR: the operator has set the stage; the gimbal checks the pose and settles.
  ProtocolReply continue_after_remount(double now_s);
  // Moves to schedule position `index` now and continues from there, from any state; index ==
  // schedule().size() publishes DONE. The message ends with "stamp=<now_s>".
  ProtocolReply resume(double now_s, std::size_t index, const std::string& reason);
  // The next start (or autostart) begins at schedule position `index` (resume_* parameters);
  // later starts begin at 0 again.
  void start_next_run_at(std::size_t index);

  // Schedule index of (phase, step, approach); schedule().size() if none. `after`: the one after.
  std::size_t find_position(Phase phase, std::uint32_t step, int approach, bool after) const;
  const std::vector<ScheduledPosition>& schedule() const { return schedule_; }
  ProtocolState state() const { return state_; }
  ProtocolStatus status(double now_s) const;

 private:
  bool running() const;
  void begin_move(std::size_t index, double now_s, ProtocolActions* out);
  // Starts the move to the current position; a GimbalFault aborts the run (false).
  bool drive(double now_s, ProtocolActions* out);
  void driver_fault(double now_s, const std::string& what, ProtocolActions* out);
  // Recovers a faulted gimbal; false with the reason in last_error_.
  bool recover_gimbal(double now_s, ProtocolActions* out);
  void command(double stamp_s, GimbalState state, ProtocolActions* out) const;
  void progress(double now_s, bool log, ProtocolActions* out);
  double time_left_s(double now_s) const;

  GimbalProtocolOptions options_;
  GimbalMotion* gimbal_;
  std::vector<ScheduledPosition> schedule_;
  ProtocolState state_ = ProtocolState::Idle;
  std::size_t index_ = 0;
  double state_since_s_ = std::numeric_limits<double>::quiet_NaN();  // latest state change
  double start_at_s_ = 0.0;       // first MOVING of a run that is starting
  double last_progress_s_ = 0.0;  // last Progress
  std::string last_error_;
  bool autostart_pending_ = false;
  std::size_t start_index_ = 0;  // where the next start begins
  std::uint64_t resumes_ = 0;
  std::uint64_t operator_waits_ = 0;
  bool faulted_ = false;  // the gimbal raised a GimbalFault: recover() before moving again
};

}  // namespace core
}  // namespace accel_intrinsics
