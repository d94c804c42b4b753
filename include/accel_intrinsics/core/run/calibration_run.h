// One calibration run as a state machine, ROS-free (docs/design.md section 4).
//
// The calibration node (and any other shell: a test, a replay tool) feeds it plain inputs and
// carries out the actions it returns; the run never calls back into its shell:
//
//   inputs                              actions (returned by every input)
//   on_command(event)          ---->    DwellAccepted   checkpoint the row, log it
//   on_sample(sample)                   Log             a line for the shell's log
//   on_controller_state(state)          CheckpointState rewrite the small state file
//   tick(now_s)                         ClearCheckpoint a new run starts: old files go
//   on_resume_reply(...)                FitNow          fit the table (core::calibrate)
//   on_fit_finished(...)                ResumeAt        ask the gimbal controller to continue at
//   restore(...) / reset(reason)                        a position (only from tick())
//                                       Abort           ask the gimbal controller to abort
//                                                       (only from tick())
//
// What it owns: the dwell assembler (samples -> dwells, docs/design.md section 2), fed through the
// commanded dwell source, the position table of accepted rows, the statistics of the run's first
// dwell accumulated as it comes (its long rest, for the noise model: docs/design.md section 12),
// the watchdogs (no samples during a dwell, too few samples, a dwell with none), retries of a
// faulty position (rewind the controller; rows measured before its new MOVING are discarded:
// "blackouts"), resume after a restart (from a checkpoint, or of the gimbal controller), and the
// decision when to fit.
//
// Time: every stamp and `now_s` is in seconds of the stand's clock (ROS time; simulated time
// under /clock). Thread safety: none; the shell serializes calls.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "accel_intrinsics/core/analysis/clock_check.h"
#include "accel_intrinsics/core/analysis/raw_stream_analysis.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/dwell_source.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/noise/rest_accumulator.h"
#include "accel_intrinsics/core/run/run_actions.h"
#include "accel_intrinsics/core/run/run_memory.h"
#include "accel_intrinsics/core/run/run_transitions.h"

namespace accel_intrinsics {
namespace core {

struct RunOptions {
  AssemblerOptions assembler;               // settle_discard_s, reorder_window_s
  std::uint32_t steps = 0;                  // expected N before the first command (0: unknown)
  int min_positions_per_phase = 3;          // for the "what is missing" message
  double imu_timeout_s = 0.0;               // no samples this long during a dwell: fault (0: off)
  std::uint32_t min_samples_per_dwell = 0;  // fewer samples in a dwell: fault (0: off)
  bool retry_on_fault = false;              // on a fault: measure again (true) or abort
  std::uint32_t max_retries = 2;            // retries of one position before aborting
  bool record_moves = false;                // keep the samples around the moves (timing lag)
  double request_retry_s = 0.5;             // ask an unreachable controller again after this
  // A run restored from a checkpoint whose controller reports IDLE (the stand PC restarted: all
  // its nodes are fresh) is continued from the checkpoint after the grace period, as after DONE.
  // Off by default: the gimbal then moves without anybody's start (a lab's unattended stand).
  bool resume_idle_controller = false;
  // Added to every IMU stamp (a device clock offset from the gimbal's; docs/design.md section 5).
  double imu_time_offset_s = 0.0;
  // Before fitting, check that IMU and gimbal stamp on one clock (core/clock_check.h); a run on
  // two clocks fails with the offset found instead of fitting garbage.
  bool check_clock = true;
  ClockCheckOptions clock;
};

// The small checkpoint beside the position table: enough to resume after a restart.
struct CheckpointState {
  double time_origin_s = std::numeric_limits<double>::quiet_NaN();  // t0 of the drift term
  std::uint32_t steps = 0;
  std::size_t rows = 0;
  bool done = false;
  std::string fault;
};

// A snapshot for status topics, diagnostics and services.
struct RunStatus {
  RunState state = RunState::Idle;
  std::array<int, 3> dwells_per_phase{{0, 0, 0}};
  std::uint32_t steps = 0;     // N of the run (or the expected N)
  AssemblerCounters counters;  // over every assembler of this run (restarts included)
  std::uint64_t commands_received = 0;
  std::uint64_t commands_rejected = 0;  // malformed commands
  std::string fault;                    // why the run was aborted (ours or the controller's)
  std::string last_fault;               // the latest fault, retried or not
  std::string fit_error;                // why the fit failed
  std::uint64_t retries = 0;            // positions measured again
  std::uint64_t dwells_discarded = 0;   // measured before a rewind
  bool restored = false;                // rows were reloaded from a checkpoint
  bool in_dwell = false;                // the assembler is accumulating a dwell:
  Phase dwell_phase = Phase::X;         //   which one,
  std::uint32_t dwell_step = 0;
  std::uint64_t dwell_samples = 0;  //   and its samples so far
  bool imu_silent = false;          // no samples for imu_timeout_s during a dwell
  double newest_sample_stamp_s = -std::numeric_limits<double>::infinity();
};

class CalibrationRun {
 public:
  explicit CalibrationRun(const RunOptions& options);

  // A well-formed gimbal command (the shell rejects malformed ones: note_rejected_command()).
  RunActions on_command(const GimbalEvent& event);
  void note_rejected_command() { ++commands_rejected_; }
  // An IMU sample (any stamp order within the reorder window).
  RunActions on_sample(const ImuSample& sample);
  // A reading of a per-dwell channel (core::kChannels: the DUT temperature on imu/temperature,
  // docs/design.md section 10; optional; on the IMU's clock like the samples): each dwell records
  // the aggregate of its readings.
  RunActions on_channel_sample(const ChannelSample& reading);
  // The gimbal controller's state on its progress topic ("IDLE", "MOVING", "SETTLED", "DONE",
  // "ABORTED", "REMOUNT", ...); `message` carries "ABORTED: <reason>". A controller that aborts
  // by itself (a gimbal fault: the device's alarm, error, silence, a lost port) is a fault of
  // the position it was at: with retry_on_fault that position is measured again once the
  // reorder window has passed (the dwells before it are kept), otherwise the run is aborted.
  RunActions on_controller_state(const std::string& state, const std::string& message);
  // Time passes: releases buffered messages older than now - reorder window, runs the watchdogs,
  // decides to fit after DONE, and hands out a due controller request (ResumeAt or Abort).
  RunActions tick(double now_s);
  // No further messages or clock ticks are coming (a bag replay that ended at DONE, a stopped
  // clock): after DONE, the reorder window is taken as passed and the run is fitted now.
  RunActions on_streams_idle();
  // DONE came and the run waits for the reorder window to pass in stamp time.
  bool waiting_after_done() const { return done_stamp_s_.has_value(); }
  // The reply to a ResumeAt: `reached` false when the controller could not be called (asked
  // again after request_retry_s); else `success`, its message, and the stamp of its MOVING.
  RunActions on_resume_reply(const ControllerRequest& request, bool reached, bool success,
                             const std::string& message, double moving_stamp_s, double now_s);
  // The reply to an Abort: when it could not be delivered it is asked again after
  // request_retry_s.
  RunActions on_abort_reply(const ControllerRequest& request, bool reached,
                            const std::string& message, double now_s);
  // After FitNow the shell fits (core::calibrate) and asks whether the result may go out: not
  // when a fault or a rewind came meanwhile, or a reset discarded the run. The final fit of a
  // run that a new run replaced before it was fitted does go out (it changes nothing here).
  bool fit_may_publish(std::uint64_t fit_ticket) const;
  // Then it reports: published, or the fit failed with `error` (empty: withheld).
  RunActions on_fit_finished(std::uint64_t fit_ticket, bool published, const std::string& error);
  // Restarted from a checkpoint: its rows, state. A run that was complete is fitted at the
  // first tick; an aborted one stays aborted; otherwise the controller is asked to continue
  // after the last row (at its first command, or once it reports DONE). Only a fresh run (no
  // input yet) is restored: otherwise throws std::logic_error.
  RunActions restore(const PositionTable& table, const CheckpointState& state);
  // Discards everything of the current run.
  RunActions reset(const std::string& reason);

  // The run's state; a controller that aborted by itself (controller_abort_) shows as Aborted
  // over every state but Done, until it runs again (STARTING, MOVING, SETTLED, REMOUNT).
  RunState state() const;
  // The run's own state (without the controller's abort shown over it).
  RunState own_state() const { return state_; }
  // Every event of this run since the last reset (the reset included), in order: for logs and
  // the transition-table test.
  const std::vector<RunEvent>& events() const { return events_; }
  bool has_result() const { return state_ == RunState::Done; }
  // `now_s` judges the IMU watchdog (imu_silent).
  RunStatus status(double now_s) const;
  // What get_intrinsics says while there is no result: the phases that lack dwells, and why.
  std::string missing_message() const;
  // The accepted rows (restored ones included) with the run's time origin.
  const PositionTable& table() const { return table_; }
  CheckpointState checkpoint_state() const;
  // Gimbal events and the samples around the moves (record_moves), for the timing lag.
  const MoveSampleRecorder& recorded_moves() const { return moves_; }
  // The noise model of the run's long rest (docs/design.md section 12), by the rule offline_fit
  // applies to a recorded run (core::noise_model_of_run: the first dwell of at least 10 times the
  // median dwell), from the first dwell's samples accumulated as they came (rest_accumulator.h).
  // None (white) when the run has no long rest, or its samples are not here (a run restored from a
  // checkpoint), or they are too few for a model (`why` then says so).
  std::optional<NoiseModel> noise_model(std::string* why = nullptr) const;
  const LongRestRecorder& long_rest() const { return long_rest_; }
  RunMemory memory() const;
  // The direction of approach the next row at (phase, step) would have.
  int approach_of_next_row(Phase phase, std::uint32_t step) const;

 private:
  struct Blackout {  // rows overlapping [begin, end) were measured before a rewind
    double begin_s = -std::numeric_limits<double>::infinity();
    double end_s = std::numeric_limits<double>::infinity();  // stamp of the rewound MOVING
  };
  struct Announced {  // a dwell announced by SETTLED, to catch one with no sample at all
    Phase phase;
    std::uint32_t step;
    double begin_s, end_s;
    bool recorded;  // data: a row of it was accepted (no fault for a dwell with no sample)
  };
  enum class Pending { None, Resume, Abort };
  // What a run restored from a checkpoint does next (restore() sets one; the run is Idle then):
  // one of three exclusive outcomes of restore() (an aborted one is RunState::Aborted).
  enum class Restored {
    None,    // not restored, or already carried on
    Fit,     // the checkpoint says DONE: fit at the first tick
    Resume,  // restored mid-protocol: rewind at the first command, or once the controller is DONE
  };

  void connect_assembler();
  // The rows an assembler call completed (returned by it, so a fault may restart it).
  void accept_rows(const CompletedRows& rows);
  void accept_row(const DwellRecord& row);
  void raise_fault(const std::string& what, Phase phase, std::uint32_t step, int approach,
                   double dwell_start_s);
  void begin_resume(const std::string& cause);
  void restart_assembler();
  void check_watchdogs(double now_s);
  void emit_fit();
  void ask_again(Pending kind, const ControllerRequest& request, double now_s);
  void emit(RunAction::Kind kind);
  void warn_on_new_drops();
  bool in_blackout(double t_start_s, double t_end_s) const;
  bool rewind_pending() const;  // a rewind asked for or not yet confirmed
  bool aborted() const { return !fault_.empty() || !controller_abort_.empty(); }
  AssemblerCounters counters() const;
  std::uint32_t steps() const { return steps_seen_ ? steps_seen_ : options_.steps; }
  // The one place the state changes: run_transition(state_, event).
  void apply(RunEvent event);
  void log(RunAction::Level level, const std::string& text);
  void log_repeating(const std::string& text);
  RunActions take_actions();

  RunOptions options_;
  DwellAssembler assembler_;
  // Gimbal commands bound the dwells (core/dwell_source.h); the run keeps the assembler for its
  // own bookkeeping (flushes, restarts, counters).
  CommandedDwellSource source_{&assembler_};
  MoveSampleRecorder moves_;
  LongRestRecorder long_rest_;
  ClockCheck clock_check_;
  RunActions actions_;
  PositionTable table_;

  std::uint32_t steps_seen_ = 0;
  std::uint64_t commands_received_ = 0;
  std::uint64_t commands_rejected_ = 0;
  // A DONE's stamp while its reorder window runs. Not a sub-state of Fitting: a DONE opens it in
  // any state (a refit under a result, one while a rewind is pending) and a fit may still run.
  std::optional<double> done_stamp_s_;
  // FitNow handed out, on_fit_finished not yet called. Not a sub-state of Fitting: the run moves on
  // (a retry, an abort, a later DONE) while its shell fits; the ticket decides what comes back.
  bool fitting_ = false;
  std::uint64_t fit_ticket_ = 0;             // of the latest FitNow
  std::uint64_t superseded_fit_ticket_ = 0;  // final fit of a run a new run replaced
  bool unreached_warned_ = false;            // log throttle: "controller not available" said once
  std::uint64_t commands_in_run_ = 0;
  std::uint64_t run_generation_ = 0;  // bumped by reset()
  RunState state_ = RunState::Idle;
  std::vector<RunEvent> events_;
  std::string fit_error_;
  bool restored_ = false;  // status data: the rows came from a checkpoint (kept all run long)
  Restored restored_next_ = Restored::None;
  double resume_deadline_s_ = std::numeric_limits<double>::quiet_NaN();  // of Restored::Resume
  std::string controller_state_;
  // A follow-up for tick(), not a phase: it waits behind a rewind already pending, in any state.
  bool controller_restarted_ = false;
  std::string fault_;             // the run was aborted by a watchdog: why
  std::string controller_abort_;  // the gimbal controller said ABORTED: why
  std::string last_fault_;
  std::map<std::tuple<int, std::uint32_t, int>, std::uint32_t> retries_;
  std::uint64_t retries_total_ = 0;
  std::uint64_t rows_discarded_ = 0;
  std::vector<Blackout> blackouts_;
  Pending pending_ = Pending::None;
  ControllerRequest request_;
  double request_after_s_ = -std::numeric_limits<double>::infinity();
  AssemblerCounters counters_before_;  // of assemblers restarted after a fault
  AssemblerCounters warned_;           // counters at the last warning
  // Arrival order: the latest command, when it is a SETTLED (the IMU watchdog's dwell). Kept in
  // every state (commands feed a fitting or rewinding run too); Dwelling is taken from it.
  std::optional<GimbalEvent> live_dwell_;
  double newest_sample_stamp_s_ = -std::numeric_limits<double>::infinity();
  std::vector<Announced> announced_;
  // The latest gimbal command in arrival order (the position a controller fault belongs to).
  std::optional<GimbalEvent> last_event_;
  // A controller fault to be retried at tick() once the reorder window has passed.
  struct ControllerFault {
    std::string reason;
    Phase phase = Phase::X;
    std::uint32_t step = 0;
    bool in_dwell = false;  // the fault came during the dwell (it is measured again)
    double stamp_s = 0.0;   // of the position's latest command
  };
  std::optional<ControllerFault> controller_fault_;
  void retry_controller_fault();
};

}  // namespace core
}  // namespace accel_intrinsics
