// The long rest accumulated as it streams (issue 38; docs/noise.md): the streamed Allan curve and
// noise model against the batch ones on the stored samples (overlapping_allan_deviation,
// estimate_noise_model), the blocks against the equal-duration blocks written here from their
// definition, on streams written here from the equations (white noise, a random walk, a
// Gauss-Markov bias, summed sample by sample) and on the real Xsens session; a 120 s rest at
// 50 kHz used whole; memory that does not grow with the rest.
#include "accel_intrinsics/core/noise/rest_accumulator.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "../../support/source_dir.h"
#include "accel_intrinsics/core/dwells/rest_detection.h"
#include "accel_intrinsics/core/dwells/samples_file.h"
#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace core {
namespace {

struct Stream {
  std::vector<double> stamps;
  std::vector<Eigen::Vector3d> outputs;
};

// A static accelerometer at rate_hz for seconds: gravity on w, a white noise of per-sample std
// white, a random walk of density walk ((m/s^2)/sqrt(s)) and a first-order Gauss-Markov bias
// (gm_sigma, gm_tau_s), each summed sample by sample; stamps with a small jitter.
Stream static_stream(double rate_hz, double seconds, double white, double walk, double gm_sigma,
                     double gm_tau_s, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> jitter(-0.05, 0.05);
  const std::size_t n = static_cast<std::size_t>(std::llround(rate_hz * seconds));
  const double dt = 1.0 / rate_hz;
  const double phi = std::exp(-dt / gm_tau_s);
  Stream s;
  s.stamps.reserve(n);
  s.outputs.reserve(n);
  Eigen::Vector3d rw = Eigen::Vector3d::Zero(), gm = Eigen::Vector3d::Zero();
  const Eigen::Vector3d level(0.12, -0.34, 9.81);
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector3d x;
    for (int a = 0; a < 3; ++a) {
      rw(a) += walk * std::sqrt(dt) * normal(rng);
      gm(a) = phi * gm(a) + gm_sigma * std::sqrt(1.0 - phi * phi) * normal(rng);
      x(a) = level(a) + rw(a) + gm(a) + white * normal(rng);
    }
    s.stamps.push_back(1000.0 + (static_cast<double>(i) + jitter(rng)) * dt);
    s.outputs.push_back(x);
  }
  return s;
}

// The blocks as defined (noise.h noise_model_of_run): kRestBlocks of equal duration over the
// first to last stamp (fewer when shorter than 1 s), each sample in the block its stamp falls in.
struct ReferenceBlock {
  double t0 = 0.0, t1 = 0.0;  // the block's edges
  std::size_t n = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
};
std::vector<ReferenceBlock> reference_blocks(const Stream& s) {
  const double first = s.stamps.front(), span = s.stamps.back() - first;
  const int count = std::max(1, std::min(kRestBlocks, static_cast<int>(std::floor(span))));
  std::vector<ReferenceBlock> out(static_cast<std::size_t>(count));
  for (int b = 0; b < count; ++b) {
    out[b].t0 = first + span * b / count;
    out[b].t1 = first + span * (b + 1) / count;
  }
  for (std::size_t i = 0; i < s.stamps.size(); ++i) {
    const std::size_t b = std::min<std::size_t>(
        out.size() - 1, static_cast<std::size_t>((s.stamps[i] - first) / (span / count)));
    ++out[b].n;
    out[b].mean += s.outputs[i];
  }
  for (ReferenceBlock& b : out) b.mean /= static_cast<double>(b.n);
  return out;
}

RestAccumulator accumulate(const Stream& s) {
  RestAccumulator acc;
  for (std::size_t i = 0; i < s.stamps.size(); ++i) acc.add(s.stamps[i], s.outputs[i]);
  return acc;
}

double rate_of(const Stream& s) {
  return static_cast<double>(s.stamps.size() - 1) / (s.stamps.back() - s.stamps.front());
}

// The streamed curve is the batch curve: same cluster sizes, taus and uncertainties exactly,
// deviations to rounding.
void expect_same_curve(const AllanCurve& streamed, const AllanCurve& batch, double rel) {
  ASSERT_EQ(streamed.tau_s.size(), batch.tau_s.size());
  EXPECT_EQ(streamed.samples, batch.samples);
  for (std::size_t i = 0; i < batch.tau_s.size(); ++i) {
    EXPECT_EQ(streamed.tau_s[i], batch.tau_s[i]) << i;
    EXPECT_EQ(streamed.relative_std[i], batch.relative_std[i]) << i;
    for (int a = 0; a < 3; ++a)
      EXPECT_NEAR(streamed.adev[i](a), batch.adev[i](a), rel * batch.adev[i](a))
          << "tau " << batch.tau_s[i] << " axis " << a;
  }
}

// The blocks: each is exactly the samples between its first and last stamps (n and mean), and
// its edges lie within one sub-block of the equal-duration edges.
void expect_blocks(const RestAccumulator& acc, const Stream& s) {
  const std::vector<DwellRecord> blocks = acc.rest_blocks();
  const std::vector<ReferenceBlock> ref = reference_blocks(s);
  ASSERT_EQ(blocks.size(), ref.size());
  const double w = acc.sub_block_s();
  std::size_t total = 0;
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    const DwellRecord& r = blocks[b];
    std::size_t n = 0;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < s.stamps.size(); ++i) {
      if (s.stamps[i] < r.t_start_s || s.stamps[i] > r.t_end_s) continue;
      ++n;
      sum += s.outputs[i];
    }
    EXPECT_EQ(r.n, n) << b;
    const Eigen::Vector3d direct = sum / static_cast<double>(n);
    EXPECT_LT((r.mean - direct).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, direct.norm())) << b;
    EXPECT_LE(std::abs(r.t_start_s - ref[b].t0), w) << b;
    EXPECT_LE(std::abs(r.t_end_s - ref[b].t1), w) << b;
    // Samples moved across an edge: at most a sub-block's worth at each end.
    const double per_sub = w * rate_of(s) + 1.0;
    EXPECT_LE(std::abs(static_cast<double>(r.n) - static_cast<double>(ref[b].n)), 2.0 * per_sub)
        << b;
    total += r.n;
  }
  EXPECT_EQ(total, s.stamps.size());
  // A sub-block is at most 2 / kSubBlocks of the rest.
  EXPECT_LE(w, 2.0 * (s.stamps.back() - s.stamps.front()) / RestAccumulator::kSubBlocks);
}

void expect_same_model(const NoiseModel& streamed, const NoiseModel& batch) {
  EXPECT_EQ(streamed.rest_samples, batch.rest_samples);
  EXPECT_EQ(streamed.rate_hz, batch.rate_hz);
  for (int a = 0; a < 3; ++a) {
    const AxisNoiseModel &x = streamed.axes[a], &y = batch.axes[a];
    EXPECT_NEAR(x.white_std, y.white_std, 1e-9 * y.white_std) << a;
    EXPECT_NEAR(x.gm_sigma, y.gm_sigma, 1e-7 * y.gm_sigma) << a;
    EXPECT_EQ(x.gm_tau_s, y.gm_tau_s) << a;
    EXPECT_NEAR(x.rw_density, y.rw_density, 1e-7 * y.rw_density) << a;
  }
}

class RestAccumulatorAtRate : public ::testing::TestWithParam<double> {};

TEST_P(RestAccumulatorAtRate, StreamedCurveAndBlocksAreTheBatchOnes) {
  const double rate = GetParam();
  const Stream s = static_stream(rate, 120.0, 0.02, 2e-4, 1.5e-3, 15.0, 38);
  const RestAccumulator acc = accumulate(s);
  ASSERT_EQ(acc.samples(), s.stamps.size());
  EXPECT_EQ(acc.rate_hz(), rate_of(s));
  expect_same_curve(acc.allan_curve(), overlapping_allan_deviation(s.outputs, rate_of(s)), 1e-10);
  expect_blocks(acc, s);
  // The noise model: the batch fit on the stored samples (today's path), to rounding.
  const std::optional<NoiseModel> streamed = acc.noise_model();
  ASSERT_TRUE(streamed.has_value());
  expect_same_model(*streamed, estimate_noise_model(s.outputs, rate_of(s)));
  EXPECT_EQ(streamed->rest_blocks.size(), static_cast<std::size_t>(kRestBlocks));
}

INSTANTIATE_TEST_SUITE_P(Rates, RestAccumulatorAtRate, ::testing::Values(100.0, 1000.0, 10000.0));

// A 120 s rest at 50 kHz (6 M samples, six times what the recorder kept until issue 38): its
// second half is three times as noisy and drifts. The model sees all of it: the white std is the
// pooled one of both halves (sqrt(5) x the first half's; the first 20 s alone would give 1 x),
// the blocks reach the last stamp, and the memory is what it was after 20 s.
TEST(RestAccumulator, A120sRestAt50kHzIsUsedWhole) {
  const double rate = 50000.0, sigma = 0.01;
  std::mt19937_64 rng(50);
  std::normal_distribution<double> normal(0.0, 1.0);
  RestAccumulator acc;
  std::size_t memory_at_20s = 0;
  const std::size_t n = static_cast<std::size_t>(120.0 * rate);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / rate;
    const bool second_half = t >= 60.0;
    const double s = second_half ? 3.0 * sigma : sigma;
    const double drift = second_half ? 1e-3 * (t - 60.0) : 0.0;
    acc.add(t, Eigen::Vector3d(s * normal(rng) + drift, s * normal(rng), 9.81 + s * normal(rng)));
    if (i + 1 == static_cast<std::size_t>(20.0 * rate)) memory_at_20s = acc.memory_bytes();
  }
  EXPECT_EQ(acc.samples(), n);
  const std::optional<NoiseModel> m = acc.noise_model();
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->rest_samples, n);
  // Pooled white std of the two halves: sigma sqrt((1 + 9) / 2).
  for (int a = 1; a < 3; ++a)
    EXPECT_NEAR(m->axes[a].white_std, sigma * std::sqrt(5.0), 0.05 * sigma * std::sqrt(5.0)) << a;
  ASSERT_EQ(m->rest_blocks.size(), static_cast<std::size_t>(kRestBlocks));
  EXPECT_NEAR(m->rest_blocks.back().t_end_s, (n - 1) / rate, 1e-9);
  // The last block: the drift's level at 116..120 s and the second half's scatter.
  EXPECT_NEAR(m->rest_blocks.back().mean(0), 1e-3 * 58.0, 1e-3);
  EXPECT_NEAR(m->rest_blocks.back().std(1), 3.0 * sigma, 0.1 * sigma);
  EXPECT_NEAR(m->rest_blocks.front().std(1), sigma, 0.05 * sigma);
  // Memory: under 1 MB, and no more after 120 s than after 20 s but for the Allan cluster sizes
  // opened in between (a few kB).
  EXPECT_LT(acc.memory_bytes(), std::size_t{1} << 20);
  EXPECT_LT(acc.memory_bytes(), memory_at_20s + 16384);
}

// imu_tk's real Xsens session (raw counts near 33000, 100 Hz, a 51 s first rest), its rests found
// as offline_fit finds them: the streamed model is the batch one on the stored samples.
TEST(RestAccumulator, XsensSessionModelIsTheBatchOne) {
  const std::vector<ImuSample> samples =
      read_samples_file(test_support::source_dir() + "/test/data/imu_tk_xsens/xsens_acc.mat");
  RestDetectionOptions options;
  options.min_rest_s = 2.0;  // offline_fit's --rest-min-s default
  PositionTable table;
  table.rows = detect_rests(samples, options).rests;
  const std::optional<LongRest> rest = find_long_rest(table);
  ASSERT_TRUE(rest.has_value());
  Stream s;
  for (const ImuSample& x : samples) {
    if (x.stamp_s < rest->t_start_s || x.stamp_s > rest->t_end_s) continue;
    s.stamps.push_back(x.stamp_s);
    s.outputs.push_back(x.outputs);
  }
  ASSERT_GT(s.stamps.size(), 3000u);
  const RestAccumulator acc = accumulate(s);
  expect_same_curve(acc.allan_curve(), overlapping_allan_deviation(s.outputs, rate_of(s)), 1e-10);
  const std::optional<NoiseModel> streamed = acc.noise_model();
  ASSERT_TRUE(streamed.has_value());
  expect_same_model(*streamed, estimate_noise_model(s.outputs, rate_of(s)));
  expect_blocks(acc, s);
  // noise_model_of_run (offline_fit's call) is the accumulator's model with the rest's source.
  std::vector<double> stamps;
  std::vector<Eigen::Vector3d> outputs;
  for (const ImuSample& x : samples) {
    stamps.push_back(x.stamp_s);
    outputs.push_back(x.outputs);
  }
  const std::optional<NoiseModel> run = noise_model_of_run(table, stamps, outputs);
  ASSERT_TRUE(run.has_value());
  EXPECT_EQ(run->source, rest->reason);
  EXPECT_EQ(run->rest_samples, streamed->rest_samples);
  for (int a = 0; a < 3; ++a) EXPECT_EQ(run->axes[a].white_std, streamed->axes[a].white_std);
  ASSERT_EQ(run->rest_blocks.size(), streamed->rest_blocks.size());
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
