// core::GimbalProtocol without a roscore: the gimbal controller's state machine driven by a fake
// gimbal (core::GimbalMotion, the protocol's part of every GimbalDriver) and a fake clock: the
// normal sweep of the three phases, faults of the gimbal and the calibration run's retries
// through resume (recovered, and exhausted), manual remount, resume from where it stopped, abort.
#include "accel_intrinsics/core/run/gimbal_protocol.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace accel_intrinsics {
namespace core {
namespace {

constexpr double kTick = 0.01;  // s: the shell's timer period on the fake clock

// A gimbal that settles move_s after each move_to(), and fails when told to.
class FakeGimbal : public GimbalMotion {
 public:
  struct Move {
    GimbalTarget target;
    double t_s;
    double settles_s;
  };

  std::string name() const override { return "fake"; }
  void move_to(const GimbalTarget& target, double t_s) override {
    moves.push_back({target, t_s, t_s + move_s});
    if (fail_move && fail_move(target)) throw GimbalFault(move_fault);
  }
  bool settled(double t_s) const override {
    if (moves.empty() || never_settle) return false;
    return t_s >= moves.back().settles_s;
  }
  double settled_at(double t_s) const override {
    return moves.empty() ? t_s : moves.back().settles_s;
  }
  void stop(double t_s) override { stops.push_back(t_s); }
  void update(double t_s) override {
    ++updates;
    if (fail_update && fail_update(t_s)) throw GimbalFault(update_fault);
  }
  bool manual_remount(Phase phase) const override { return remount.count(phase) > 0; }
  void recover(double t_s) override {
    recovers.push_back(t_s);
    if (!recover_fault.empty()) throw GimbalFault(recover_fault);
  }
  std::string status_text() const override { return status; }

  double move_s = 0.3;
  bool never_settle = false;
  std::set<Phase> remount;
  std::function<bool(const GimbalTarget&)> fail_move;
  std::string move_fault = "fake: error:22 (feed rate has not yet been set)";
  std::function<bool(double)> fail_update;
  std::string update_fault = "fake: ALARM:1 (hard limit triggered)";
  std::string recover_fault;  // non-empty: recover() fails with these words
  std::string status = "Run|MPos:12.000";

  std::vector<Move> moves;
  std::vector<double> stops;
  std::vector<double> recovers;
  int updates = 0;
};

GimbalProtocolOptions test_options() {
  GimbalProtocolOptions o;
  o.protocol.steps_per_phase = 3;
  o.protocol.move_s = 0.3;
  o.protocol.settle_s = 0.2;
  o.protocol.dwell_s = 1.0;
  o.protocol.phase_change_s = 1.0;
  o.start_delay_s = 0.5;
  o.settle_timeout_s = 5.0;
  o.continue_service = "/stand/gimbal_controller/continue";
  return o;
}

bool same_position(const GimbalEvent& c, const ScheduledPosition& p) {
  return c.phase == p.phase && c.step == p.step && c.steps == p.steps && c.angle_rad == p.angle_rad;
}

bool same_target(const GimbalTarget& t, const ScheduledPosition& p) {
  return t.phase == p.phase && t.step == p.step && t.steps == p.steps &&
         t.angle_rad == p.angle_rad && t.approach == p.approach;
}

// The shell: a fake clock that ticks the protocol every kTick and keeps what it was asked to do.
class Shell {
 public:
  explicit Shell(const GimbalProtocolOptions& options = test_options())
      : protocol(options, &gimbal) {}

  void keep(const ProtocolActions& actions) {
    for (const ProtocolAction& a : actions) {
      if (a.kind == ProtocolAction::Kind::Command) commands.push_back(a.command);
      if (a.kind == ProtocolAction::Kind::Log) logs.push_back(a);
      if (a.kind == ProtocolAction::Kind::Progress) progress.push_back(a.status);
    }
  }
  ProtocolReply keep(const ProtocolReply& r) {
    keep(r.actions);
    return r;
  }
  // Ticks until `done` (checked after each tick) or `limit_s` of clock time; true when done.
  bool run_until(const std::function<bool()>& done, double limit_s = 300.0) {
    const double end_s = now_s + limit_s;
    while (now_s < end_s) {
      now_s += kTick;
      keep(protocol.tick(now_s));
      if (done()) return true;
    }
    return false;
  }
  bool run_until_state(ProtocolState state, double limit_s = 300.0) {
    return run_until([&] { return protocol.state() == state; }, limit_s);
  }
  bool logged(ProtocolAction::Level level, const std::string& words) const {
    for (const ProtocolAction& a : logs) {
      if (a.level == level && a.text.find(words) != std::string::npos) return true;
    }
    return false;
  }

  FakeGimbal gimbal;  // declared first: the protocol holds a pointer to it
  GimbalProtocol protocol;
  double now_s = 100.0;
  std::vector<GimbalEvent> commands;
  std::vector<ProtocolAction> logs;
  std::vector<ProtocolStatus> progress;
};

// Commands from `from` on are MOVING, SETTLED for schedule positions first..last, then DONE.
void expect_sweep(const std::vector<GimbalEvent>& commands, std::size_t from,
                  const std::vector<ScheduledPosition>& schedule, std::size_t first) {
  ASSERT_EQ(commands.size(), from + 2 * (schedule.size() - first) + 1);
  for (std::size_t i = first; i < schedule.size(); ++i) {
    const GimbalEvent& moving = commands[from + 2 * (i - first)];
    const GimbalEvent& settled = commands[from + 2 * (i - first) + 1];
    EXPECT_EQ(moving.state, GimbalState::Moving) << "position " << i;
    EXPECT_EQ(settled.state, GimbalState::Settled) << "position " << i;
    EXPECT_TRUE(same_position(moving, schedule[i])) << "position " << i;
    EXPECT_TRUE(same_position(settled, schedule[i])) << "position " << i;
  }
  EXPECT_EQ(commands.back().state, GimbalState::Done);
}

TEST(GimbalProtocol, NormalSweepVisitsTheThreePhasesInOrder) {
  for (int variant = 0; variant < 4; ++variant) {
    GimbalProtocolOptions o = test_options();
    o.protocol.two_way = variant == 1;
    o.protocol.closing_position = variant == 2;
    // Variant 3: a long rest at the first position (the noise model's, initial_rest_s).
    const double first_dwell_s = 10.0 * o.protocol.dwell_s + 0.3;
    if (variant == 3) o.protocol.initial_rest_s = first_dwell_s;
    Shell shell(o);
    const std::vector<ScheduledPosition>& schedule = shell.protocol.schedule();
    const double started_s = shell.now_s;
    const ProtocolReply r = shell.keep(shell.protocol.start(started_s));
    ASSERT_TRUE(r.success) << r.message;
    EXPECT_NE(r.message.find("started: " + std::to_string(schedule.size()) + " positions"),
              std::string::npos)
        << r.message;
    EXPECT_EQ(shell.protocol.state(), ProtocolState::Starting);
    ASSERT_TRUE(shell.run_until_state(ProtocolState::Done));

    SCOPED_TRACE("variant " + std::to_string(variant));
    expect_sweep(shell.commands, 0, schedule, 0);
    // Phases x, y, z in turn, each fully before the next.
    for (std::size_t i = 1; i < schedule.size(); ++i) {
      EXPECT_LE(index(schedule[i - 1].phase), index(schedule[i].phase));
    }
    EXPECT_EQ(schedule.back().phase, Phase::Z);
    // The gimbal went to every position in schedule order, once, and was never stopped.
    ASSERT_EQ(shell.gimbal.moves.size(), schedule.size());
    for (std::size_t i = 0; i < schedule.size(); ++i) {
      EXPECT_TRUE(same_target(shell.gimbal.moves[i].target, schedule[i])) << i;
      // MOVING is stamped when the move was issued; SETTLED when the gimbal says it settled.
      EXPECT_EQ(shell.commands[2 * i].stamp_s, shell.gimbal.moves[i].t_s) << i;
      EXPECT_EQ(shell.commands[2 * i + 1].stamp_s, shell.gimbal.moves[i].settles_s) << i;
      // The dwell lasts dwell_s (to within one tick of the shell's timer), the first one the
      // long rest when there is one.
      const double dwell_s = shell.commands[2 * i + 2].stamp_s - shell.commands[2 * i + 1].stamp_s;
      const double expected_s = variant == 3 && i == 0 ? first_dwell_s : o.protocol.dwell_s;
      EXPECT_GE(dwell_s, expected_s - 1e-9) << i;
      EXPECT_LT(dwell_s, expected_s + kTick + 1e-9) << i;
    }
    EXPECT_GE(shell.commands.front().stamp_s, started_s + o.start_delay_s - 1e-9);
    EXPECT_LT(shell.commands.front().stamp_s, started_s + o.start_delay_s + kTick + 1e-9);
    EXPECT_TRUE(shell.gimbal.stops.empty());
    EXPECT_TRUE(shell.gimbal.recovers.empty());

    const ProtocolStatus done = shell.protocol.status(shell.now_s);
    EXPECT_EQ(done.position_number, schedule.size());
    EXPECT_EQ(done.fraction, 1.0);
    EXPECT_EQ(done.level, ProtocolStatus::Level::Ok);
    EXPECT_EQ(done.text, "DONE");
    // Nothing moves after DONE.
    const std::size_t n = shell.commands.size();
    shell.run_until([] { return false; }, 20.0);
    EXPECT_EQ(shell.commands.size(), n);
    EXPECT_EQ(shell.gimbal.moves.size(), schedule.size());
  }
}

TEST(GimbalProtocol, ProgressTellsWhereTheRunIs) {
  Shell shell;
  shell.keep(shell.protocol.start(shell.now_s));
  ASSERT_TRUE(shell.run_until([&] { return shell.commands.size() == 4; }));  // SETTLED x step 1
  const ProtocolStatus s = shell.protocol.status(shell.now_s);
  EXPECT_EQ(s.state, ProtocolState::Dwelling);
  EXPECT_TRUE(s.running);
  EXPECT_EQ(s.position.phase, Phase::X);
  EXPECT_EQ(s.position.step, 1u);
  EXPECT_EQ(s.position_number, 2u);
  EXPECT_EQ(s.text, "SETTLED phase x step 2/3");
  EXPECT_GT(s.fraction, 0.0);
  EXPECT_LT(s.fraction, 1.0);
  // Every state change is reported at once, and the periodic report is flagged for the log.
  ASSERT_FALSE(shell.progress.empty());
  EXPECT_EQ(shell.progress.back().state, ProtocolState::Dwelling);
  shell.run_until([] { return false; }, 0.5);
  bool periodic = false;
  for (const ProtocolAction& a : shell.protocol.tick(shell.now_s + 2.0)) {
    periodic = periodic || (a.kind == ProtocolAction::Kind::Progress && a.log);
  }
  EXPECT_TRUE(periodic);
}

TEST(GimbalProtocol, AutostartBeginsAtTheFirstTick) {
  GimbalProtocolOptions o = test_options();
  o.autostart = true;
  Shell shell(o);
  EXPECT_EQ(shell.protocol.state(), ProtocolState::Idle);
  shell.run_until([] { return true; });
  EXPECT_EQ(shell.protocol.state(), ProtocolState::Starting);
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Done));
  expect_sweep(shell.commands, 0, shell.protocol.schedule(), 0);
}

TEST(GimbalProtocol, GimbalFaultAbortsWithTheDevicesWordsAndResumeRetriesThePosition) {
  Shell shell;
  const std::vector<ScheduledPosition>& schedule = shell.protocol.schedule();
  // A fault while idle is logged (throttled by the shell) and changes nothing.
  shell.gimbal.fail_update = [](double) { return true; };
  shell.run_until([] { return false; }, 0.1);
  EXPECT_EQ(shell.protocol.state(), ProtocolState::Idle);
  ASSERT_FALSE(shell.logs.empty());
  EXPECT_TRUE(shell.logs.back().repeating);
  EXPECT_TRUE(shell.commands.empty());
  EXPECT_TRUE(shell.gimbal.stops.empty());

  // The alarm comes once, during the move to position 4 (phase y step 1).
  const std::size_t faulty = shell.protocol.find_position(Phase::Y, 1, +1, false);
  ASSERT_EQ(faulty, 4u);
  bool alarmed = false;
  shell.gimbal.fail_update = [&](double) {
    if (alarmed || shell.gimbal.moves.size() != faulty + 1) return false;
    alarmed = true;
    return true;
  };
  shell.keep(shell.protocol.start(shell.now_s));
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Aborted));
  const double fault_s = shell.now_s;

  // MOVING to the faulty position, then DONE there at the fault: the open dwell is closed.
  ASSERT_GE(shell.commands.size(), 2u);
  const GimbalEvent& done = shell.commands.back();
  const GimbalEvent& moving = shell.commands[shell.commands.size() - 2];
  EXPECT_EQ(moving.state, GimbalState::Moving);
  EXPECT_TRUE(same_position(moving, schedule[faulty]));
  EXPECT_EQ(done.state, GimbalState::Done);
  EXPECT_TRUE(same_position(done, schedule[faulty]));
  EXPECT_EQ(done.stamp_s, fault_s);
  EXPECT_EQ(shell.gimbal.stops.size(), 1u);
  const ProtocolStatus aborted = shell.protocol.status(shell.now_s);
  EXPECT_EQ(aborted.level, ProtocolStatus::Level::Error);
  EXPECT_EQ(aborted.text, "ABORTED: gimbal fault: fake: ALARM:1 (hard limit triggered)");
  EXPECT_TRUE(shell.logged(ProtocolAction::Level::Error, "fake: ALARM:1 (hard limit triggered)"));
  ASSERT_FALSE(shell.progress.empty());
  EXPECT_EQ(shell.progress.back().state, ProtocolState::Aborted);

  // A faulted gimbal is left alone: no polls, no moves, no commands.
  const int updates = shell.gimbal.updates;
  const std::size_t commands = shell.commands.size(), moves = shell.gimbal.moves.size();
  shell.run_until([] { return false; }, 30.0);
  EXPECT_EQ(shell.gimbal.updates, updates);
  EXPECT_EQ(shell.commands.size(), commands);
  EXPECT_EQ(shell.gimbal.moves.size(), moves);
  EXPECT_TRUE(shell.gimbal.recovers.empty());

  // The calibration run retries the position: the gimbal is recovered first, MOVING goes out
  // now, and the protocol runs on to DONE from there.
  const ProtocolReply r =
      shell.keep(shell.protocol.resume(shell.now_s, faulty, "retry after the gimbal fault"));
  ASSERT_TRUE(r.success) << r.message;
  ASSERT_EQ(shell.gimbal.recovers.size(), 1u);
  EXPECT_EQ(shell.gimbal.recovers[0], shell.now_s);
  std::ostringstream stamp;
  stamp.precision(17);
  stamp << shell.now_s;
  EXPECT_NE(
      r.message.find("moving to phase y step 1, position 5 of 9, MOVING stamp=" + stamp.str()),
      std::string::npos)
      << r.message;
  EXPECT_TRUE(shell.logged(ProtocolAction::Level::Warn, "the fake gimbal recovered"));
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Done));
  expect_sweep(shell.commands, commands, schedule, faulty);
  const ProtocolStatus after = shell.protocol.status(shell.now_s);
  EXPECT_EQ(after.resumes, 1u);
  EXPECT_EQ(after.last_error, "");
}

TEST(GimbalProtocol, FaultOfAMoveAbortsAtItsMovingStampAndStartRecovers) {
  Shell shell;
  bool failed = false;
  shell.gimbal.fail_move = [&](const GimbalTarget& t) {
    if (failed || t.phase != Phase::X || t.step != 2) return false;
    failed = true;
    return true;
  };
  shell.keep(shell.protocol.start(shell.now_s));
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Aborted));
  ASSERT_EQ(shell.commands.size(), 6u);  // x0, x1 measured; MOVING x2, then DONE at once
  EXPECT_EQ(shell.commands[4].state, GimbalState::Moving);
  EXPECT_EQ(shell.commands[5].state, GimbalState::Done);
  EXPECT_EQ(shell.commands[5].stamp_s, shell.commands[4].stamp_s);
  EXPECT_EQ(shell.protocol.status(shell.now_s).last_error,
            "gimbal fault: fake: error:22 (feed rate has not yet been set)");
  // A new start recovers the gimbal and runs the whole protocol again from its first position.
  const std::size_t before = shell.commands.size();
  ASSERT_TRUE(shell.keep(shell.protocol.start(shell.now_s)).success);
  EXPECT_EQ(shell.gimbal.recovers.size(), 1u);
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Done));
  expect_sweep(shell.commands, before, shell.protocol.schedule(), 0);
}

TEST(GimbalProtocol, RetriesExhaustedLeaveTheRunAborted) {
  Shell shell;
  const std::vector<ScheduledPosition>& schedule = shell.protocol.schedule();
  const std::size_t faulty = shell.protocol.find_position(Phase::Z, 0, +1, false);
  // The hardware is broken at this position: every move there fails.
  shell.gimbal.fail_move = [&](const GimbalTarget& t) { return same_target(t, schedule[faulty]); };
  shell.keep(shell.protocol.start(shell.now_s));
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Aborted));

  // The calibration run's retries (CalibrationRun max_retries = 2): each resume recovers the
  // gimbal, which fails again at the same position and aborts the run again.
  const std::uint32_t max_retries = 2;
  for (std::uint32_t retry = 1; retry <= max_retries; ++retry) {
    shell.run_until([] { return false; }, 1.0);
    const std::size_t before = shell.commands.size();
    const ProtocolReply r =
        shell.keep(shell.protocol.resume(shell.now_s, faulty, "retry " + std::to_string(retry)));
    EXPECT_EQ(shell.protocol.state(), ProtocolState::Aborted) << "retry " << retry;
    ASSERT_EQ(shell.commands.size(), before + 2) << "retry " << retry;
    EXPECT_EQ(shell.commands[before].state, GimbalState::Moving);
    EXPECT_EQ(shell.commands[before + 1].state, GimbalState::Done);
    EXPECT_TRUE(same_position(shell.commands[before + 1], schedule[faulty]));
    // The abort is reported with the device's words as it happens.
    bool reported = false;
    for (const ProtocolAction& a : r.actions) {
      reported = reported || (a.kind == ProtocolAction::Kind::Progress &&
                              a.status.text == "ABORTED: gimbal fault: " + shell.gimbal.move_fault);
    }
    EXPECT_TRUE(reported) << "retry " << retry;
  }
  EXPECT_EQ(shell.gimbal.recovers.size(), max_retries);
  EXPECT_EQ(shell.protocol.status(shell.now_s).resumes, max_retries);
  // Retries exhausted: the shell asks no more, and the protocol stays aborted and still.
  std::size_t moves_there = 0;
  for (const FakeGimbal::Move& m : shell.gimbal.moves) {
    moves_there += same_target(m.target, schedule[faulty]) ? 1 : 0;
  }
  EXPECT_EQ(moves_there, 1u + max_retries);
  for (const GimbalEvent& c : shell.commands) {
    EXPECT_FALSE(c.state == GimbalState::Settled && same_position(c, schedule[faulty]));
  }
  const std::size_t commands = shell.commands.size();
  shell.run_until([] { return false; }, 60.0);
  EXPECT_EQ(shell.commands.size(), commands);
  EXPECT_EQ(shell.protocol.state(), ProtocolState::Aborted);

  // A device that cannot be brought back refuses a resume and a start, with its words, and
  // publishes nothing.
  shell.gimbal.recover_fault = "fake: no reply from /dev/ttyUSB0 within 2 s";
  const ProtocolReply resume = shell.keep(shell.protocol.resume(shell.now_s, faulty, "retry 3"));
  EXPECT_FALSE(resume.success);
  EXPECT_EQ(resume.message,
            "resume refused: could not recover the gimbal after its fault: fake: no reply from "
            "/dev/ttyUSB0 within 2 s");
  const ProtocolReply start = shell.keep(shell.protocol.start(shell.now_s));
  EXPECT_FALSE(start.success);
  EXPECT_EQ(start.message.rfind("start refused: could not recover the gimbal", 0), 0u)
      << start.message;
  EXPECT_EQ(shell.commands.size(), commands);
  EXPECT_EQ(shell.protocol.state(), ProtocolState::Aborted);
  EXPECT_EQ(shell.progress.back().level, ProtocolStatus::Level::Error);
}

TEST(GimbalProtocol, SettleTimeoutAbortsWithTheGimbalsStatus) {
  Shell shell;
  shell.keep(shell.protocol.start(shell.now_s));
  ASSERT_TRUE(shell.run_until([&] { return shell.commands.size() == 2; }));  // SETTLED x0
  shell.gimbal.never_settle = true;
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Aborted));
  const GimbalEvent& moving = shell.commands[2];
  EXPECT_EQ(moving.state, GimbalState::Moving);
  EXPECT_GT(shell.now_s - moving.stamp_s, 5.0);
  EXPECT_LT(shell.now_s - moving.stamp_s, 5.0 + 2 * kTick);
  EXPECT_EQ(shell.commands.back().state, GimbalState::Done);
  EXPECT_EQ(shell.protocol.status(shell.now_s).last_error,
            "the gimbal did not settle at phase x step 1 within settle_timeout_s = 5 s (fake "
            "reports Run|MPos:12.000)");
  EXPECT_EQ(shell.gimbal.stops.size(), 1u);
}

TEST(GimbalProtocol, ManualRemountWaitsForTheOperator) {
  Shell shell;
  const std::vector<ScheduledPosition>& schedule = shell.protocol.schedule();
  shell.gimbal.remount = {Phase::Y, Phase::Z};
  const ProtocolReply early = shell.protocol.continue_after_remount(shell.now_s);
  EXPECT_FALSE(early.success);
  EXPECT_EQ(early.message, "not waiting for a remount (IDLE)");

  shell.keep(shell.protocol.start(shell.now_s));
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Remount));
  const std::size_t y0 = shell.protocol.find_position(Phase::Y, 0, +1, false);
  // Phase x measured, then MOVING for y step 0 closed its last dwell; the stage turned there.
  ASSERT_EQ(shell.commands.size(), 2 * y0 + 1);
  EXPECT_EQ(shell.commands.back().state, GimbalState::Moving);
  EXPECT_TRUE(same_position(shell.commands.back(), schedule[y0]));
  ASSERT_EQ(shell.gimbal.moves.size(), y0 + 1);
  EXPECT_TRUE(shell.logged(ProtocolAction::Level::Warn,
                           "remount the DUT for phase y (it turns about its own y axis), then "
                           "call /stand/gimbal_controller/continue"));
  const ProtocolStatus waiting = shell.protocol.status(shell.now_s);
  EXPECT_EQ(waiting.level, ProtocolStatus::Level::Warn);
  EXPECT_EQ(waiting.text,
            "REMOUNT phase y step 1/3: remount the DUT to turn about its own y axis, then call "
            "/stand/gimbal_controller/continue");

  // The operator takes longer than the settle timeout: the protocol waits, settled or not.
  shell.run_until([] { return false; }, 3 * test_options().settle_timeout_s);
  EXPECT_EQ(shell.protocol.state(), ProtocolState::Remount);
  EXPECT_EQ(shell.commands.size(), 2 * y0 + 1);

  // continue: the move is issued again now, and SETTLED comes after it (not from the first one).
  const double continued_s = shell.now_s;
  const ProtocolReply r = shell.keep(shell.protocol.continue_after_remount(continued_s));
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_EQ(r.message, "continuing with phase y");
  ASSERT_EQ(shell.gimbal.moves.size(), y0 + 2);
  EXPECT_EQ(shell.gimbal.moves.back().t_s, continued_s);
  EXPECT_TRUE(same_target(shell.gimbal.moves.back().target, schedule[y0]));
  EXPECT_EQ(shell.commands.size(), 2 * y0 + 1);  // no second MOVING
  ASSERT_TRUE(shell.run_until([&] { return shell.commands.size() == 2 * y0 + 2; }));
  EXPECT_EQ(shell.commands.back().state, GimbalState::Settled);
  EXPECT_EQ(shell.commands.back().stamp_s, continued_s + shell.gimbal.move_s);

  // Phase z needs the operator too; then the run ends normally.
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Remount));
  EXPECT_EQ(shell.protocol.status(shell.now_s).position.phase, Phase::Z);
  ASSERT_TRUE(shell.keep(shell.protocol.continue_after_remount(shell.now_s)).success);
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Done));
  expect_sweep(shell.commands, 0, schedule, 0);
}

TEST(GimbalProtocol, ResumeContinuesFromWhereItStopped) {
  Shell shell;
  const std::vector<ScheduledPosition>& schedule = shell.protocol.schedule();
  // The first run begins where an earlier one stopped (the resume_* parameters); the next run
  // begins at the start again.
  const std::size_t y1 = shell.protocol.find_position(Phase::Y, 1, +1, false);
  shell.protocol.start_next_run_at(y1);
  shell.keep(shell.protocol.start(shell.now_s));
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Done));
  expect_sweep(shell.commands, 0, schedule, y1);
  std::size_t from = shell.commands.size();
  shell.keep(shell.protocol.start(shell.now_s));
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Done));
  expect_sweep(shell.commands, from, schedule, 0);

  // Mid-run, the calibration run rewinds to the position after x step 1: MOVING for x step 2
  // goes out now and the protocol continues from there.
  shell.keep(shell.protocol.start(shell.now_s));
  const std::size_t z0 = shell.protocol.find_position(Phase::Z, 0, +1, false);
  ASSERT_TRUE(shell.run_until([&] {
    return shell.protocol.state() == ProtocolState::Dwelling &&
           shell.protocol.status(shell.now_s).position_number == z0 + 1;
  }));
  const std::size_t x2 = shell.protocol.find_position(Phase::X, 1, +1, true);
  ASSERT_EQ(x2, 2u);
  from = shell.commands.size();
  const ProtocolReply r = shell.keep(shell.protocol.resume(shell.now_s, x2, "row rejected"));
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_EQ(shell.commands[from].stamp_s, shell.now_s);
  ASSERT_TRUE(shell.run_until_state(ProtocolState::Done));
  expect_sweep(shell.commands, from, schedule, x2);
  EXPECT_EQ(shell.protocol.status(shell.now_s).resumes, 1u);

  // Resuming after the last position: nothing left, DONE now.
  shell.keep(shell.protocol.start(shell.now_s));
  ASSERT_TRUE(shell.run_until([&] { return shell.protocol.state() == ProtocolState::Dwelling; }));
  const std::size_t stops = shell.gimbal.stops.size();
  const std::size_t last = schedule.size() - 1;
  const ProtocolReply end = shell.keep(shell.protocol.resume(
      shell.now_s,
      shell.protocol.find_position(schedule[last].phase, schedule[last].step, +1, true),
      "checkpoint complete"));
  ASSERT_TRUE(end.success);
  EXPECT_NE(end.message.find("nothing left, DONE stamp="), std::string::npos) << end.message;
  EXPECT_EQ(shell.protocol.state(), ProtocolState::Done);
  EXPECT_EQ(shell.commands.back().state, GimbalState::Done);
  EXPECT_TRUE(same_position(shell.commands.back(), schedule[last]));
  EXPECT_EQ(shell.commands.back().stamp_s, shell.now_s);
  EXPECT_EQ(shell.gimbal.stops.size(), stops + 1);  // it was moving: stopped where it is
}

TEST(GimbalProtocol, AbortStopsTheGimbalAndClosesTheDwell) {
  Shell shell;
  const ProtocolReply idle = shell.protocol.abort(shell.now_s, "operator");
  EXPECT_FALSE(idle.success);
  EXPECT_EQ(idle.message, "not running (IDLE)");
  EXPECT_TRUE(shell.gimbal.stops.empty());

  // While starting nothing has been published: the abort publishes nothing either.
  shell.keep(shell.protocol.start(shell.now_s));
  const ProtocolReply starting = shell.keep(shell.protocol.abort(shell.now_s, "operator"));
  ASSERT_TRUE(starting.success);
  EXPECT_EQ(starting.message, "aborted: operator");
  EXPECT_TRUE(shell.commands.empty());
  EXPECT_EQ(shell.gimbal.stops.size(), 1u);
  EXPECT_EQ(shell.protocol.status(shell.now_s).text, "ABORTED: operator");

  // Aborted in a dwell: DONE at once for the position, the gimbal stops, nothing moves after.
  ASSERT_TRUE(shell.keep(shell.protocol.start(shell.now_s)).success);
  ASSERT_TRUE(shell.run_until([&] { return shell.commands.size() == 4; }));  // SETTLED x1
  const ProtocolReply busy = shell.protocol.start(shell.now_s);
  EXPECT_FALSE(busy.success);
  EXPECT_EQ(busy.message, "already running (SETTLED phase x step 1)");
  shell.run_until([] { return false; }, 0.2);
  const ProtocolReply r = shell.keep(shell.protocol.abort(shell.now_s, "operator left"));
  ASSERT_TRUE(r.success);
  ASSERT_EQ(shell.commands.size(), 5u);
  EXPECT_EQ(shell.commands.back().state, GimbalState::Done);
  EXPECT_TRUE(same_position(shell.commands.back(), shell.protocol.schedule()[1]));
  EXPECT_EQ(shell.commands.back().stamp_s, shell.now_s);
  EXPECT_EQ(shell.gimbal.stops.size(), 2u);
  EXPECT_EQ(shell.gimbal.stops.back(), shell.now_s);
  const ProtocolStatus s = shell.protocol.status(shell.now_s);
  EXPECT_EQ(s.state, ProtocolState::Aborted);
  EXPECT_EQ(s.level, ProtocolStatus::Level::Error);
  EXPECT_EQ(s.text, "ABORTED: operator left");
  EXPECT_EQ(s.position_number, 0u);
  const std::size_t moves = shell.gimbal.moves.size();
  shell.run_until([] { return false; }, 30.0);
  EXPECT_EQ(shell.commands.size(), 5u);
  EXPECT_EQ(shell.gimbal.moves.size(), moves);
  // A second abort has nothing to stop.
  EXPECT_FALSE(shell.protocol.abort(shell.now_s, "again").success);
}

TEST(GimbalProtocol, RefusesInvalidOptions) {
  FakeGimbal gimbal;
  GimbalProtocolOptions o = test_options();
  o.settle_timeout_s = 0.0;
  EXPECT_THROW((GimbalProtocol(o, &gimbal)), std::invalid_argument);
  o = test_options();
  o.start_delay_s = -1.0;
  EXPECT_THROW((GimbalProtocol(o, &gimbal)), std::invalid_argument);
  EXPECT_THROW((GimbalProtocol(test_options(), nullptr)), std::invalid_argument);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
