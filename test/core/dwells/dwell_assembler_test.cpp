#include "accel_intrinsics/core/dwells/dwell_assembler.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "accel_intrinsics/core/simulation/simulator.h"

namespace core = accel_intrinsics::core;

namespace {
core::GimbalEvent command(double t, core::Phase phase, std::uint32_t step,
                          core::GimbalState state) {
  core::GimbalEvent e;
  e.stamp_s = t;
  e.phase = phase;
  e.step = step;
  e.steps = 4;
  e.angle_rad = core::step_angle(step, 4);
  e.state = state;
  return e;
}
core::ImuSample sample(double t, double value) {
  core::ImuSample s;
  s.stamp_s = t;
  s.outputs = Eigen::Vector3d(value, 2 * value, -value);
  return s;
}
}  // namespace

TEST(DwellAssembler, AssignsSamplesByStampToHalfOpenDwells) {
  core::DwellAssembler assembler;
  using S = core::GimbalState;
  assembler.add_sample(sample(0.5, 100));  // before any command: outside
  assembler.add_command(command(1.0, core::Phase::X, 0, S::Moving));
  assembler.add_sample(sample(1.5, 100));  // moving: outside
  assembler.add_command(command(2.0, core::Phase::X, 0, S::Settled));
  assembler.add_sample(sample(2.0, 1));  // at the SETTLED stamp: inside
  assembler.add_sample(sample(2.5, 2));
  assembler.add_sample(sample(2.9, 3));
  assembler.add_command(command(3.0, core::Phase::X, 1, S::Moving));
  assembler.add_sample(sample(3.0, 100));  // at the MOVING stamp: outside (half-open)
  assembler.add_command(command(4.0, core::Phase::X, 1, S::Settled));
  assembler.add_sample(sample(4.5, 10));
  assembler.add_command(command(5.0, core::Phase::X, 1, S::Done));
  assembler.add_sample(sample(5.5, 100));  // after DONE: outside
  assembler.flush();
  const auto& rows = assembler.table().rows;
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].n, 3u);
  EXPECT_DOUBLE_EQ(rows[0].mean(0), 2.0);
  EXPECT_DOUBLE_EQ(rows[0].mean(1), 4.0);
  EXPECT_DOUBLE_EQ(rows[0].std(0), 1.0);
  EXPECT_DOUBLE_EQ(rows[0].t_start_s, 2.0);
  EXPECT_DOUBLE_EQ(rows[0].t_end_s, 3.0);
  EXPECT_EQ(rows[1].n, 1u);
  EXPECT_EQ(rows[1].step, 1u);
  EXPECT_DOUBLE_EQ(rows[1].t_end_s, 5.0);
  EXPECT_TRUE(assembler.done());
  EXPECT_DOUBLE_EQ(assembler.time_origin_s(), 1.0);
  const auto& c = assembler.counters();
  EXPECT_EQ(c.samples_used, 4u);
  EXPECT_EQ(c.dropped_outside_dwell, 4u);
  EXPECT_EQ(c.commands, 5u);
  EXPECT_EQ(c.commands_out_of_order, 0u);
}

TEST(DwellAssembler, CountsNonFiniteBackwardsLateAndSettleDiscard) {
  core::AssemblerOptions options;
  options.settle_discard_s = 0.25;
  options.reorder_window_s = 0.1;
  core::DwellAssembler assembler(options);
  using S = core::GimbalState;
  assembler.add_command(command(0.0, core::Phase::Y, 0, S::Moving));
  assembler.add_command(command(1.0, core::Phase::Y, 0, S::Settled));
  assembler.add_sample(sample(1.1, 5));  // in the settle-discard window
  assembler.add_sample(sample(1.3, 1));
  assembler.add_sample(sample(1.3, 2));  // the stamp again, other values: clock went back
  assembler.add_sample(sample(1.4, std::nan("")));
  assembler.add_sample(sample(1.5, 3));
  assembler.add_sample(sample(2.0, 5));
  // Stamps up to 1.5 have been processed (newest 2.0 minus the 0.1 s window, up to the last
  // buffered stamp): a MOVING stamped 1.45 arrives too late to be put in order.
  assembler.add_command(command(1.45, core::Phase::Y, 1, S::Moving));
  assembler.flush();
  const auto& c = assembler.counters();
  EXPECT_EQ(c.dropped_settle_discard, 1u);
  EXPECT_EQ(c.dropped_backwards, 1u);
  EXPECT_EQ(c.dropped_non_finite, 1u);
  EXPECT_EQ(c.commands_out_of_order, 1u);
  ASSERT_EQ(assembler.table().rows.size(), 1u);
  EXPECT_DOUBLE_EQ(assembler.table().rows[0].t_start_s, 1.25);
}

TEST(DwellAssembler, ReorderWindowMakesArrivalOrderIrrelevant) {
  // The same messages in stamp order and shuffled within 0.2 s give identical tables.
  core::SimulationOptions sim;
  sim.protocol.steps_per_phase = 6;
  sim.protocol.dwell_s = 1.0;
  sim.rate_hz = 200;
  const core::Recording rec = core::simulate_recording(sim);
  struct Msg {
    double arrival;
    bool is_command;
    std::size_t i;
  };
  std::vector<Msg> ordered;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> delay(0.0, 0.2);
  for (std::size_t i = 0; i < rec.commands.size(); ++i)
    ordered.push_back({rec.commands[i].stamp_s + delay(rng), true, i});
  for (std::size_t i = 0; i < rec.samples.size(); ++i)
    ordered.push_back({rec.samples[i].stamp_s + 0.01, false, i});
  std::sort(ordered.begin(), ordered.end(),
            [](const Msg& a, const Msg& b) { return a.arrival < b.arrival; });

  core::DwellAssembler in_order, shuffled;
  core::feed_in_stamp_order(rec, &in_order);
  for (const auto& m : ordered) {
    if (m.is_command)
      shuffled.add_command(rec.commands[m.i]);
    else
      shuffled.add_sample(rec.samples[m.i]);
  }
  shuffled.flush();
  ASSERT_EQ(in_order.table().rows.size(), 18u);
  ASSERT_EQ(shuffled.table().rows.size(), 18u);
  for (std::size_t i = 0; i < 18; ++i) {
    EXPECT_EQ(in_order.table().rows[i].n, shuffled.table().rows[i].n);
    EXPECT_EQ(in_order.table().rows[i].mean, shuffled.table().rows[i].mean);
    EXPECT_EQ(in_order.table().rows[i].std, shuffled.table().rows[i].std);
  }
  EXPECT_EQ(shuffled.counters().dropped_late, 0u);
  EXPECT_EQ(shuffled.counters().commands_out_of_order, 0u);
}

TEST(DwellAssembler, ShuffledAndDuplicatedSamplesGiveTheSameTable) {
  // IMU messages reordered within 0.2 s and one in seven sent twice (a bag merged from two
  // recorders): every sample is used once, in stamp order, so the table is identical.
  core::SimulationOptions sim;
  sim.protocol.steps_per_phase = 6;
  sim.protocol.dwell_s = 1.0;
  sim.rate_hz = 200;
  const core::Recording rec = core::simulate_recording(sim);
  struct Msg {
    double arrival;
    bool is_command;
    std::size_t i;
  };
  std::vector<Msg> messages;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> delay(0.0, 0.2);
  for (std::size_t i = 0; i < rec.commands.size(); ++i)
    messages.push_back({rec.commands[i].stamp_s, true, i});
  std::uint64_t copies = 0;
  for (std::size_t i = 0; i < rec.samples.size(); ++i) {
    messages.push_back({rec.samples[i].stamp_s + delay(rng), false, i});
    if (i % 7 == 3) {
      messages.push_back({rec.samples[i].stamp_s + delay(rng), false, i});
      ++copies;
    }
  }
  std::sort(messages.begin(), messages.end(),
            [](const Msg& a, const Msg& b) { return a.arrival < b.arrival; });
  core::AssemblerOptions options;
  options.reorder_window_s = 0.25;
  core::DwellAssembler in_order(options), messy(options);
  core::feed_in_stamp_order(rec, &in_order);
  for (const auto& m : messages) {
    if (m.is_command)
      messy.add_command(rec.commands[m.i]);
    else
      messy.add_sample(rec.samples[m.i]);
  }
  messy.flush();
  ASSERT_EQ(messy.table().rows.size(), in_order.table().rows.size());
  for (std::size_t i = 0; i < messy.table().rows.size(); ++i) {
    EXPECT_EQ(messy.table().rows[i].n, in_order.table().rows[i].n);
    EXPECT_EQ(messy.table().rows[i].mean, in_order.table().rows[i].mean);
    EXPECT_EQ(messy.table().rows[i].std, in_order.table().rows[i].std);
  }
  EXPECT_EQ(messy.counters().duplicates, copies);
  EXPECT_EQ(messy.counters().dropped_backwards, 0u);
  EXPECT_EQ(messy.counters().dropped_late, 0u);
  EXPECT_EQ(messy.counters().samples_used, in_order.counters().samples_used);
}

TEST(DwellAssembler, SampleLaterThanTheWindowIsDroppedAndCounted) {
  // A sample that arrives 0.5 s after newer ones, with a 0.2 s window: its stamp has been
  // released already, so it cannot be put in order. It is dropped, counted, and not in the mean.
  core::AssemblerOptions options;
  options.reorder_window_s = 0.2;
  core::DwellAssembler assembler(options);
  using S = core::GimbalState;
  assembler.add_command(command(0.0, core::Phase::X, 0, S::Moving));
  assembler.add_command(command(1.0, core::Phase::X, 0, S::Settled));
  for (int k = 0; k < 10; ++k) assembler.add_sample(sample(1.0 + 0.1 * k, 2.0));
  assembler.add_sample(sample(1.25, 100.0));  // late: newest 1.9, released up to 1.7
  assembler.add_command(command(2.0, core::Phase::X, 1, S::Moving));
  assembler.flush();
  EXPECT_EQ(assembler.counters().dropped_late, 1u);
  ASSERT_EQ(assembler.table().rows.size(), 1u);
  EXPECT_EQ(assembler.table().rows[0].n, 10u);
  EXPECT_DOUBLE_EQ(assembler.table().rows[0].mean(0), 2.0);
}

TEST(DwellAssembler, ReturnsEachDwellOnceAndResetStartsOver) {
  core::SimulationOptions sim;
  sim.protocol.steps_per_phase = 3;
  sim.protocol.dwell_s = 0.5;
  const core::Recording rec = core::simulate_recording(sim);
  core::DwellAssembler assembler;
  // Fed by hand in stamp order (commands first at equal stamps), every call's returned rows.
  std::vector<core::DwellRecord> returned;
  const auto keep = [&](const core::CompletedRows& rows) {
    returned.insert(returned.end(), rows.begin(), rows.end());
  };
  std::size_t c = 0;
  for (const core::ImuSample& s : rec.samples) {
    while (c < rec.commands.size() && rec.commands[c].stamp_s <= s.stamp_s) {
      keep(assembler.add_command(rec.commands[c++]));
    }
    keep(assembler.add_sample(s));
  }
  while (c < rec.commands.size()) keep(assembler.add_command(rec.commands[c++]));
  keep(assembler.flush());
  ASSERT_EQ(returned.size(), 9u);
  ASSERT_EQ(assembler.table().rows.size(), 9u);
  for (std::size_t i = 0; i < returned.size(); ++i) {
    EXPECT_EQ(returned[i].t_start_s, assembler.table().rows[i].t_start_s) << i;
    EXPECT_EQ(returned[i].n, assembler.table().rows[i].n) << i;
  }
  EXPECT_TRUE(assembler.flush().empty());  // nothing returned twice
  assembler.reset();
  EXPECT_TRUE(assembler.table().rows.empty());
  EXPECT_FALSE(assembler.done());
}

// A reset starts a new run: its counters (what the result reports as used and dropped) count that
// run only, so the same recording fed after a reset counts exactly what it counted the first time.
TEST(DwellAssembler, ResetZeroesTheCounters) {
  core::SimulationOptions sim;
  sim.protocol.steps_per_phase = 3;
  sim.protocol.dwell_s = 0.5;
  const core::Recording rec = core::simulate_recording(sim);
  core::DwellAssembler assembler;
  core::feed_in_stamp_order(rec, &assembler);
  core::GimbalEvent broken = rec.commands.back();
  broken.stamp_s = std::nan("");  // a command with a non-finite stamp: counted and warned
  assembler.add_command(broken);
  const core::AssemblerCounters first = assembler.counters();
  ASSERT_EQ(first.commands, rec.commands.size() + 1);
  ASSERT_GT(first.samples_used, 0u);
  ASSERT_GT(first.commands_out_of_order, 0u);
  ASSERT_FALSE(first.last_warning.empty());
  assembler.reset();
  EXPECT_EQ(assembler.counters().commands, 0u);
  EXPECT_EQ(assembler.counters().samples_used, 0u);
  EXPECT_EQ(assembler.counters().commands_out_of_order, 0u);
  EXPECT_TRUE(assembler.counters().last_warning.empty());
  core::feed_in_stamp_order(rec, &assembler);
  EXPECT_EQ(assembler.counters().commands, rec.commands.size());
  EXPECT_EQ(assembler.counters().samples_used, first.samples_used);
  EXPECT_EQ(assembler.counters().dropped_outside_dwell, first.dropped_outside_dwell);
}

TEST(DwellAssembler, RecordsTheClosingPositionAsStepN) {
  // A recorded run with the closing position: step N (= steps) at 2 pi is a dwell like any other,
  // and with no angle effect it reads what step 0 read (the same orientation).
  core::SimulationOptions sim;
  sim.protocol.steps_per_phase = 4;
  sim.protocol.dwell_s = 1.0;
  sim.protocol.closing_position = true;
  sim.rate_hz = 200;
  const core::Recording rec = core::simulate_recording(sim);
  core::DwellAssembler assembler;
  core::feed_in_stamp_order(rec, &assembler);
  const auto& rows = assembler.table().rows;
  ASSERT_EQ(rows.size(), 15u);
  EXPECT_EQ(assembler.counters().commands_out_of_order, 0u);
  const double sigma = core::sample_noise_std(sim);
  for (int phase = 0; phase < 3; ++phase) {
    const core::DwellRecord& first = rows[5 * phase];
    const core::DwellRecord& closing = rows[5 * phase + 4];
    EXPECT_EQ(core::index(closing.phase), phase);
    EXPECT_EQ(closing.step, 4u);
    EXPECT_EQ(closing.angle_rad, 2.0 * core::kPi);
    EXPECT_GT(closing.t_start_s, rows[5 * phase + 3].t_end_s);
    const double tolerance = 6.0 * sigma * std::sqrt(1.0 / first.n + 1.0 / closing.n);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(closing.mean(k), first.mean(k), tolerance) << phase << k;
    }
  }
}

TEST(DwellAssembler, ReleasesInStampOrderWhateverMixOfInOrderAndLateArrivals) {
  // Most messages arrive in order (the fast path), some late within the window (the heap), a
  // command arrives after a sample with its stamp: released strictly by (stamp, commands first,
  // arrival), the order of one heap over everything.
  core::AssemblerOptions options;
  options.reorder_window_s = 0.5;
  core::DwellAssembler assembler(options);
  std::vector<std::pair<double, char>> released;  // (stamp, 'c' command / 's' sample)
  assembler.set_release_observers(
      [&](const core::GimbalEvent& c) {
        released.push_back({c.stamp_s, 'c'});
      },
      [&](const core::ImuSample& s) {
        released.push_back({s.stamp_s, 's'});
      });
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> stamps;
  for (int i = 0; i < 2000; ++i) stamps.push_back(0.001 * i);
  // One in ten arrives up to 0.3 s late.
  std::vector<std::pair<double, double>> arrivals;  // (arrival, stamp)
  for (double t : stamps) arrivals.push_back({t + (u(rng) < 0.1 ? 0.3 * u(rng) : 0.0), t});
  std::stable_sort(arrivals.begin(), arrivals.end());
  core::GimbalEvent moving;
  moving.state = core::GimbalState::Moving;
  bool command_sent = false;
  for (const auto& a : arrivals) {
    core::ImuSample s;
    s.stamp_s = a.second;
    assembler.add_sample(s);
    if (!command_sent && a.second == stamps[500]) {
      moving.stamp_s = stamps[500];  // after the sample with its stamp
      assembler.add_command(moving);
      command_sent = true;
    }
  }
  assembler.flush();
  ASSERT_TRUE(command_sent);
  ASSERT_EQ(released.size(), stamps.size() + 1);
  for (std::size_t i = 1; i < released.size(); ++i) {
    ASSERT_LE(released[i - 1].first, released[i].first) << i;
  }
  const auto command =
      std::find(released.begin(), released.end(), std::make_pair(stamps[500], 'c'));
  ASSERT_NE(command, released.end());
  EXPECT_EQ(*(command + 1), std::make_pair(stamps[500], 's'));  // the command first
  EXPECT_EQ(assembler.counters().dropped_late, 0u);
}
