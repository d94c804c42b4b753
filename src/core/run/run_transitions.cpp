// The run's states, events and transition table (run_transitions.h).
#include "accel_intrinsics/core/run/run_transitions.h"

#include <vector>

namespace accel_intrinsics {
namespace core {

const char* run_state_name(RunState state) {
  switch (state) {
    case RunState::Idle: return "idle";
    case RunState::Running: return "running";
    case RunState::Dwelling: return "dwelling";
    case RunState::WaitingForResume: return "waiting for resume";
    case RunState::Fitting: return "fitting";
    case RunState::Done: return "done";
    case RunState::FitFailed: return "fit failed";
    case RunState::Aborted: return "aborted";
  }
  return "?";
}

const char* run_event_name(RunEvent event) {
  switch (event) {
    case RunEvent::Reset: return "reset";
    case RunEvent::RestoredAborted: return "restored aborted";
    case RunEvent::RestoredDone: return "restored done";
    case RunEvent::RestoredMidRun: return "restored mid-run";
    case RunEvent::Moving: return "moving";
    case RunEvent::Settled: return "settled";
    case RunEvent::DoneReceived: return "done received";
    case RunEvent::DoneDiscarded: return "done discarded";
    case RunEvent::FitStarted: return "fit started";
    case RunEvent::ClockMismatch: return "clock mismatch";
    case RunEvent::FitPublished: return "fit published";
    case RunEvent::FitFailed: return "fit failed";
    case RunEvent::FitWithheld: return "fit withheld";
    case RunEvent::FaultRetried: return "fault retried";
    case RunEvent::FaultAborted: return "fault aborted";
    case RunEvent::ControllerFault: return "controller fault";
    case RunEvent::ResumeRequested: return "resume requested";
    case RunEvent::ResumeConfirmed: return "resume confirmed";
    case RunEvent::ResumeRefused: return "resume refused";
  }
  return "?";
}

const std::vector<RunTransition>& run_transition_table() {
  using S = RunState;
  using E = RunEvent;
  static const std::vector<RunTransition> table = [] {
    std::vector<RunTransition> t;
    const auto rows = [&t](std::initializer_list<S> from, E event, S to, bool collecting = false) {
      for (S f : from) t.push_back({f, event, to, collecting});
    };
    const std::initializer_list<S> all = {S::Idle,    S::Running, S::Dwelling,  S::WaitingForResume,
                                          S::Fitting, S::Done,    S::FitFailed, S::Aborted};
    const std::initializer_list<S> collecting = {S::Idle, S::Running, S::Dwelling};
    rows(all, E::Reset, S::Idle);
    rows({S::Idle}, E::RestoredAborted, S::Aborted);
    // Restored to be fitted or resumed: Idle until then (FitStarted, ResumeRequested).
    rows({S::Idle}, E::RestoredDone, S::Idle);
    rows({S::Idle}, E::RestoredMidRun, S::Idle);
    // Commands move a collecting run; in the other states they only feed the assembler.
    rows(collecting, E::Moving, S::Running);
    rows(collecting, E::Settled, S::Dwelling);
    rows(collecting, E::DoneReceived, S::Fitting);
    // Aborted by the controller meanwhile: no fit, the run is where its commands say.
    rows({S::Fitting}, E::DoneDiscarded, S::Running, true);
    // Idle: a restored complete run; FitFailed: fitted again after a later DONE.
    rows({S::Idle, S::Fitting, S::FitFailed}, E::FitStarted, S::Fitting);
    rows({S::Idle, S::Fitting, S::FitFailed}, E::ClockMismatch, S::FitFailed);
    rows({S::Fitting}, E::FitPublished, S::Done);
    // Done: a second fit of the run (after a retried position) failed.
    rows({S::Fitting, S::Done}, E::FitFailed, S::FitFailed);
    rows({S::Fitting}, E::FitWithheld, S::Running, true);
    // A result stays through a retry (the rewound positions are fitted again); an abort ends it.
    rows({S::Idle, S::Running, S::Dwelling, S::Fitting, S::FitFailed}, E::FaultRetried,
         S::WaitingForResume);
    rows({S::Idle, S::Running, S::Dwelling, S::WaitingForResume, S::Fitting, S::Done, S::FitFailed},
         E::FaultAborted, S::Aborted);
    rows({S::Running, S::Dwelling, S::Fitting, S::FitFailed}, E::ControllerFault,
         S::WaitingForResume);
    rows({S::Idle, S::Running, S::Dwelling, S::Fitting, S::FitFailed}, E::ResumeRequested,
         S::WaitingForResume);
    rows({S::WaitingForResume}, E::ResumeConfirmed, S::Running, true);
    rows({S::Idle, S::Running, S::Dwelling, S::WaitingForResume, S::Fitting, S::FitFailed},
         E::ResumeRefused, S::Aborted);
    return t;
  }();
  return table;
}

const RunTransition* run_transition(RunState from, RunEvent event) {
  for (const RunTransition& t : run_transition_table()) {
    if (t.from == from && t.event == event) return &t;
  }
  return nullptr;
}

}  // namespace core

}  // namespace accel_intrinsics
