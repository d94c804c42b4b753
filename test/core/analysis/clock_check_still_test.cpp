// ClockCheck's still stretches (clock_check.h, "Memory"): a rest is summarized as it arrives, and
// the check's findings are those of keeping every bin. The stream is written here from the
// equations: an ideal DUT turned in raised-cosine moves through the three phases, a white noise, a
// long rest in each phase. Fed backwards (every sample earlier than the first), no chunk of bins
// is ever complete and every bin is kept: the reference.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "accel_intrinsics/core/analysis/clock_check.h"
#include "accel_intrinsics/core/model/gimbal_kinematics.h"

namespace accel_intrinsics {
namespace core {
namespace {

struct Stream {
  std::vector<GimbalEvent> commands;
  std::vector<ImuSample> samples;
};

// Three phases; in each, a remount (1 s) to angle 0, a rest of rest_s, then 6 steps of 45 degrees
// (moves of 0.5 s, dwells of 1.5 s). The outputs are those of an ideal DUT (the specific force in
// the pose of docs/design.md's gimbal) plus a white noise; IMU stamps late by offset_s.
Stream stream(double rest_s, double offset_s, double rate_hz, std::uint64_t seed) {
  Stream out;
  double t = 0.0;
  const Phase phases[] = {Phase::X, Phase::Y, Phase::Z};
  for (Phase phase : phases) {
    for (std::uint32_t step = 0; step <= 6; ++step) {
      const double move_s = step == 0 ? 1.0 : 0.5;
      GimbalEvent e;
      e.phase = phase;
      e.steps = 8;
      e.step = step;
      e.angle_rad = 2.0 * M_PI * step / 8.0;
      e.state = GimbalState::Moving;
      e.stamp_s = t;
      out.commands.push_back(e);
      e.state = GimbalState::Settled;
      e.stamp_s = t + move_s;
      out.commands.push_back(e);
      t += move_s + (step == 0 ? rest_s : 1.5);
    }
  }
  const double g = 9.81;
  auto force = [&](const GimbalEvent& c) {
    return specific_force_in_dut(phase_pose(c.phase, c.angle_rad), g);
  };
  const Eigen::Vector3d start = specific_force_in_dut(phase_pose(Phase::Z, 1.0), g);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.02);
  auto n = static_cast<std::size_t>((t + 1.0) * rate_hz);
  // The check's bins start at the first sample it gets: the last is a whole number of bins later,
  // so that fed backwards, it bins the samples alike.
  n -= (n - 1) % static_cast<std::size_t>(std::llround(rate_hz * ClockCheckOptions().bin_s));
  std::size_t next = 0;  // the next command
  for (std::size_t i = 0; i < n; ++i) {
    const double time = static_cast<double>(i) / rate_hz;
    while (next < out.commands.size() && out.commands[next].stamp_s <= time) ++next;
    Eigen::Vector3d f = start;
    if (next > 0) {
      const GimbalEvent& last = out.commands[next - 1];
      f = force(last);
      if (last.state == GimbalState::Moving) {  // from the pose before, to the command's
        const Eigen::Vector3d from = next >= 2 ? force(out.commands[next - 2]) : start;
        const double x = move_fraction(time, last.stamp_s, out.commands[next].stamp_s);
        f = (1.0 - x) * from + x * f;
      }
    }
    ImuSample s;
    s.stamp_s = time + offset_s;
    s.outputs = f + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    out.samples.push_back(s);
  }
  return out;
}

struct Checked {
  ClockCheckResult result;
  std::size_t bytes = 0;
};

Checked check(const Stream& s, bool backwards) {
  ClockCheck check;
  for (const GimbalEvent& c : s.commands) check.add_command(c);
  if (backwards) {
    for (auto it = s.samples.rbegin(); it != s.samples.rend(); ++it) check.add_sample(*it);
  } else {
    for (const ImuSample& sample : s.samples) check.add_sample(sample);
  }
  return {check.result(), check.memory_bytes()};
}

TEST(ClockCheckStill, ARestSummarizedFindsWhatEveryBinFinds) {
  const double offsets[] = {0.0, 0.3, -1.0, 3.0, 45.0};
  std::uint64_t seed = 0;
  for (double offset : offsets) {
    const Stream s = stream(40.0, offset, 1000.0, ++seed);
    const Checked summarized = check(s, false);
    const Checked every_bin = check(s, true);
    const ClockCheckResult& a = summarized.result;
    const ClockCheckResult& b = every_bin.result;
    ASSERT_TRUE(a.checked) << a.not_checked_why;
    ASSERT_TRUE(b.checked) << b.not_checked_why;
    EXPECT_EQ(a.offset_found, b.offset_found) << "offset " << offset;
    EXPECT_EQ(a.offset_found, offset != 0.0) << "offset " << offset;
    // The same findings, but for a sample on a bin's edge that rounding puts in the next bin.
    EXPECT_NEAR(a.offset_s, b.offset_s, 2e-3) << "offset " << offset;
    if (offset != 0.0) EXPECT_NEAR(a.offset_s, offset, 0.02);
    EXPECT_NEAR(a.explained_at_zero, b.explained_at_zero, 2e-3) << "offset " << offset;
    EXPECT_NEAR(a.explained_at_offset, b.explained_at_offset, 2e-3) << "offset " << offset;
    EXPECT_NEAR(a.start_gap_s, b.start_gap_s, 0.011) << "offset " << offset;  // a bin
    EXPECT_NEAR(a.end_gap_s, b.end_gap_s, 0.011) << "offset " << offset;
    EXPECT_EQ(a.motion_fills_moves, b.motion_fills_moves) << "offset " << offset;
    // 3 rests of 40 s: 3.2 kB a second each, bin by bin (384 kB); summarized, a few chunks.
    EXPECT_LT(summarized.bytes + 250000, every_bin.bytes)
        << summarized.bytes << " vs " << every_bin.bytes;
  }
}

TEST(ClockCheckStill, ALongerRestCostsNothingMore) {
  const Checked short_rest = check(stream(20.0, 2.0, 2000.0, 7), false);
  const Checked long_rest = check(stream(200.0, 2.0, 2000.0, 7), false);
  EXPECT_TRUE(long_rest.result.offset_found);
  EXPECT_NEAR(long_rest.result.offset_s, 2.0, 0.02);
  // 540 s more of rests (3 x 180 s): 1.7 MB bin by bin; summarized, a chunk more or less where a
  // rest meets a move (the chunks fall elsewhere on the moves).
  EXPECT_LE(long_rest.bytes, short_rest.bytes + 4 * 32 * ClockCheck::kChunkBins)
      << long_rest.bytes << " vs " << short_rest.bytes;
}

// A chunk joins a still stretch when its motion stays below the noise floor seen so far
// (clock_check.h, "Memory"), the first chunk's included. Written here without noise: x ramps
// (1 m/s^2 a second: a motion of 0.1 at every boundary) for 4.56 s, from the first sample, then
// holds; a wiggle of 1e-4 m/s^2 (far below the ramp's motion, far above nothing) follows in the
// fourth chunk, then x holds again. With the ramp's first chunk counted, the floor is the ramp's
// and the wiggle is summarized: of the 8 chunks, the first three (the floor is known from the
// fourth on) and the last two (waiting for the next) are kept bin by bin, 5 in all.
TEST(ClockCheckStill, TheFloorCountsTheFirstChunksMotion) {
  ClockCheck check;
  const double bin_s = ClockCheckOptions().bin_s;
  const double chunk_s = ClockCheck::kChunkBins * bin_s;
  const double rate_hz = 1000.0;
  for (std::size_t i = 0; i < static_cast<std::size_t>(8 * chunk_s * rate_hz); ++i) {
    ImuSample s;
    s.stamp_s = static_cast<double>(i) / rate_hz;
    const double t = s.stamp_s;
    double x = std::min(t, 4.56);
    if (t >= 3 * chunk_s && t < 4 * chunk_s) x += 1e-4 * std::sin(2.0 * M_PI * t / 0.4);
    s.outputs = Eigen::Vector3d(x, 0.0, 9.81);
    check.add_sample(s);
  }
  // Beyond what an empty check holds (its noise-floor histograms are of fixed size).
  const std::size_t held = check.memory_bytes() - ClockCheck().memory_bytes();
  const std::size_t chunk_bytes = ClockCheck::kChunkBins * 32;  // 32 bytes a bin
  EXPECT_GT(held, 5 * chunk_bytes) << held;
  EXPECT_LT(held, 6 * chunk_bytes) << held;
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
