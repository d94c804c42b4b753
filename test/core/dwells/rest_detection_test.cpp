// Rest detection (rest_detection.h) on streams written here sample by sample: the quiet level of
// a quantized output whose blocks read constant is floored by its output step; a still span whose
// output creeps (a device settling on a soft surface) is rejected with the output and the size of
// the creep, and the same span without the creep is a rest.
#include "accel_intrinsics/core/dwells/rest_detection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace accel_intrinsics {
namespace core {
namespace {

TEST(RestDetection, TheQuietStdOfAQuantizedStreamIsFlooredByItsFirstStep) {
  // A still DUT read through an output quantized to 0.01 m/s^2: x reads 0.00 once, then 0.01
  // for good; y and z never change. Every block but the first reads constant (std 0), so the
  // quiet std of x rests on the one output step, seen between the first two samples: half a step
  // (rest_detection.cpp, floored()); y and z show no step and stay at 0.
  const double step = 0.01;
  std::vector<ImuSample> samples(200);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    samples[i].stamp_s = 0.01 * static_cast<double>(i);
    samples[i].outputs = Eigen::Vector3d(i == 0 ? 0.0 : step, 0.0, 9.81);
  }
  const Eigen::Vector3d quiet = quiet_std_of(samples, 10, 0.5);
  EXPECT_NEAR(quiet.x(), 0.5 * step, 1e-12);
  EXPECT_EQ(quiet.y(), 0.0);
  EXPECT_EQ(quiet.z(), 0.0);
}

// A still span of 8 s at 200 Hz (blocks of 0.25 s, 50 samples): each output sits at its level with
// a square-wave "noise" of +-sigma (the sign flips every sample, so every block of an even count
// averages it out exactly); optionally v creeps down linearly at `creep` m/s^2 per second, as a
// device tilting while it settles. The creep moves v by 0.0041 m/s^2 per block: below the block
// step that breaks a run (mean_step_factor 8 standard errors, 0.016), but 20 blocks of it between
// the first and the last third (0.081) exceed creep_factor 15 standard errors (0.030).
std::vector<ImuSample> still_span(double creep) {
  const double rate = 200.0, sigma = 0.01;
  const Eigen::Vector3d level(0.30, -0.20, 9.80);
  std::vector<ImuSample> samples(1600);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const double t = static_cast<double>(i) / rate;
    const double sign = i % 2 == 0 ? 1.0 : -1.0;
    samples[i].stamp_s = t;
    samples[i].outputs = level + Eigen::Vector3d(sign, -sign, sign) * sigma;
    samples[i].outputs.y() -= creep * t;
  }
  return samples;
}

std::string significant(double value, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", digits, value);
  return buf;
}

// The creep rejection names the output and the change to 3 significant digits and its size in
// quiet std to 2; nothing else reached that message (a mutation of its precision survived).
TEST(RestDetection, SlowCreepIsRejectedNamingTheOutputAndTheChange) {
  const double creep = 0.0162469;  // m/s^2 per second
  const std::vector<ImuSample> samples = still_span(creep);
  const RestDetection d = detect_rests(samples);
  EXPECT_TRUE(d.rests.empty());
  ASSERT_EQ(d.rejected.size(), 1u);
  const RejectedSpan& span = d.rejected.front();
  // The change between the first and the last third of the span kept (after trimming), from the
  // stream's equation: the mean of v over the samples of each third.
  std::vector<double> v;
  for (const ImuSample& s : samples)
    if (s.stamp_s >= span.t_start_s && s.stamp_s <= span.t_end_s) v.push_back(s.outputs.y());
  ASSERT_EQ(v.size() % (3 * d.block_samples), 0u) << "the span is not whole thirds of blocks";
  const std::size_t third = v.size() / 3;
  double first = 0.0, last = 0.0;
  for (std::size_t i = 0; i < third; ++i) {
    first += v[i] / static_cast<double>(third);
    last += v[v.size() - third + i] / static_cast<double>(third);
  }
  const double change = last - first;
  EXPECT_NEAR(change, -creep * 0.25 * static_cast<double>(2 * third / d.block_samples), 1e-12);
  const std::string expected = "output v moves by " + significant(change, 3) + " (" +
                               significant(std::abs(change) / d.quiet_std.y(), 2) + " quiet std)";
  EXPECT_NE(span.reason.find("slow motion, not a rest"), std::string::npos) << span.reason;
  EXPECT_NE(span.reason.find(expected), std::string::npos)
      << span.reason << "\nexpected: " << expected;
}

// Control: the same span without the creep is one rest at the levels written.
TEST(RestDetection, TheSameSpanWithoutCreepIsARest) {
  const RestDetection d = detect_rests(still_span(0.0));
  EXPECT_TRUE(d.rejected.empty()) << d.rejected.front().reason;
  ASSERT_EQ(d.rests.size(), 1u);
  EXPECT_LT((d.rests.front().mean - Eigen::Vector3d(0.30, -0.20, 9.80)).norm(), 1e-9);
  EXPECT_GE(d.rests.front().t_end_s - d.rests.front().t_start_s, 7.0);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
