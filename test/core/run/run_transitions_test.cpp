// The calibration run's transition table walked on a real run (core::CalibrationRun, no
// roscore): every state is reached by plain inputs, every input is applied in every state, and
// the run must end where the table says for the events it raised (a pair not in the table
// leaves the state as it was). Every row of the table must be taken at least once.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/run/calibration_run.h"

namespace accel_intrinsics {
namespace core {
namespace {

using S = RunState;
using E = RunEvent;

const std::vector<S> kStates = {S::Idle,    S::Running, S::Dwelling,  S::WaitingForResume,
                                S::Fitting, S::Done,    S::FitFailed, S::Aborted};

// A run driven by hand: commands, samples at 50 Hz, ticks, and the replies of a shell.
struct Driver {
  // retry: a fault is measured again up to max_retries times, or ends the run.
  explicit Driver(bool retry = true, std::uint32_t max_retries = 10)
      : run(options(retry, max_retries)) {}

  static RunOptions options(bool retry, std::uint32_t max_retries) {
    RunOptions o;
    o.steps = 2;
    o.assembler.reorder_window_s = 0.1;
    o.check_clock = false;
    o.retry_on_fault = retry;
    o.max_retries = max_retries;
    o.min_samples_per_dwell = 5;
    o.imu_timeout_s = 1.0;
    return o;
  }

  void take(const RunActions& actions) {
    for (const RunAction& a : actions) {
      if (a.kind == RunAction::Kind::FitNow) ticket = a.fit_ticket;
      if (a.kind == RunAction::Kind::ResumeAt) request = a.request;
    }
  }
  void command(GimbalState state, std::uint32_t step) {
    GimbalEvent e;
    e.stamp_s = t;
    e.phase = Phase::X;
    e.step = step;
    e.steps = 2;
    e.angle_rad = step * kPi;
    e.state = state;
    take(run.on_command(e));
  }
  void samples(int n) {
    for (int i = 0; i < n; ++i) {
      t += 0.02;
      ImuSample s;
      s.stamp_s = t;
      s.outputs = Eigen::Vector3d(0.0, 0.0, 9.8);
      take(run.on_sample(s));
    }
    t += 0.02;
  }
  void tick(double after_s = 0.5) {
    t += after_s;
    take(run.tick(t));
  }
  // The window passes (a fit is handed out if one is due), then the latest fit finishes.
  void fit_finished(bool published, const std::string& error) {
    tick();
    take(run.on_fit_finished(ticket, published, error));
  }
  void dwell(std::uint32_t step, int n) {
    command(GimbalState::Moving, step);
    t += 0.5;
    command(GimbalState::Settled, step);
    samples(n);
  }

  // Plain inputs that bring a fresh run into `state`.
  void reach(S state) {
    switch (state) {
      case S::Idle: break;
      case S::Running: command(GimbalState::Moving, 0); break;
      case S::Dwelling: dwell(0, 20); break;
      case S::WaitingForResume:  // a dwell with too few samples, measured again
        dwell(0, 2);
        command(GimbalState::Moving, 1);
        tick();
        break;
      case S::Fitting:
        dwell(0, 20);
        command(GimbalState::Done, 0);
        break;
      case S::Done:
      case S::FitFailed:
        reach(S::Fitting);
        tick();
        take(run.on_fit_finished(ticket, state == S::Done, state == S::Done ? "" : "too few"));
        break;
      case S::Aborted:  // the controller refuses the rewind
        reach(S::WaitingForResume);
        take(run.tick(t));
        take(run.on_resume_reply(request, true, false, "no such position", 0.0, t));
        break;
    }
  }

  // A fresh run restored from the checkpoint of another one: complete (it is fitted at the first
  // tick) or mid-run (one dwell recorded: resumed at the first command). Both wait in Idle.
  void restore(bool complete) {
    Driver first;
    if (complete) {
      first.reach(S::Done);
    } else {
      first.dwell(0, 20);
      first.command(GimbalState::Moving, 1);
      first.tick();
    }
    t = first.t;
    take(run.restore(first.run.table(), first.run.checkpoint_state()));
  }

  CalibrationRun run;
  double t = 10.0;
  std::uint64_t ticket = 0;
  ControllerRequest request;
};

// The inputs applied in every state.
const std::vector<std::pair<std::string, std::function<void(Driver&)>>>& inputs() {
  static const std::vector<std::pair<std::string, std::function<void(Driver&)>>> list = {
      {"reset", [](Driver& d) { d.take(d.run.reset("test")); }},
      {"MOVING",
       [](Driver& d) {
         d.t += 0.5;
         d.command(GimbalState::Moving, 1);
         d.tick(0.05);
       }},
      {"SETTLED",
       [](Driver& d) {
         d.t += 0.5;
         d.command(GimbalState::Settled, 1);
         d.tick(0.05);
       }},
      {"DONE",
       [](Driver& d) {
         d.t += 0.5;
         d.command(GimbalState::Done, 1);
         d.tick(0.05);
       }},
      {"DONE, window passed",
       [](Driver& d) {
         d.t += 0.5;
         d.command(GimbalState::Done, 1);
         d.tick();
       }},
      {"DONE, fit failed",
       [](Driver& d) {
         d.t += 0.5;
         d.command(GimbalState::Done, 1);
         d.tick();
         d.take(d.run.on_fit_finished(d.ticket, false, "bad"));
       }},
      {"IMU stall", [](Driver& d) { d.tick(2.0); }},
      {"new run",
       [](Driver& d) {
         d.t += 0.5;
         d.command(GimbalState::Moving, 0);
       }},
      {"dwell",
       [](Driver& d) {
         d.t += 0.5;
         d.dwell(1, 20);
         d.command(GimbalState::Moving, 2);
       }},
      {"short dwell",
       [](Driver& d) {
         d.t += 0.5;
         d.dwell(1, 2);
         d.command(GimbalState::Moving, 2);
         d.tick();
       }},
      {"tick", [](Driver& d) { d.tick(); }},
      {"streams idle", [](Driver& d) { d.take(d.run.on_streams_idle()); }},
      {"fit published", [](Driver& d) { d.fit_finished(true, ""); }},
      {"fit failed", [](Driver& d) { d.fit_finished(false, "bad"); }},
      {"fit withheld", [](Driver& d) { d.fit_finished(false, ""); }},
      {"controller ABORTED",
       [](Driver& d) {
         d.take(d.run.on_controller_state("ABORTED", "ABORTED: alarm"));
         d.tick();
       }},
      {"controller restarted",
       [](Driver& d) {
         d.take(d.run.on_controller_state("MOVING", ""));
         d.take(d.run.on_controller_state("IDLE", ""));
         d.tick();
       }},
      {"resume confirmed",
       [](Driver& d) {
         d.take(d.run.tick(d.t));
         d.take(d.run.on_resume_reply(d.request, true, true, "resumed", d.t + 0.01, d.t));
       }},
      {"resume refused",
       [](Driver& d) {
         d.take(d.run.tick(d.t));
         d.take(d.run.on_resume_reply(d.request, true, false, "refused", 0.0, d.t));
       }},
      {"resume unreached",
       [](Driver& d) { d.take(d.run.on_resume_reply(d.request, false, false, "", 0.0, d.t)); }},
  };
  return list;
}

// The states the table allows after `events` from `from` (a collecting target: any of the
// collecting states, as the run's inputs say); `actual` must be one of them. Rows taken from a
// known state go to `taken`.
void expect_table_fold(S from, const std::vector<E>& events, S actual, const std::string& what,
                       std::set<std::pair<S, E>>* taken) {
  std::set<S> possible = {from};
  for (E e : events) {
    std::set<S> next;
    for (S s : possible) {
      const RunTransition* t = run_transition(s, e);
      if (t == nullptr) {
        next.insert(s);
        continue;
      }
      if (possible.size() == 1) taken->insert({s, e});
      if (t->collecting) {
        next.insert({S::Idle, S::Running, S::Dwelling, S::Fitting});
      } else {
        next.insert(t->to);
      }
    }
    possible = next;
  }
  std::string allowed;
  for (S s : possible) allowed += std::string(" ") + run_state_name(s);
  EXPECT_TRUE(possible.count(actual))
      << what << ": got " << run_state_name(actual) << ", the table allows" << allowed;
}

TEST(RunTransitions, TableHasOneRowPerPairAndResetLeavesEveryState) {
  std::set<std::pair<S, E>> pairs;
  for (const RunTransition& t : run_transition_table()) {
    EXPECT_TRUE(pairs.insert({t.from, t.event}).second)
        << run_state_name(t.from) << " x " << run_event_name(t.event) << " twice";
  }
  for (S s : kStates) {
    const RunTransition* t = run_transition(s, E::Reset);
    ASSERT_NE(t, nullptr) << run_state_name(s);
    EXPECT_EQ(t->to, S::Idle);
  }
  // Aborted is left by a reset only; a result only by a reset, an abort or a failed refit.
  for (const RunTransition& t : run_transition_table()) {
    if (t.from == S::Aborted) {
      EXPECT_EQ(t.event, E::Reset) << run_event_name(t.event);
    }
    if (t.from == S::Done && t.to != S::Done) {
      EXPECT_TRUE(t.event == E::Reset || t.event == E::FaultAborted || t.event == E::FitFailed)
          << run_event_name(t.event);
    }
  }
}

// Where the walk starts: every state, and Idle with a restored run's follow-up pending.
struct Start {
  std::string name;
  S state;
  std::function<void(Driver&)> reach;
};
std::vector<Start> starts() {
  std::vector<Start> list;
  for (S s : kStates) list.push_back({run_state_name(s), s, [s](Driver& d) { d.reach(s); }});
  list.push_back({"idle (restored done)", S::Idle, [](Driver& d) { d.restore(true); }});
  list.push_back({"idle (restored mid-run)", S::Idle, [](Driver& d) { d.restore(false); }});
  return list;
}

TEST(RunTransitions, EveryInputInEveryStateGoesWhereTheTableSays) {
  std::set<std::pair<S, E>> taken;
  // Faults retried, ending the run, and ending it at once (the rewind of a controller fault).
  const std::vector<std::pair<bool, std::uint32_t>> retries = {{true, 10}, {false, 0}, {true, 0}};
  for (const auto& retry : retries) {
    for (const Start& start : starts()) {
      const S state = start.state;
      {
        Driver d(retry.first, retry.second);
        start.reach(d);
        if (!retry.first || retry.second == 0) {
          if (d.run.state() != state) continue;  // its recipe needs a retry
        }
        ASSERT_EQ(d.run.state(), state) << "recipe of " << start.name;
      }
      for (const auto& input : inputs()) {
        Driver d(retry.first, retry.second);
        start.reach(d);
        const std::vector<E> before = d.run.events();
        input.second(d);
        const std::vector<E>& all = d.run.events();
        // A reset clears the log and starts it again with Reset (the recipes never reset).
        const bool continued =
            all.size() >= before.size() && std::equal(before.begin(), before.end(), all.begin());
        const std::vector<E> raised(all.begin() + (continued ? before.size() : 0), all.end());
        expect_table_fold(state, raised, d.run.own_state(), start.name + " + " + input.first,
                          &taken);
      }
    }
  }
  // Rows the walk above cannot raise (its recipes and inputs are plain), and where they are taken.
  const std::set<std::pair<S, E>> elsewhere = {
      {S::Idle, E::RestoredAborted},     // RestoreIsRefusedUnlessFreshAndAnAbortedRunStaysAborted
      {S::Fitting, E::DoneDiscarded},    // ControllerAbortShowsOverTheRunAndDoneIsNotFitted
      {S::Idle, E::RestoredDone},        // RestoredRunWaitsInIdleForItsFollowUp
      {S::Idle, E::RestoredMidRun},      // RestoredRunWaitsInIdleForItsFollowUp
      {S::Fitting, E::ClockMismatch},    // ImuOnAnotherClockFailsWithTheOffsetInsteadOfFitting
      {S::Idle, E::ClockMismatch},       // a restored complete run on two clocks, as Fitting's
      {S::FitFailed, E::ClockMismatch},  // a refit after a failed fit on two clocks, as Fitting's
      {S::Idle, E::FaultRetried},        // not reached: no dwell without a command; the target is
      {S::Idle, E::FaultAborted},        //   that of the other collecting states
      // A fault released by the window after DONE, or after a failed or published fit:
      {S::Fitting, E::FaultRetried},
      {S::Fitting, E::FaultAborted},
      {S::Done, E::FaultAborted},
      {S::FitFailed, E::FaultRetried},
      {S::FitFailed, E::FaultAborted},
      {S::FitFailed, E::ControllerFault},
      {S::FitFailed, E::ResumeRequested},
      {S::Fitting, E::ControllerFault},  // the controller aborting while DONE waits its window
      {S::Fitting, E::ResumeRequested},
  };
  for (const RunTransition& t : run_transition_table()) {
    if (elsewhere.count({t.from, t.event})) continue;
    EXPECT_TRUE(taken.count({t.from, t.event}))
        << "row " << run_state_name(t.from) << " x " << run_event_name(t.event) << " never taken";
  }
}

TEST(RunTransitions, RestoreIsRefusedUnlessFreshAndAnAbortedRunStaysAborted) {
  CheckpointState aborted;
  aborted.fault = "IMU stream stopped";
  for (S state : kStates) {
    Driver d;
    d.reach(state);
    if (state == S::Idle) {
      d.run.restore(PositionTable(), aborted);
      EXPECT_EQ(d.run.state(), S::Aborted);
      EXPECT_THROW(d.run.restore(PositionTable(), aborted), std::logic_error);
    } else {
      EXPECT_THROW(d.run.restore(PositionTable(), aborted), std::logic_error)
          << run_state_name(state);
      EXPECT_EQ(d.run.state(), state);
    }
  }
}

TEST(RunTransitions, ControllerAbortShowsOverTheRunAndDoneIsNotFitted) {
  Driver d(/*retry=*/false);
  d.dwell(0, 20);
  d.take(d.run.on_controller_state("ABORTED", "ABORTED: limit switch"));
  EXPECT_EQ(d.run.state(), S::Aborted);
  EXPECT_EQ(d.run.own_state(), S::Dwelling);
  d.command(GimbalState::Done, 0);
  EXPECT_EQ(d.run.own_state(), S::Fitting);
  d.tick();  // the window after DONE passes: no fit of an aborted run
  EXPECT_EQ(d.run.events().back(), E::DoneDiscarded);
  EXPECT_EQ(d.run.own_state(), S::Running);
  EXPECT_EQ(d.ticket, 0u);
  // The controller runs again: the run is where its own state says.
  d.take(d.run.on_controller_state("STARTING", ""));
  EXPECT_EQ(d.run.state(), S::Running);
}

// restore() of a complete or a mid-run checkpoint leaves the run Idle with its follow-up: the
// first tick fits a complete one; the first command of the controller resumes a mid-run one
// (and a tick does not fit it); a reset drops either.
TEST(RunTransitions, RestoredRunWaitsInIdleForItsFollowUp) {
  std::set<std::pair<S, E>> taken;
  {
    Driver d;
    d.restore(true);
    EXPECT_EQ(d.run.events().back(), E::RestoredDone);
    EXPECT_EQ(d.run.state(), S::Idle);
    EXPECT_EQ(d.ticket, 0u);
    d.tick();
    EXPECT_EQ(d.run.events().back(), E::FitStarted);
    EXPECT_EQ(d.run.state(), S::Fitting);
    EXPECT_NE(d.ticket, 0u);
    const std::uint64_t ticket = d.ticket;
    d.tick();  // fitted once
    EXPECT_EQ(d.ticket, ticket);
    d.take(d.run.on_fit_finished(d.ticket, true, ""));
    EXPECT_EQ(d.run.state(), S::Done);
  }
  {
    Driver d;
    d.restore(false);
    EXPECT_EQ(d.run.events().back(), E::RestoredMidRun);
    EXPECT_EQ(d.run.state(), S::Idle);
    d.tick();
    EXPECT_EQ(d.run.state(), S::Idle);
    EXPECT_EQ(d.ticket, 0u);
    d.command(GimbalState::Moving, 1);
    EXPECT_EQ(d.run.state(), S::WaitingForResume);
    d.take(d.run.tick(d.t));
    EXPECT_TRUE(d.request.after);  // after the one recorded dwell
    EXPECT_EQ(d.request.step, 0u);
  }
  for (bool complete : {true, false}) {
    Driver d;
    d.restore(complete);
    d.take(d.run.reset("test"));
    d.tick();
    EXPECT_EQ(d.ticket, 0u) << complete;
    d.command(GimbalState::Moving, 1);
    EXPECT_EQ(d.run.state(), S::Running) << complete;
  }
}

// The DONE's window and the shell's fit are the run's data, not sub-states of Fitting: they
// overlap (a DONE while the fit runs) and outlive it (the fit is published while the window
// runs; the window then refits under the result).
TEST(RunTransitions, DoneWindowAndRunningFitOutliveFitting) {
  Driver d;
  d.reach(S::Fitting);
  EXPECT_TRUE(d.run.waiting_after_done());
  d.tick();  // FitNow handed out
  const std::uint64_t first = d.ticket;
  ASSERT_NE(first, 0u);
  EXPECT_FALSE(d.run.waiting_after_done());
  d.t += 0.5;
  d.command(GimbalState::Done, 1);  // DONE again while the fit runs
  EXPECT_TRUE(d.run.waiting_after_done());
  EXPECT_EQ(d.run.own_state(), S::Fitting);
  EXPECT_TRUE(d.run.fit_may_publish(first));
  d.take(d.run.on_fit_finished(first, true, ""));
  EXPECT_EQ(d.run.own_state(), S::Done);
  EXPECT_TRUE(d.run.waiting_after_done());  // the result is out, the window still runs
  d.tick();
  EXPECT_FALSE(d.run.waiting_after_done());
  EXPECT_NE(d.ticket, first);  // fitted again; the result stays meanwhile
  EXPECT_EQ(d.run.own_state(), S::Done);
  EXPECT_TRUE(d.run.fit_may_publish(d.ticket));
  EXPECT_FALSE(d.run.fit_may_publish(first));
  d.take(d.run.on_fit_finished(d.ticket, false, "too few"));
  EXPECT_EQ(d.run.own_state(), S::FitFailed);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
