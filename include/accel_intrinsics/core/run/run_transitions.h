// The calibration run's states, the events that move it and its transition table
// (docs/design.md section 4; CalibrationRun in calibration_run.h changes its state only here).
#pragma once

#include <vector>

namespace accel_intrinsics {
namespace core {

enum class RunState {
  Idle,              // no gimbal command yet (or since a reset); a run restored from a checkpoint
                     // waits here to be fitted (complete) or resumed (mid-run) by its follow-up
  Running,           // the protocol runs; the gimbal moves between dwells
  Dwelling,          // inside a dwell (latest command: SETTLED)
  WaitingForResume,  // a position is to be measured again, or a restart resumed: the controller
                     // has not yet confirmed the rewind
  Fitting,           // DONE received: waiting for the reorder window, or the fit is running
  Done,              // fitted: the result is out
  FitFailed,         // the fit after DONE failed (too few dwells, ...)
  Aborted,           // a watchdog or the gimbal controller aborted the run
};
const char* run_state_name(RunState state);

// What moves the run from one state to another. The run raises exactly these, each in one
// place, and changes its state only through run_transition().
enum class RunEvent {
  Reset,            // reset(): discarded (also when a new run starts)
  RestoredAborted,  // restore() of a checkpoint whose run was aborted
  RestoredDone,     // restore() of a complete run: fitted at the first tick (FitStarted)
  RestoredMidRun,   // restore() mid-protocol: resumed at the first command or a DONE controller
  Moving,           // a gimbal MOVING (or a DONE the run ignores: inside a blackout)
  Settled,          // a gimbal SETTLED: a dwell begins
  DoneReceived,     // a gimbal DONE the run takes: fit once the reorder window has passed
  DoneDiscarded,    // the window after DONE passed, but the run is aborted: no fit
  FitStarted,       // FitNow handed out
  ClockMismatch,    // no fit: IMU and gimbal stamp on two clocks (the fit error says the offset)
  FitPublished,     // on_fit_finished: published
  FitFailed,        // on_fit_finished: the fit failed
  FitWithheld,      // on_fit_finished: not published, no error (shutdown)
  FaultRetried,     // a fault (watchdog or the controller's): the position is measured again
  FaultAborted,     // a fault that ends the run (no retry, or max_retries reached)
  ControllerFault,  // the controller aborted by itself: retried at tick() after the window
  ResumeRequested,  // the controller is to rewind (this node or the controller restarted)
  ResumeConfirmed,  // the controller rewound and no other rewind is pending
  ResumeRefused,    // the controller refused to rewind: the run is aborted
};
const char* run_event_name(RunEvent event);

// One row of the transition table. `collecting`: the target is where the run's inputs put it:
// Fitting while a DONE waits for its window or a fit runs, else Idle (no command of this run
// yet), Dwelling (latest command SETTLED) or Running.
struct RunTransition {
  RunState from;
  RunEvent event;
  RunState to;
  bool collecting;
};
// The whole table. A (state, event) pair that is not in it is ignored: the state stays (for
// example a late DONE while the run waits for a rewind, or any command after it was aborted).
const std::vector<RunTransition>& run_transition_table();
// The row for (from, event), or nullptr when the pair is ignored.
const RunTransition* run_transition(RunState from, RunEvent event);

}  // namespace core
}  // namespace accel_intrinsics
