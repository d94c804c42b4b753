// core::CalibrationRun without a roscore: normal runs, watchdogs, retries, resume after a
// restart (of the node or of the gimbal controller), reset during a fit.
//
// A FakeStand plays a simulated recording into the run in stamp order, ticks it every 50 ms of
// stand time, and answers its actions as the gimbal controller would: ResumeAt replays the
// recording from the requested position onward, shifted to "now" (the rewound protocol); Abort
// stops the stream; FitNow is answered with a successful fit. Faults are injected into the first
// pass only, so a retried position is clean.
#include "accel_intrinsics/core/run/calibration_run.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <optional>
#include <set>

#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

struct StreamEvent {
  double stamp_s;
  bool is_command;
  GimbalEvent command;
  ImuSample sample;
};

class FakeStand {
 public:
  // `tweak` changes the simulation (a long rest, a slow bias) before it runs.
  explicit FakeStand(std::uint32_t steps = 4, bool two_way = false,
                     const std::function<void(SimulationOptions*)>& tweak = {}) {
    SimulationOptions sim;
    sim.protocol.steps_per_phase = steps;
    sim.protocol.two_way = two_way;
    sim.protocol.move_s = 0.5;
    sim.protocol.settle_s = 0.2;
    sim.protocol.dwell_s = 1.0;
    sim.protocol.phase_change_s = 1.0;
    sim.rate_hz = 50.0;
    sim.truth.S = Eigen::Matrix3d::Identity();
    sim.seed = 7;
    if (tweak) tweak(&sim);
    recording_ = simulate_recording(sim);
    for (const GimbalEvent& c : recording_.commands) all_.push_back({c.stamp_s, true, c, {}});
    for (const ImuSample& s : recording_.samples) all_.push_back({s.stamp_s, false, {}, s});
    std::stable_sort(all_.begin(), all_.end(), [](const StreamEvent& a, const StreamEvent& b) {
      return a.stamp_s < b.stamp_s || (a.stamp_s == b.stamp_s && a.is_command && !b.is_command);
    });
    stream_ = all_;
    now_s_ = all_.front().stamp_s;
  }

  // Drops samples of the first pass for which `drop` is true (stamps of the original timeline).
  void inject_first_pass(const std::function<bool(const ImuSample&)>& drop) {
    std::vector<StreamEvent> kept;
    for (const StreamEvent& e : stream_) {
      if (!e.is_command && drop(e.sample)) continue;
      kept.push_back(e);
    }
    stream_ = kept;
  }

  // The IMU stamps its samples on a clock `offset_s` ahead of the gimbal's (they still arrive
  // when they are taken).
  void shift_imu_clock(double offset_s) {
    for (StreamEvent& e : stream_) {
      if (!e.is_command) e.sample.stamp_s += offset_s;
    }
  }

  // The first pass keeps only `n` samples of the dwell in `interval`.
  void keep_first_samples_of(std::pair<double, double> interval, int n) {
    int kept = 0;
    inject_first_pass([&](const ImuSample& s) {
      return s.stamp_s >= interval.first && s.stamp_s < interval.second && ++kept > n;
    });
  }

  // The stamp interval of the dwell (phase, step) in the original timeline (first visit).
  std::pair<double, double> dwell_interval(Phase phase, std::uint32_t step) const {
    for (std::size_t i = 0; i < recording_.commands.size(); ++i) {
      const GimbalEvent& c = recording_.commands[i];
      if (c.state == GimbalState::Settled && c.phase == phase && c.step == step) {
        return {c.stamp_s, recording_.commands[i + 1].stamp_s};
      }
    }
    ADD_FAILURE() << "no such dwell";
    return {0, 0};
  }

  // Plays the stream into `run` until stand time `until_s` (or the end plus a few seconds).
  void play(CalibrationRun* run, double until_s = 1e300) {
    // The end moves when a rewind replaces the rest of the stream.
    const auto stop = [&] {
      const double end_s = stream_.empty() ? now_s_ : stream_.back().stamp_s;
      return std::min(until_s, std::max(end_s + 3.0, idle_until_s_));
    };
    idle_until_s_ = now_s_ + 3.0;
    while (now_s_ < stop()) {
      now_s_ += 0.01;
      while (cursor_ < stream_.size() && stream_[cursor_].stamp_s <= now_s_) {
        const StreamEvent& e = stream_[cursor_++];
        if (e.is_command) {
          if (controller_alive_) carry_out(run, run->on_command(e.command));
        } else {
          carry_out(run, run->on_sample(e.sample));
        }
      }
      if (++ticks_ % 5 == 0) carry_out(run, run->tick(now_s_));
      if (cursor_ < stream_.size()) idle_until_s_ = now_s_ + 3.0;
    }
  }

  // The controller process dies: no commands until it is back (its samples still flow).
  void kill_controller(CalibrationRun* run) {
    carry_out(run, run->on_controller_state("MOVING", "MOVING"));
    controller_alive_ = false;
    controller_dead_since_s_ = now_s_;
  }
  void restart_controller(CalibrationRun* run) {
    controller_alive_ = true;
    // Its stream would continue; a fresh controller stands still until told to resume.
    stream_.resize(cursor_);
    carry_out(run, run->on_controller_state("IDLE", "IDLE"));
  }

  // The gimbal faults now at (phase, step) (a serial gimbal's alarm, error or lost port): the
  // controller stops, publishes DONE for that position, and says ABORTED with the device's words.
  void controller_fault(CalibrationRun* run, Phase phase, std::uint32_t step,
                        const std::string& words) {
    stream_.resize(cursor_);
    GimbalEvent done;
    done.stamp_s = now_s_;
    done.phase = phase;
    done.step = step;
    done.steps = 4;
    done.angle_rad = 2.0 * 3.14159265358979 * step / 4.0;
    done.state = GimbalState::Done;
    carry_out(run, run->on_command(done));
    carry_out(run, run->on_controller_state("ABORTED", "ABORTED: gimbal fault: " + words));
  }

  void carry_out(CalibrationRun* run, const RunActions& actions) {
    for (const RunAction& a : actions) {
      switch (a.kind) {
        case RunAction::Kind::DwellAccepted: checkpoint_rows_.push_back(a.row); break;
        case RunAction::Kind::Log: log_.push_back(a.text); break;
        case RunAction::Kind::CheckpointState: checkpoint_ = run->checkpoint_state(); break;
        case RunAction::Kind::ClearCheckpoint:
          checkpoint_rows_.clear();
          ++checkpoint_clears_;
          break;
        case RunAction::Kind::FitNow:
          fitted_.push_back(a.table);
          noise_models_.push_back(a.noise_model);
          if (answer_fits_) {
            const bool ok = run->fit_may_publish(a.fit_ticket);
            carry_out(run, run->on_fit_finished(a.fit_ticket, ok, ""));
          } else {
            open_tickets_.push_back(a.fit_ticket);
          }
          break;
        case RunAction::Kind::ResumeAt:
          resumes_.push_back(a.request);
          if (!controller_reachable_) {
            carry_out(run, run->on_resume_reply(a.request, false, false, "", 0.0, now_s_));
          } else if (refuse_resume_) {
            carry_out(
                run, run->on_resume_reply(a.request, true, false, "no such position", 0.0, now_s_));
          } else {
            const double stamp = rewind_to(a.request);
            carry_out(run, run->on_resume_reply(a.request, true, true, "resumed", stamp, now_s_));
          }
          break;
        case RunAction::Kind::Abort:
          aborts_.push_back(a.request.reason);
          stream_.resize(cursor_);  // the controller stops; nothing more comes
          break;
      }
    }
  }

  // The rewound protocol: the recording from the MOVING of the requested position (or of the one
  // after it) onward, shifted to start just after now. Returns the new MOVING's stamp.
  double rewind_to(const ControllerRequest& r) {
    std::size_t first = recording_.commands.size();
    int visits = 0;
    for (std::size_t i = 0; i < recording_.commands.size(); ++i) {
      const GimbalEvent& c = recording_.commands[i];
      if (c.state != GimbalState::Moving || c.phase != r.phase || c.step != r.step) continue;
      // The visit with the requested approach: first visit +1, second (return sweep) -1.
      ++visits;
      if ((r.approach > 0) != (visits == 1)) continue;
      first = i;
      break;
    }
    if (first == recording_.commands.size()) {
      first = 0;  // "from the first position"
    } else if (r.after) {
      first += 2;  // skip MOVING and SETTLED of that position: the next MOVING
    }
    if (r.reason.find("no dwell recorded") != std::string::npos) first = 0;
    const double old_start = recording_.commands[first].stamp_s;
    const double shift = now_s_ + 0.02 - old_start;
    std::vector<StreamEvent> next(stream_.begin(), stream_.begin() + cursor_);
    for (const StreamEvent& e : all_) {
      if (e.stamp_s < old_start) continue;
      StreamEvent moved = e;
      moved.stamp_s += shift;
      moved.command.stamp_s += moved.is_command ? shift : 0.0;
      moved.sample.stamp_s += moved.is_command ? 0.0 : shift;
      next.push_back(moved);
    }
    stream_ = next;
    return old_start + shift;
  }

  Recording recording_;
  std::vector<StreamEvent> all_, stream_;
  std::size_t cursor_ = 0;
  double now_s_ = 0.0;
  double idle_until_s_ = 0.0;  // play() goes on this long after the stream ran out
  long ticks_ = 0;
  bool controller_alive_ = true;
  bool controller_reachable_ = true;
  bool refuse_resume_ = false;
  bool answer_fits_ = true;
  double controller_dead_since_s_ = 0.0;
  std::vector<DwellRecord> checkpoint_rows_;
  CheckpointState checkpoint_;
  int checkpoint_clears_ = 0;
  std::vector<std::string> log_;
  std::vector<PositionTable> fitted_;
  std::vector<std::optional<NoiseModel>> noise_models_;  // handed out with each FitNow
  std::vector<std::uint64_t> open_tickets_;
  std::vector<ControllerRequest> resumes_;
  std::vector<std::string> aborts_;
};

RunOptions options_for(std::uint32_t steps) {
  RunOptions o;
  o.steps = steps;
  o.assembler.reorder_window_s = 0.25;
  return o;
}

// N = 4, at least `min_samples` per dwell, a faulty position measured again.
RunOptions retrying_options(std::uint32_t min_samples) {
  RunOptions o = options_for(4);
  o.min_samples_per_dwell = min_samples;
  o.retry_on_fault = true;
  return o;
}

// Every (phase, step) of an N-step one-way protocol exactly once, in protocol order.
void expect_complete_table(const PositionTable& table, std::uint32_t steps) {
  ASSERT_EQ(table.rows.size(), 3 * steps);
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    EXPECT_EQ(index(table.rows[i].phase), static_cast<int>(i / steps)) << "row " << i;
    EXPECT_EQ(table.rows[i].step, i % steps) << "row " << i;
    EXPECT_GT(table.rows[i].n, 20u) << "row " << i;
  }
}

bool log_contains(const std::vector<std::string>& log, const std::string& text) {
  for (const std::string& line : log) {
    if (line.find(text) != std::string::npos) return true;
  }
  return false;
}

TEST(CalibrationRun, CleanRunEndsWithOneFitOfEveryDwell) {
  FakeStand stand;
  CalibrationRun run(options_for(4));
  EXPECT_EQ(run.state(), RunState::Idle);
  stand.play(&run, stand.dwell_interval(Phase::Y, 1).first + 0.5);
  EXPECT_EQ(run.state(), RunState::Dwelling);
  stand.play(&run);
  EXPECT_EQ(run.state(), RunState::Done);
  ASSERT_EQ(stand.fitted_.size(), 1u);
  expect_complete_table(stand.fitted_[0], 4);
  // Every accepted row was checkpointed, and the state file says done.
  EXPECT_EQ(stand.checkpoint_rows_.size(), 12u);
  EXPECT_TRUE(stand.checkpoint_.done);
  EXPECT_EQ(stand.checkpoint_.rows, 12u);
  EXPECT_EQ(stand.checkpoint_.time_origin_s, stand.recording_.commands.front().stamp_s);
  const RunStatus s = run.status(stand.now_s_);
  EXPECT_EQ(s.retries, 0u);
  EXPECT_EQ(s.dwells_discarded, 0u);
  EXPECT_TRUE(stand.resumes_.empty());
  EXPECT_TRUE(stand.aborts_.empty());
}

// ---- The noise model of the long rest (docs/design.md section 12)
// ---------------------------------

// A 60 s first dwell under a slow bias (Gauss-Markov 0.002 m/s^2, 10 s).
void long_rest_with_slow_bias(SimulationOptions* so) {
  so->protocol.initial_rest_s = 60.0;
  so->bias_gm_sigma = 0.002;
  so->bias_gm_tau_s = 10.0;
}

// offline_fit's noise model of a recorded run: noise_model_of_run over every sample it holds.
std::optional<NoiseModel> offline_noise_model(const PositionTable& table,
                                              const std::vector<ImuSample>& samples) {
  std::vector<double> stamps;
  std::vector<Eigen::Vector3d> outputs;
  for (const ImuSample& s : samples) {
    stamps.push_back(s.stamp_s);
    outputs.push_back(s.outputs);
  }
  return noise_model_of_run(table, stamps, outputs);
}

void expect_same_model(const NoiseModel& a, const NoiseModel& b) {
  EXPECT_EQ(a.rest_samples, b.rest_samples);
  EXPECT_EQ(a.source, b.source);
  for (int s = 0; s < 3; ++s) {
    EXPECT_EQ(a.axes[s].white_std, b.axes[s].white_std) << s;
    EXPECT_EQ(a.axes[s].gm_sigma, b.axes[s].gm_sigma) << s;
    EXPECT_EQ(a.axes[s].gm_tau_s, b.axes[s].gm_tau_s) << s;
    EXPECT_EQ(a.axes[s].rw_density, b.axes[s].rw_density) << s;
  }
}

TEST(CalibrationRun, FitIsHandedTheNoiseModelOfTheLongRest) {
  // The live run keeps the first dwell's raw samples as they come and hands the fit the noise
  // model that offline_fit finds in the whole recording of the same run.
  FakeStand stand(4, false, long_rest_with_slow_bias);
  CalibrationRun run(options_for(4));
  stand.play(&run);
  ASSERT_EQ(run.state(), RunState::Done);
  ASSERT_EQ(stand.noise_models_.size(), 1u);
  ASSERT_TRUE(stand.noise_models_[0].has_value());
  const NoiseModel& live = *stand.noise_models_[0];
  EXPECT_FALSE(live.white()) << live.kind();
  const std::optional<NoiseModel> offline =
      offline_noise_model(stand.fitted_[0], stand.recording_.samples);
  ASSERT_TRUE(offline.has_value());
  expect_same_model(live, *offline);
  EXPECT_GE(live.rest_samples, stand.fitted_[0].rows.front().n);
  EXPECT_TRUE(log_contains(stand.log_, "noise model " + live.kind() + " from "));
  // Without a long rest the fit stays white (nothing to estimate from).
  FakeStand plain;
  CalibrationRun white_run(options_for(4));
  plain.play(&white_run);
  ASSERT_EQ(plain.noise_models_.size(), 1u);
  EXPECT_FALSE(plain.noise_models_[0].has_value());
}

TEST(CalibrationRun, LongRestMeasuredAgainAfterAFaultGivesTheNoiseModel) {
  // The first pass of the long rest keeps 5 samples only: a fault, the protocol rewound to the
  // first position, the rest measured again. The model is the second rest's (the first one's 5
  // samples are not in it): offline_fit's model of the accepted rows over the samples played.
  FakeStand stand(4, false, long_rest_with_slow_bias);
  stand.keep_first_samples_of(stand.dwell_interval(Phase::X, 0), 5);
  CalibrationRun run(retrying_options(20));
  stand.play(&run);
  ASSERT_EQ(stand.resumes_.size(), 1u);
  EXPECT_EQ(stand.resumes_[0].step, 0u);
  ASSERT_EQ(run.state(), RunState::Done);
  ASSERT_EQ(stand.noise_models_.size(), 1u);
  ASSERT_TRUE(stand.noise_models_[0].has_value());
  std::vector<ImuSample> played;
  for (const StreamEvent& e : stand.stream_) {
    if (!e.is_command) played.push_back(e.sample);
  }
  const std::optional<NoiseModel> offline = offline_noise_model(stand.fitted_[0], played);
  ASSERT_TRUE(offline.has_value());
  expect_same_model(*stand.noise_models_[0], *offline);
  EXPECT_GT(stand.noise_models_[0]->rest_samples, 1000u);
}

TEST(CalibrationRun, ImuOnAnotherClockFailsWithTheOffsetInsteadOfFitting) {
  FakeStand stand;
  stand.shift_imu_clock(1.3);
  CalibrationRun run(options_for(4));
  stand.play(&run);
  EXPECT_EQ(run.state(), RunState::FitFailed);
  EXPECT_TRUE(stand.fitted_.empty());
  const std::string error = run.status(stand.now_s_).fit_error;
  EXPECT_NE(error.find("IMU stamps are 1.3"), std::string::npos) << error;
  EXPECT_NE(error.find("pass imu_time_offset_s -1.3"), std::string::npos) << error;
  EXPECT_NE(run.missing_message().find("clocks not synchronized"), std::string::npos);

  // The offset given: the stamps agree and the run is fitted.
  FakeStand fixed_stand;
  fixed_stand.shift_imu_clock(1.3);
  RunOptions fixed = options_for(4);
  fixed.imu_time_offset_s = -1.3;
  CalibrationRun fixed_run(fixed);
  fixed_stand.play(&fixed_run);
  EXPECT_EQ(fixed_run.state(), RunState::Done);
  ASSERT_EQ(fixed_stand.fitted_.size(), 1u);
  expect_complete_table(fixed_stand.fitted_[0], 4);
}

TEST(CalibrationRun, TooFewSamplesAreMeasuredAgainOnRetry) {
  FakeStand stand;
  const auto bad = stand.dwell_interval(Phase::Y, 2);
  stand.keep_first_samples_of(bad, 5);
  CalibrationRun run(retrying_options(20));
  stand.play(&run);
  ASSERT_EQ(stand.resumes_.size(), 1u);
  EXPECT_EQ(stand.resumes_[0].phase, Phase::Y);
  EXPECT_EQ(stand.resumes_[0].step, 2u);
  EXPECT_FALSE(stand.resumes_[0].after);
  EXPECT_NE(stand.resumes_[0].reason.find("has 5 samples"), std::string::npos);
  EXPECT_EQ(run.state(), RunState::Done);
  ASSERT_EQ(stand.fitted_.size(), 1u);
  expect_complete_table(stand.fitted_[0], 4);
  const RunStatus s = run.status(stand.now_s_);
  EXPECT_EQ(s.retries, 1u);
  EXPECT_NE(s.last_fault.find("fewer than min_samples_per_dwell = 20"), std::string::npos);
}

// The minimum is inclusive: a dwell with exactly min_samples_per_dwell samples is accepted, one
// with one fewer is not.
TEST(CalibrationRun, MinSamplesPerDwellIsInclusive) {
  std::uint64_t fewest = 0;
  {
    FakeStand stand;
    CalibrationRun run(options_for(4));
    stand.play(&run);
    ASSERT_EQ(run.state(), RunState::Done);
    ASSERT_EQ(stand.fitted_.size(), 1u);
    fewest = stand.fitted_[0].rows.front().n;
    for (const DwellRecord& r : stand.fitted_[0].rows) fewest = std::min(fewest, r.n);
    ASSERT_GT(fewest, 2u);
  }
  FakeStand stand;
  RunOptions o = options_for(4);
  o.min_samples_per_dwell = fewest;
  CalibrationRun run(o);
  stand.play(&run);
  EXPECT_EQ(run.state(), RunState::Done) << "a dwell of exactly the minimum was refused";
  EXPECT_TRUE(stand.aborts_.empty());
  FakeStand short_stand;
  o.min_samples_per_dwell = fewest + 1;
  CalibrationRun short_run(o);
  short_stand.play(&short_run);
  EXPECT_EQ(short_run.state(), RunState::Aborted);
}

TEST(CalibrationRun, TooFewSamplesAbortWithoutRetry) {
  FakeStand stand;
  const auto bad = stand.dwell_interval(Phase::X, 1);
  stand.inject_first_pass(
      [&](const ImuSample& s) { return s.stamp_s >= bad.first + 0.1 && s.stamp_s < bad.second; });
  RunOptions o = options_for(4);
  o.min_samples_per_dwell = 20;
  CalibrationRun run(o);
  stand.play(&run);
  EXPECT_EQ(run.state(), RunState::Aborted);
  ASSERT_EQ(stand.aborts_.size(), 1u);
  EXPECT_NE(stand.aborts_[0].find("(on_fault: abort)"), std::string::npos);
  EXPECT_TRUE(stand.fitted_.empty());
  EXPECT_EQ(stand.checkpoint_.fault, stand.aborts_[0]);
  EXPECT_NE(run.missing_message().find("run aborted: dwell phase x step 1 has"), std::string::npos);
  // The rows before the fault stay in the checkpoint ("nothing lost").
  EXPECT_EQ(stand.checkpoint_rows_.size(), 1u);
}

TEST(CalibrationRun, GivesUpAfterMaxRetries) {
  FakeStand stand;
  RunOptions o = options_for(4);
  o.min_samples_per_dwell = 1000;  // no dwell ever has that many
  o.retry_on_fault = true;
  o.max_retries = 2;
  CalibrationRun run(o);
  stand.play(&run);
  EXPECT_EQ(stand.resumes_.size(), 2u);
  EXPECT_EQ(run.state(), RunState::Aborted);
  ASSERT_EQ(stand.aborts_.size(), 1u);
  EXPECT_NE(stand.aborts_[0].find("gave up after 2 retries (max_retries)"), std::string::npos);
  EXPECT_EQ(run.status(stand.now_s_).retries, 2u);
}

TEST(CalibrationRun, ImuStallDuringADwellIsRetried) {
  FakeStand stand;
  const auto dwell = stand.dwell_interval(Phase::Z, 0);
  // The stream stops in the middle of the dwell and comes back only after the rewind.
  stand.inject_first_pass([&](const ImuSample& s) { return s.stamp_s >= dwell.first + 0.3; });
  RunOptions o = options_for(4);
  o.imu_timeout_s = 0.5;
  o.retry_on_fault = true;
  CalibrationRun run(o);
  stand.play(&run, dwell.first + 0.3 + 0.4);
  EXPECT_FALSE(run.status(stand.now_s_).imu_silent);
  EXPECT_TRUE(stand.resumes_.empty());
  stand.play(&run);
  ASSERT_GE(stand.resumes_.size(), 1u);
  EXPECT_EQ(stand.resumes_[0].phase, Phase::Z);
  EXPECT_EQ(stand.resumes_[0].step, 0u);
  EXPECT_NE(stand.resumes_[0].reason.find("IMU stream stopped"), std::string::npos);
  EXPECT_EQ(run.state(), RunState::Done);
  ASSERT_EQ(stand.fitted_.size(), 1u);
  expect_complete_table(stand.fitted_[0], 4);
}

TEST(CalibrationRun, DwellWithoutAnySampleIsAFault) {
  FakeStand stand;
  const auto dwell = stand.dwell_interval(Phase::X, 2);
  stand.inject_first_pass(
      [&](const ImuSample& s) { return s.stamp_s >= dwell.first && s.stamp_s < dwell.second; });
  RunOptions o = options_for(4);
  o.min_samples_per_dwell = 10;
  CalibrationRun run(o);
  stand.play(&run);
  EXPECT_EQ(run.state(), RunState::Aborted);
  ASSERT_EQ(stand.aborts_.size(), 1u);
  EXPECT_NE(stand.aborts_[0].find("dwell phase x step 2 has no samples at all"), std::string::npos);
}

TEST(CalibrationRun, UnreachableControllerIsAskedAgain) {
  FakeStand stand;
  const auto bad = stand.dwell_interval(Phase::X, 3);
  stand.inject_first_pass(
      [&](const ImuSample& s) { return s.stamp_s >= bad.first + 0.2 && s.stamp_s < bad.second; });
  RunOptions o = options_for(4);
  o.min_samples_per_dwell = 20;
  o.retry_on_fault = true;
  o.request_retry_s = 0.5;
  CalibrationRun run(o);
  stand.controller_reachable_ = false;
  stand.play(&run, bad.second + 1.2);
  EXPECT_EQ(run.state(), RunState::WaitingForResume);
  const std::size_t asked = stand.resumes_.size();
  EXPECT_GE(asked, 2u);
  EXPECT_LE(asked, 3u);  // once per request_retry_s, not once per tick
  stand.controller_reachable_ = true;
  stand.play(&run);
  EXPECT_EQ(run.state(), RunState::Done) << ::testing::PrintToString(stand.log_);
  expect_complete_table(stand.fitted_.at(0), 4);
}

TEST(CalibrationRun, RefusedResumeAbortsWithTheControllersWords) {
  FakeStand stand;
  const auto bad = stand.dwell_interval(Phase::X, 3);
  stand.inject_first_pass(
      [&](const ImuSample& s) { return s.stamp_s >= bad.first + 0.2 && s.stamp_s < bad.second; });
  CalibrationRun run(retrying_options(20));
  stand.refuse_resume_ = true;
  stand.play(&run);
  EXPECT_EQ(run.state(), RunState::Aborted);
  EXPECT_NE(run.missing_message().find("refused to resume at phase x step 3: no such position"),
            std::string::npos);
  EXPECT_TRUE(stand.fitted_.empty());
}

TEST(CalibrationRun, RestartFromCheckpointContinuesAfterTheLastRow) {
  FakeStand stand;
  const auto cut = stand.dwell_interval(Phase::Y, 1);
  {
    CalibrationRun first(options_for(4));
    stand.play(&first, cut.first + 0.5);  // killed in the middle of dwell y 1
  }
  PositionTable saved;
  saved.rows = stand.checkpoint_rows_;
  ASSERT_EQ(saved.rows.size(), 5u);  // x 0..3, y 0
  const CheckpointState state = stand.checkpoint_;
  EXPECT_FALSE(state.done);

  CalibrationRun second(options_for(4));
  stand.carry_out(&second, second.restore(saved, state));
  EXPECT_TRUE(second.status(stand.now_s_).restored);
  stand.play(&second);
  ASSERT_EQ(stand.resumes_.size(), 1u);
  EXPECT_EQ(stand.resumes_[0].phase, Phase::Y);
  EXPECT_EQ(stand.resumes_[0].step, 0u);
  EXPECT_TRUE(stand.resumes_[0].after);
  EXPECT_EQ(second.state(), RunState::Done);
  ASSERT_EQ(stand.fitted_.size(), 1u);
  expect_complete_table(stand.fitted_[0], 4);
  // The drift term's clock is the first run's.
  EXPECT_EQ(stand.fitted_[0].time_origin_s, state.time_origin_s);
}

// The stand PC restarted: the calibration node comes back from its checkpoint beside a fresh,
// IDLE gimbal controller. Only with resume_idle_controller is that controller told to continue.
TEST(CalibrationRun, RestartedStandWithAnIdleControllerResumesOnlyWhenAllowed) {
  for (const bool allowed : {false, true}) {
    SCOPED_TRACE(allowed ? "resume_idle_controller" : "default");
    FakeStand stand;
    const auto cut = stand.dwell_interval(Phase::Y, 2);
    {
      CalibrationRun first(options_for(4));
      stand.play(&first, cut.first + 0.3);  // the PC loses power in dwell y 2
    }
    PositionTable saved;
    saved.rows = stand.checkpoint_rows_;
    ASSERT_EQ(saved.rows.size(), 6u);  // x 0..3, y 0..1
    RunOptions o = options_for(4);
    o.resume_idle_controller = allowed;
    CalibrationRun second(o);
    stand.carry_out(&second, second.restore(saved, stand.checkpoint_));
    stand.restart_controller(&second);  // fresh controller: IDLE, no commands
    stand.play(&second);
    if (!allowed) {
      EXPECT_TRUE(stand.resumes_.empty());
      EXPECT_TRUE(stand.fitted_.empty());
      continue;
    }
    ASSERT_EQ(stand.resumes_.size(), 1u);
    EXPECT_EQ(stand.resumes_[0].phase, Phase::Y);
    EXPECT_EQ(stand.resumes_[0].step, 1u);
    EXPECT_TRUE(stand.resumes_[0].after);
    EXPECT_NE(stand.resumes_[0].reason.find("stand restarted"), std::string::npos);
    EXPECT_EQ(second.state(), RunState::Done);
    ASSERT_EQ(stand.fitted_.size(), 1u);
    expect_complete_table(stand.fitted_[0], 4);
    EXPECT_EQ(stand.fitted_[0].time_origin_s, stand.checkpoint_.time_origin_s);
  }
}

TEST(CalibrationRun, RestoredCompleteRunIsFittedAtOnce) {
  FakeStand stand;
  CalibrationRun first(options_for(4));
  stand.play(&first);
  ASSERT_TRUE(stand.checkpoint_.done);
  PositionTable saved;
  saved.rows = stand.checkpoint_rows_;
  CalibrationRun second(options_for(4));
  stand.carry_out(&second, second.restore(saved, stand.checkpoint_));
  stand.carry_out(&second, second.tick(stand.now_s_));
  EXPECT_EQ(second.state(), RunState::Done);
  ASSERT_EQ(stand.fitted_.size(), 2u);
  expect_complete_table(stand.fitted_[1], 4);
}

TEST(CalibrationRun, RestoredAbortedRunStaysAborted) {
  CalibrationRun run(options_for(4));
  CheckpointState state;
  state.time_origin_s = 1.0;
  state.steps = 4;
  state.fault = "IMU stream stopped";
  run.restore(PositionTable(), state);
  EXPECT_EQ(run.state(), RunState::Aborted);
  EXPECT_NE(run.missing_message().find("run aborted: IMU stream stopped"), std::string::npos);
}

TEST(CalibrationRun, ControllerRestartMidRunResumesAfterTheLastRow) {
  FakeStand stand;
  const auto dwell = stand.dwell_interval(Phase::Z, 1);
  CalibrationRun run(options_for(4));
  stand.play(&run, dwell.first + 0.4);
  stand.kill_controller(&run);
  stand.play(&run, dwell.first + 2.0);
  EXPECT_TRUE(stand.resumes_.empty());  // a silent controller alone is no restart
  stand.restart_controller(&run);
  stand.play(&run);
  ASSERT_EQ(stand.resumes_.size(), 1u);
  EXPECT_EQ(stand.resumes_[0].phase, Phase::Z);
  EXPECT_EQ(stand.resumes_[0].step, 0u);
  EXPECT_TRUE(stand.resumes_[0].after);
  EXPECT_NE(stand.resumes_[0].reason.find("gimbal controller restarted"), std::string::npos);
  EXPECT_EQ(run.state(), RunState::Done);
  expect_complete_table(stand.fitted_.at(0), 4);
}

TEST(CalibrationRun, ControllerAbortEndsTheRunWithItsReason) {
  FakeStand stand;
  CalibrationRun run(options_for(4));
  stand.play(&run, stand.dwell_interval(Phase::X, 2).first);
  stand.carry_out(&run, run.on_controller_state("ABORTED", "ABORTED: limit switch hit"));
  EXPECT_EQ(run.state(), RunState::Aborted);
  EXPECT_EQ(run.status(stand.now_s_).fault, "limit switch hit");
  EXPECT_NE(run.missing_message().find("aborted by the gimbal controller: limit switch hit"),
            std::string::npos);
}

TEST(CalibrationRun, ControllerFaultInAMoveIsRetriedAtItsPosition) {
  FakeStand stand;
  const auto dwell = stand.dwell_interval(Phase::X, 2);
  RunOptions o = options_for(4);
  o.retry_on_fault = true;
  CalibrationRun run(o);
  stand.play(&run, dwell.first - 0.1);  // moving to x/2
  stand.controller_fault(&run, Phase::X, 2, "grbl: alarm 'ALARM:1' (Hard limit triggered.)");
  EXPECT_EQ(run.state(), RunState::WaitingForResume);  // not aborted: it will be retried
  stand.play(&run);
  ASSERT_EQ(stand.resumes_.size(), 1u);
  EXPECT_EQ(stand.resumes_[0].phase, Phase::X);
  EXPECT_EQ(stand.resumes_[0].step, 2u);
  EXPECT_FALSE(stand.resumes_[0].after);
  EXPECT_NE(stand.resumes_[0].reason.find("ALARM:1"), std::string::npos)
      << stand.resumes_[0].reason;
  EXPECT_NE(run.status(stand.now_s_).last_fault.find("Hard limit"), std::string::npos);
  EXPECT_EQ(run.status(stand.now_s_).retries, 1u);
  EXPECT_EQ(run.state(), RunState::Done);
  ASSERT_EQ(stand.fitted_.size(), 1u);
  expect_complete_table(stand.fitted_[0], 4);
}

TEST(CalibrationRun, ControllerFaultInADwellMeasuresItAgain) {
  FakeStand stand;
  const auto dwell = stand.dwell_interval(Phase::Y, 1);
  RunOptions o = options_for(4);
  o.retry_on_fault = true;
  CalibrationRun run(o);
  stand.play(&run, dwell.first + 0.4);  // in the dwell of y/1
  stand.controller_fault(&run, Phase::Y, 1, "smc100: serial port /dev/ttyUSB0 lost: end of file");
  stand.play(&run);
  ASSERT_EQ(stand.resumes_.size(), 1u);
  EXPECT_EQ(stand.resumes_[0].phase, Phase::Y);
  EXPECT_EQ(stand.resumes_[0].step, 1u);
  EXPECT_EQ(run.state(), RunState::Done);
  ASSERT_EQ(stand.fitted_.size(), 1u);
  // The dwell the fault cut short is not in the table: y/1 once, measured in full.
  expect_complete_table(stand.fitted_[0], 4);
}

TEST(CalibrationRun, ControllerFaultWithoutRetryAbortsAndKeepsTheDwells) {
  FakeStand stand;
  const auto dwell = stand.dwell_interval(Phase::X, 3);
  CalibrationRun run(options_for(4));
  stand.play(&run, dwell.first - 0.1);
  stand.controller_fault(&run, Phase::X, 3, "grbl: 'G21 G90 G0 X270.0000' answered 'error:9'");
  stand.play(&run);
  EXPECT_TRUE(stand.resumes_.empty());
  EXPECT_EQ(run.state(), RunState::Aborted);
  EXPECT_NE(run.missing_message().find("error:9"), std::string::npos) << run.missing_message();
  EXPECT_EQ(stand.checkpoint_rows_.size(), 3u);  // x/0, x/1, x/2
}

TEST(CalibrationRun, ControllerFaultGivesUpAfterMaxRetries) {
  FakeStand stand;
  const auto dwell = stand.dwell_interval(Phase::X, 1);
  RunOptions o = options_for(4);
  o.retry_on_fault = true;
  o.max_retries = 0;
  CalibrationRun run(o);
  stand.play(&run, dwell.first - 0.1);
  stand.controller_fault(&run, Phase::X, 1, "grbl: no reply on /dev/ttyACM0 within 2 s");
  stand.play(&run);
  EXPECT_TRUE(stand.resumes_.empty());
  EXPECT_EQ(run.state(), RunState::Aborted);
  EXPECT_NE(run.status(stand.now_s_).fault.find("no reply on /dev/ttyACM0"), std::string::npos)
      << run.status(stand.now_s_).fault;
  EXPECT_EQ(stand.checkpoint_rows_.size(), 1u);  // x/0 kept
}

TEST(CalibrationRun, ResetDuringTheFitWithholdsItsResult) {
  FakeStand stand;
  stand.answer_fits_ = false;
  CalibrationRun run(options_for(4));
  stand.play(&run);
  ASSERT_EQ(stand.open_tickets_.size(), 1u);
  EXPECT_EQ(run.state(), RunState::Fitting);
  const std::uint64_t ticket = stand.open_tickets_[0];
  EXPECT_TRUE(run.fit_may_publish(ticket));
  stand.carry_out(&run, run.reset("reset requested"));
  EXPECT_EQ(stand.checkpoint_clears_, 1);
  EXPECT_FALSE(run.fit_may_publish(ticket));
  run.on_fit_finished(ticket, true, "");
  EXPECT_EQ(run.state(), RunState::Idle);
  EXPECT_TRUE(run.table().rows.empty());
}

TEST(CalibrationRun, FitFailureIsReportedWithTheMissingDwells) {
  CalibrationRun run(options_for(4));
  FakeStand stand;
  stand.answer_fits_ = false;
  stand.play(&run);
  ASSERT_EQ(stand.open_tickets_.size(), 1u);
  run.on_fit_finished(stand.open_tickets_[0], false, "phase z has 2 dwells");
  EXPECT_EQ(run.state(), RunState::FitFailed);
  EXPECT_NE(run.missing_message().find("the fit failed (phase z has 2 dwells)"), std::string::npos);
}

// A failed fit is logged as an error naming what is missing: the operator's only word that DONE
// gave no result.
TEST(CalibrationRun, FitFailureIsLoggedAsAnError) {
  CalibrationRun run(options_for(4));
  FakeStand stand;
  stand.answer_fits_ = false;
  stand.play(&run);
  ASSERT_EQ(stand.open_tickets_.size(), 1u);
  const RunActions actions = run.on_fit_finished(stand.open_tickets_[0], false, "too few");
  int errors = 0;
  for (const RunAction& a : actions) {
    if (a.kind != RunAction::Kind::Log || a.level != RunAction::Level::Error) continue;
    ++errors;
    EXPECT_NE(a.text.find("no result after DONE"), std::string::npos) << a.text;
    EXPECT_NE(a.text.find("the fit failed (too few)"), std::string::npos) << a.text;
  }
  EXPECT_EQ(errors, 1);
}

TEST(CalibrationRun, NewRunRightAfterDoneStillFitsThePreviousOne) {
  FakeStand stand;
  CalibrationRun run(options_for(4));
  stand.answer_fits_ = false;
  // Everything up to DONE, but not the reorder window after it.
  const double done_s = stand.recording_.commands.back().stamp_s;
  stand.play(&run, done_s + 0.05);
  ASSERT_TRUE(stand.fitted_.empty());
  GimbalEvent start = stand.recording_.commands.front();
  start.stamp_s = done_s + 0.1;
  stand.carry_out(&run, run.on_command(start));
  ASSERT_EQ(stand.fitted_.size(), 1u);
  expect_complete_table(stand.fitted_[0], 4);
  EXPECT_TRUE(run.fit_may_publish(stand.open_tickets_.at(0)));  // the finished run's result
  EXPECT_EQ(stand.checkpoint_clears_, 1);
  EXPECT_EQ(run.state(), RunState::Running);
  EXPECT_TRUE(run.table().rows.empty());
  EXPECT_EQ(run.table().time_origin_s, start.stamp_s);
}

TEST(CalibrationRun, SecondRunAfterARunWithARetryStartsFresh) {
  FakeStand stand;
  const auto bad = stand.dwell_interval(Phase::Y, 0);
  stand.keep_first_samples_of(bad, 5);
  CalibrationRun run(retrying_options(20));
  stand.play(&run);
  ASSERT_EQ(run.state(), RunState::Done);
  ASSERT_EQ(stand.resumes_.size(), 1u);
  // The stand runs the protocol once more: a new run, not dwells added to the finished one.
  stand.rewind_to(ControllerRequest());  // from the first position
  stand.play(&run);
  ASSERT_EQ(stand.fitted_.size(), 2u);
  expect_complete_table(stand.fitted_[1], 4);
  EXPECT_EQ(run.state(), RunState::Done);
  EXPECT_EQ(run.status(stand.now_s_).retries, 0u);
}

// The counters a run reports (samples used, dropped, commands) belong to that run: a reset drops
// those of the assembler a retry replaced as well as those of the current one.
TEST(CalibrationRun, ResetZeroesTheCountersOfRestartedAssemblers) {
  FakeStand stand;
  stand.keep_first_samples_of(stand.dwell_interval(Phase::Y, 0), 5);
  CalibrationRun run(retrying_options(20));
  stand.play(&run);
  ASSERT_EQ(stand.resumes_.size(), 1u);  // a retry: the first assembler was replaced
  ASSERT_EQ(run.state(), RunState::Done);
  ASSERT_GT(run.status(stand.now_s_).counters.commands, 0u);
  ASSERT_GT(run.status(stand.now_s_).counters.samples_used, 0u);
  stand.carry_out(&run, run.reset("reset requested"));
  const AssemblerCounters after = run.status(stand.now_s_).counters;
  EXPECT_EQ(after.commands, 0u);
  EXPECT_EQ(after.samples_used, 0u);
  EXPECT_EQ(after.dropped_outside_dwell, 0u);
  EXPECT_EQ(after.dropped_settle_discard, 0u);
}

TEST(CalibrationRun, RepliesToARequestOfAResetRunAreIgnored) {
  FakeStand stand;
  const auto bad = stand.dwell_interval(Phase::X, 2);
  stand.inject_first_pass(
      [&](const ImuSample& s) { return s.stamp_s >= bad.first + 0.2 && s.stamp_s < bad.second; });
  RunOptions o = options_for(4);
  o.min_samples_per_dwell = 20;
  CalibrationRun run(o);
  stand.play(&run, bad.second + 0.5);
  ASSERT_EQ(run.state(), RunState::Aborted);
  ASSERT_EQ(stand.aborts_.size(), 1u);
  // The abort request, handed out before the reset, is answered after it.
  ControllerRequest old_request;
  old_request.reason = stand.aborts_[0];
  old_request.run_generation = 0;  // the run before the first reset
  run.reset("reset requested");
  run.on_abort_reply(old_request, false, "", stand.now_s_ + 1.0);
  EXPECT_EQ(run.state(), RunState::Idle);
  for (const RunAction& a : run.tick(stand.now_s_ + 5.0)) {
    EXPECT_NE(a.kind, RunAction::Kind::Abort) << "a reset run's abort asked again";
  }
  run.on_resume_reply(old_request, true, false, "refused", 0.0, stand.now_s_ + 5.0);
  EXPECT_EQ(run.state(), RunState::Idle);
  EXPECT_TRUE(run.status(stand.now_s_).fault.empty());
}

TEST(CalibrationRun, UndeliveredAbortIsAskedAgain) {
  FakeStand stand;
  const auto bad = stand.dwell_interval(Phase::X, 2);
  stand.inject_first_pass(
      [&](const ImuSample& s) { return s.stamp_s >= bad.first + 0.2 && s.stamp_s < bad.second; });
  RunOptions o = options_for(4);
  o.min_samples_per_dwell = 20;
  CalibrationRun run(o);
  stand.play(&run, bad.second + 0.5);
  ASSERT_EQ(stand.aborts_.size(), 1u);
  ControllerRequest r;
  r.reason = stand.aborts_[0];
  // The stand delivered it; say it did not: asked again after request_retry_s, not before.
  for (const RunAction& a : run.tick(stand.now_s_)) EXPECT_NE(a.kind, RunAction::Kind::Abort);
  r.run_generation = 0;
  run.on_abort_reply(r, false, "", stand.now_s_);
  int again = 0;
  for (const RunAction& a : run.tick(stand.now_s_ + 0.1)) again += a.kind == RunAction::Kind::Abort;
  EXPECT_EQ(again, 0);
  for (const RunAction& a : run.tick(stand.now_s_ + 0.6)) again += a.kind == RunAction::Kind::Abort;
  EXPECT_EQ(again, 1);
}

TEST(CalibrationRun, MalformedCommandsAreCountedAndDropsWarned) {
  CalibrationRun run(options_for(4));
  run.note_rejected_command();
  ImuSample bad;
  bad.stamp_s = 1.0;
  bad.outputs(0) = std::numeric_limits<double>::quiet_NaN();
  const RunActions actions = run.on_sample(bad);
  // Released only after the reorder window: the warning comes with the tick that releases it.
  std::vector<std::string> log;
  for (const RunAction& a : run.tick(2.0)) log.push_back(a.text);
  for (const RunAction& a : actions) log.push_back(a.text);
  const RunStatus s = run.status(2.0);
  EXPECT_EQ(s.commands_rejected, 1u);
  EXPECT_EQ(s.counters.dropped_non_finite, 1u);
  EXPECT_TRUE(log_contains(log, "NaN or infinite"));
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
