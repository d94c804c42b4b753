// The calibration run's memory does not grow with its long rest (issue 38; docs/noise.md "The
// long rest in constant memory"): a run with a first dwell of 20 s and the same run with one of
// 120 s, at 10 kHz, streamed through core::CalibrationRun as the node streams them. The stream is
// written here from the equations (gravity on w plus a white noise, turning during the moves);
// the parts' byte counts (CalibrationRun::memory()) are compared between the two runs: the long
// rest's statistics, the assembler's reorder buffer and the clock check's bins (a still stretch
// summarized) are the same size, and every sample of the rest reaches the noise model.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "accel_intrinsics/core/run/calibration_run.h"

namespace accel_intrinsics {
namespace core {
namespace {

constexpr double kRateHz = 10000.0;
constexpr double kMoveS = 0.5;
constexpr double kDwellS = 1.5;
constexpr int kShortDwells = 6;

struct Outcome {
  RunMemory peak;  // of each part, over the stream
  RunMemory end;   // after DONE and the reorder window
  std::uint64_t rest_samples_fed = 0;
  std::optional<NoiseModel> model;
  std::string why;
};

RunMemory max_of(const RunMemory& a, const RunMemory& b) {
  RunMemory m;
  m.assembler = std::max(a.assembler, b.assembler);
  m.long_rest = std::max(a.long_rest, b.long_rest);
  m.clock_check = std::max(a.clock_check, b.clock_check);
  m.moves = std::max(a.moves, b.moves);
  m.table = std::max(a.table, b.table);
  return m;
}

// A run on phase x: MOVING at 0, SETTLED 0.5 s later, a first dwell of first_dwell_s, then
// kShortDwells dwells of 1.5 s with 0.5 s moves, DONE. Samples every 1 / kRateHz s from 0 in
// stamp order, a command before a sample of the same stamp, as a driver and the controller
// publish them.
Outcome stream_run(double first_dwell_s) {
  RunOptions options;
  options.steps = 8;
  CalibrationRun run(options);
  std::vector<GimbalEvent> commands;
  double t = 0.0;
  for (int step = 0; step <= kShortDwells; ++step) {
    GimbalEvent e;
    e.phase = Phase::X;
    e.steps = 8;
    e.step = static_cast<std::uint32_t>(step);
    e.angle_rad = 2.0 * M_PI * step / 8.0;
    e.state = GimbalState::Moving;
    e.stamp_s = t;
    commands.push_back(e);
    e.state = GimbalState::Settled;
    e.stamp_s = t + kMoveS;
    commands.push_back(e);
    t += kMoveS + (step == 0 ? first_dwell_s : kDwellS);
  }
  GimbalEvent done = commands.back();
  done.state = GimbalState::Done;
  done.stamp_s = t;
  commands.push_back(done);
  const double rest_start_s = commands[1].stamp_s, rest_end_s = commands[2].stamp_s;

  std::mt19937_64 rng(38);
  std::normal_distribution<double> noise(0.0, 0.01);
  Outcome out;
  std::size_t next_command = 0;
  const auto n = static_cast<std::size_t>(std::llround(t * kRateHz));
  for (std::size_t i = 0; i <= n; ++i) {
    const double stamp = static_cast<double>(i) / kRateHz;
    while (next_command < commands.size() && commands[next_command].stamp_s <= stamp)
      run.on_command(commands[next_command++]);
    // The angle about x: that of the last command, turning at a constant rate during a move.
    const GimbalEvent& last = commands[next_command - 1];
    double angle = last.angle_rad;
    if (last.state == GimbalState::Moving)
      angle += (2.0 * M_PI / 8.0) * (stamp - last.stamp_s) / kMoveS;
    ImuSample s;
    s.stamp_s = stamp;
    s.outputs = Eigen::Vector3d(noise(rng), 9.81 * std::sin(angle) + noise(rng),
                                9.81 * std::cos(angle) + noise(rng));
    run.on_sample(s);
    if (stamp >= rest_start_s && stamp <= rest_end_s) ++out.rest_samples_fed;
    if (i % 1000 == 0) out.peak = max_of(out.peak, run.memory());
  }
  while (next_command < commands.size()) run.on_command(commands[next_command++]);
  run.tick(t + 1.0);
  out.end = run.memory();
  out.peak = max_of(out.peak, out.end);
  out.model = run.noise_model(&out.why);
  return out;
}

TEST(LongRestMemory, TheRunHoldsNoMoreForA120sRestThanFor20s) {
  const Outcome short_rest = stream_run(20.0);
  const Outcome long_rest = stream_run(120.0);

  // Every sample of the rest reached the noise model, in both runs.
  ASSERT_TRUE(short_rest.model.has_value()) << short_rest.why;
  ASSERT_TRUE(long_rest.model.has_value()) << long_rest.why;
  EXPECT_EQ(short_rest.model->rest_samples, short_rest.rest_samples_fed);
  EXPECT_EQ(long_rest.model->rest_samples, long_rest.rest_samples_fed);
  EXPECT_GT(long_rest.rest_samples_fed, 1190000u);

  // The long rest's statistics: the same bytes but for the Allan cluster sizes opened in between
  // (a few per decade of samples, under 2 kB each); under 256 kB. Keeping the raw samples would
  // take 32 bytes a sample: 32 MB more.
  EXPECT_LT(long_rest.peak.long_rest, short_rest.peak.long_rest + 32768);
  EXPECT_LT(long_rest.peak.long_rest, std::size_t{256} << 10);
  // The reorder buffer holds the window's events at any dwell length.
  EXPECT_LT(long_rest.peak.assembler, short_rest.peak.assembler + 4096);
  EXPECT_EQ(long_rest.end.table, short_rest.end.table);
  EXPECT_EQ(long_rest.peak.moves, 0u);  // record_moves is off
  // The clock check summarizes the still rest as it arrives: 100 s more of it cost no more than
  // two chunks of bins (where the rest meets a move; keeping it bin by bin took 32 bytes per 10 ms:
  // 320 kB more).
  EXPECT_LE(long_rest.peak.clock_check,
            short_rest.peak.clock_check + 2 * 32 * ClockCheck::kChunkBins)
      << long_rest.peak.clock_check << " vs " << short_rest.peak.clock_check;
  EXPECT_LE(long_rest.end.clock_check, short_rest.end.clock_check + 2 * 32 * ClockCheck::kChunkBins)
      << long_rest.end.clock_check << " vs " << short_rest.end.clock_check;
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
