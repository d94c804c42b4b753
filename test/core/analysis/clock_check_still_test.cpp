// ClockCheck's still stretches (clock_check.h, "Memory"): a rest is summarized as it arrives, and
// the check's findings are those of keeping every bin. The stream is written here from the
// equations: a DUT with gravity on w turning about x in raised-cosine moves, a white noise, long
// rests between groups of moves. Fed backwards (every sample earlier than the first), no chunk of
// bins is ever complete and every bin is kept: the reference.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <random>
#include <vector>

#include "accel_intrinsics/core/analysis/clock_check.h"

namespace accel_intrinsics {
namespace core {
namespace {

struct Stream {
  std::vector<GimbalEvent> commands;
  std::vector<ImuSample> samples;
};

// Rests of rest_s, each followed by 6 moves of 0.5 s and dwells of 1.5 s; IMU stamps late by
// offset_s.
Stream stream(double rest_s, double offset_s, double rate_hz, std::uint64_t seed) {
  Stream out;
  double t = rest_s;
  int step = 0;
  for (int group = 0; group < 3; ++group) {
    for (int i = 0; i < 6; ++i, ++step) {
      GimbalEvent e;
      e.steps = 8;
      e.step = static_cast<std::uint32_t>(step + 1);
      e.angle_rad = 2.0 * M_PI * (step + 1) / 8.0;
      e.state = GimbalState::Moving;
      e.stamp_s = t;
      out.commands.push_back(e);
      e.state = GimbalState::Settled;
      e.stamp_s = t + 0.5;
      out.commands.push_back(e);
      t += 0.5 + 1.5;
    }
    t += rest_s;
  }
  auto angle_at = [&](double time) {
    double angle = 0.0;
    for (std::size_t i = 0; i + 1 < out.commands.size(); i += 2) {
      const double t0 = out.commands[i].stamp_s, t1 = out.commands[i + 1].stamp_s;
      const double from = out.commands[i].angle_rad - 2.0 * M_PI / 8.0;
      if (time >= t1) angle = out.commands[i].angle_rad;
      if (time > t0 && time < t1)
        angle = from + (2.0 * M_PI / 8.0) * 0.5 * (1.0 - std::cos(M_PI * (time - t0) / (t1 - t0)));
    }
    return angle;
  };
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.02);
  const auto n = static_cast<std::size_t>(t * rate_hz);
  for (std::size_t i = 0; i < n; ++i) {
    const double time = static_cast<double>(i) / rate_hz;
    const double a = angle_at(time);
    ImuSample s;
    s.stamp_s = time + offset_s;
    s.outputs = Eigen::Vector3d(noise(rng), 9.81 * std::sin(a) + noise(rng),
                                9.81 * std::cos(a) + noise(rng));
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
    EXPECT_NEAR(a.offset_s, b.offset_s, 1e-3) << "offset " << offset;
    if (offset != 0.0) EXPECT_NEAR(a.offset_s, offset, 0.02);
    EXPECT_NEAR(a.explained_at_zero, b.explained_at_zero, 1e-3) << "offset " << offset;
    EXPECT_NEAR(a.explained_at_offset, b.explained_at_offset, 1e-3) << "offset " << offset;
    EXPECT_NEAR(a.start_gap_s, b.start_gap_s, 1e-3) << "offset " << offset;
    EXPECT_NEAR(a.end_gap_s, b.end_gap_s, 1e-3) << "offset " << offset;
    EXPECT_EQ(a.motion_fills_moves, b.motion_fills_moves) << "offset " << offset;
    // 3 rests of 40 s: 3.2 kB a second each, bin by bin (384 kB); summarized, a few chunks.
    EXPECT_LT(summarized.bytes + 300000, every_bin.bytes)
        << summarized.bytes << " vs " << every_bin.bytes;
  }
}

TEST(ClockCheckStill, ALongerRestCostsNothingMore) {
  const Checked short_rest = check(stream(20.0, 2.0, 2000.0, 7), false);
  const Checked long_rest = check(stream(200.0, 2.0, 2000.0, 7), false);
  EXPECT_TRUE(long_rest.result.offset_found);
  EXPECT_NEAR(long_rest.result.offset_s, 2.0, 0.02);
  // 540 s more of rests (3 x 180 s): 1.7 MB bin by bin.
  EXPECT_LE(long_rest.bytes, short_rest.bytes + 2048)
      << long_rest.bytes << " vs " << short_rest.bytes;
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
