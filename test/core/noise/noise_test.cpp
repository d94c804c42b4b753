// Noise figures (core/noise.h): white noise from dwells, the overlapping Allan deviation against
// a loop over clusters written out here, and N, B, K recovered from simulated static records
// whose white noise, random walk and bias instability (a sum of Gauss-Markov processes with
// correlation times spread over 2.5 decades: a flat Allan floor) are known.
#include "accel_intrinsics/core/noise/noise.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "../../support/statistical_bounds.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

// Allan variance of a first-order Gauss-Markov process of variance s2 and correlation time T
// (IEEE Std 952 / El-Sheimy et al. 2008).
double markov_avar(double s2, double T, double tau) {
  const double x = tau / T;
  return s2 * T * T / (tau * tau) * (2.0 * x - 3.0 + 4.0 * std::exp(-x) - std::exp(-2.0 * x));
}

struct Record {
  std::vector<Eigen::Vector3d> samples;
  double rate_hz = 10.0;
  Eigen::Vector3d white = Eigen::Vector3d::Zero();  // N per axis
  Eigen::Vector3d walk = Eigen::Vector3d::Zero();   // K per axis
  double flicker_floor = 0.0;                       // adev floor of the Markov sum (axis u)
};

// u: white + bias instability + random walk; v: white only; w: white + random walk.
Record make_record(std::size_t n, std::uint64_t seed) {
  Record r;
  r.samples.assign(n, Eigen::Vector3d::Zero());
  r.white = Eigen::Vector3d(0.002, 0.003, 0.002);
  r.walk = Eigen::Vector3d(1e-4, 0.0, 1e-4);
  const double dt = 1.0 / r.rate_hz;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  // Markov sum: correlation times 1 .. 316 s, equal variances, scaled so that its Allan
  // deviation peaks at 1e-3 m/s^2.
  std::vector<double> T;
  for (int i = 0; i < 6; ++i) T.push_back(std::pow(10.0, 0.5 * i));
  double peak = 0.0;
  for (double lt = -1.0; lt <= 4.5; lt += 0.01) {
    double s = 0.0;
    for (double t : T) s += markov_avar(1.0, t, std::pow(10.0, lt));
    peak = std::max(peak, s);
  }
  r.flicker_floor = 1e-3;
  const double s2 = r.flicker_floor * r.flicker_floor / peak;
  std::vector<double> state(T.size());
  for (double& v : state) v = std::sqrt(s2) * normal(rng);
  Eigen::Vector3d walk = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) r.samples[i](a) = r.white(a) * std::sqrt(r.rate_hz) * normal(rng);
    for (int a : {0, 2}) {
      walk(a) += r.walk(a) * std::sqrt(dt) * normal(rng);
      r.samples[i](a) += walk(a);
    }
    for (std::size_t j = 0; j < T.size(); ++j) {
      const double phi = std::exp(-dt / T[j]);
      state[j] = phi * state[j] + std::sqrt(s2 * (1.0 - phi * phi)) * normal(rng);
      r.samples[i](0) += state[j];
    }
    r.samples[i] += Eigen::Vector3d(0.1, -9.8, 0.05);  // static outputs
  }
  return r;
}

// The Allan variance written as its definition: a loop over every overlapping pair of clusters.
double allan_by_clusters(const std::vector<double>& x, std::size_t m, double rate) {
  const std::size_t n = x.size();
  double sum = 0.0;
  std::size_t terms = 0;
  for (std::size_t k = 0; k + 2 * m <= n; ++k) {
    double first = 0.0, second = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      first += x[k + i];
      second += x[k + m + i];
    }
    const double diff = (second - first) / static_cast<double>(m);
    sum += diff * diff;
    ++terms;
  }
  (void)rate;
  return std::sqrt(0.5 * sum / static_cast<double>(terms));
}

TEST(Allan, CumulativeSumsEqualTheClusterLoop) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal(0.0, 0.01);
  std::vector<double> x(3000);
  double walk = 0.0;
  for (double& v : x) {
    walk += 1e-4 * normal(rng);
    v = 9.8 + normal(rng) + walk;
  }
  const std::vector<std::size_t> sizes = {1, 2, 3, 7, 16, 40, 300, 700};
  // Every-sample cluster starts (stride divisor larger than any m).
  const std::vector<double> adev = overlapping_allan_deviation(x, 100.0, sizes, 1u << 30);
  for (std::size_t j = 0; j < sizes.size(); ++j) {
    EXPECT_NEAR(adev[j], allan_by_clusters(x, sizes[j], 100.0), 1e-9 * adev[j]) << sizes[j];
  }
}

TEST(Allan, StrideKeepsThePrecision) {
  const Record r = make_record(200000, 3);
  std::vector<double> x(r.samples.size());
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = r.samples[i](1);
  std::vector<std::size_t> sizes;
  for (std::size_t m = 20; m <= 50000; m *= 2) sizes.push_back(m);
  const std::vector<double> strided = overlapping_allan_deviation(x, r.rate_hz, sizes);
  const std::vector<double> full = overlapping_allan_deviation(x, r.rate_hz, sizes, 1u << 30);
  for (std::size_t j = 0; j < sizes.size(); ++j) {
    EXPECT_NEAR(strided[j], full[j], 0.02 * full[j]) << "m = " << sizes[j];
  }
}

TEST(Allan, WhiteNoiseFollowsTheLineWithinItsUncertainty) {
  const Record r = make_record(100000, 4);
  const AllanCurve curve = overlapping_allan_deviation(r.samples, r.rate_hz);
  ASSERT_GT(curve.tau_s.size(), 30u);
  EXPECT_DOUBLE_EQ(curve.tau_s.front(), 0.1);
  EXPECT_LE(curve.tau_s.back(), 100000 / 4 / r.rate_hz);
  // k std at every tau, the 1e-3 split over the taus (3 std at each of ~40 taus would fail a
  // correct estimator in several % of seeds).
  const double k = statistical_bounds::normal_k(1e-3 / static_cast<double>(curve.tau_s.size()));
  for (std::size_t i = 0; i < curve.tau_s.size(); ++i) {
    const double expected = r.white(1) / std::sqrt(curve.tau_s[i]);
    EXPECT_NEAR(curve.adev[i](1), expected, k * curve.relative_std[i] * expected)
        << "tau " << curve.tau_s[i];
  }
}

class NoiseParametersTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    record_ = new Record(make_record(2000000, 11));
    curve_ = new AllanCurve(overlapping_allan_deviation(record_->samples, record_->rate_hz));
  }
  static void TearDownTestSuite() {
    delete record_;
    delete curve_;
  }
  static Record* record_;
  static AllanCurve* curve_;
};
Record* NoiseParametersTest::record_ = nullptr;
AllanCurve* NoiseParametersTest::curve_ = nullptr;

TEST_F(NoiseParametersTest, WhiteNoiseDensityWithin5Percent) {
  for (int a = 0; a < 3; ++a) {
    const NoiseParameters p = noise_parameters(*curve_, a);
    EXPECT_NEAR(p.white_density, record_->white(a), 0.05 * record_->white(a)) << "axis " << a;
    EXPECT_GT(p.white_points, 0) << "read on the -1/2 line, axis " << a;
    EXPECT_GT(p.white_density_std, 0.0);
    EXPECT_LT(p.white_density_std, 0.05 * p.white_density);
  }
}

TEST_F(NoiseParametersTest, RandomWalkWithin30Percent) {
  for (int a : {0, 2}) {
    const NoiseParameters p = noise_parameters(*curve_, a);
    EXPECT_NEAR(p.random_walk, record_->walk(a), 0.3 * record_->walk(a)) << "axis " << a;
    EXPECT_GT(p.random_walk_points, 0) << "read on the +1/2 line, axis " << a;
    EXPECT_GT(p.random_walk_std, 0.0);
  }
}

TEST_F(NoiseParametersTest, BiasInstabilityWithinFactor1Point5) {
  const NoiseParameters p = noise_parameters(*curve_, 0);
  const double truth = record_->flicker_floor / kBiasInstabilityFloor;
  EXPECT_GT(p.bias_instability, truth / 1.5);
  EXPECT_LT(p.bias_instability, truth * 1.5);
  // Its tau lies between the white-noise and the random-walk crossings of the floor.
  EXPECT_TRUE(p.bias_instability_floor_seen);
  EXPECT_GT(p.bias_instability_tau_s, 4.0);
  EXPECT_LT(p.bias_instability_tau_s, 300.0);
}

TEST_F(NoiseParametersTest, PureWhiteNoiseShowsNoRandomWalkAboveItsUncertainty) {
  const NoiseParameters p = noise_parameters(*curve_, 1);
  EXPECT_EQ(p.random_walk_points, 0);
  EXPECT_FALSE(p.bias_instability_floor_seen);
  EXPECT_LE(p.random_walk, p.random_walk_std);
  // ... and that uncertainty is far below the random walk of the other axes: it would be seen.
  EXPECT_LT(p.random_walk_std, 0.3 * record_->walk(0));
}

// The axis is an index into three-vectors: 0, 1 and 2 are read, anything else is refused rather
// than read past the end (mutation sample, issue 37).
TEST_F(NoiseParametersTest, RefusesAnAxisOutsideZeroToTwo) {
  EXPECT_THROW(noise_parameters(*curve_, 3), std::invalid_argument);
  EXPECT_THROW(noise_parameters(*curve_, -1), std::invalid_argument);
  EXPECT_NO_THROW(noise_parameters(*curve_, 0));
  EXPECT_NO_THROW(noise_parameters(*curve_, 2));
}

TEST(DwellNoise, DensityFromSimulatedDwells) {
  SimulationOptions sim;
  sim.rate_hz = 200.0;
  sim.noise_density = 150e-6 * kStandardGravity;
  const PositionTable table = simulate_position_table(sim);
  const std::optional<DwellNoise> noise = dwell_noise(table);
  ASSERT_TRUE(noise.has_value());
  EXPECT_NEAR(noise->rate_hz, sim.rate_hz, 0.01 * sim.rate_hz);
  // The simulator's density is the one-sided one: sample std = density sqrt(rate / 2).
  const double expected = sample_noise_std(sim) / std::sqrt(sim.rate_hz);
  EXPECT_NEAR(expected, sim.noise_density / std::sqrt(2.0), 1e-12);
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(noise->density(a), expected, 4.0 * noise->density_std(a)) << a;
    EXPECT_NEAR(noise->sample_std(a), sample_noise_std(sim), 0.02 * sample_noise_std(sim));
  }
  EXPECT_FALSE(dwell_noise(PositionTable{}).has_value());
}

// The density's standard uncertainty against a Monte Carlo of the estimator's spread: 400 runs
// of the simulated stand (another seed each), the standard deviation of the density estimates
// (n - 1) beside the mean of the uncertainty each run states. 400 runs resolve the spread to
// 3.5 %; a factor sqrt(2) either way is 40 %.
TEST(DwellNoise, DensityUncertaintyIsTheSpreadOfTheEstimate) {
  SimulationOptions sim;
  sim.rate_hz = 200.0;
  sim.noise_density = 150e-6 * kStandardGravity;
  const int runs = 400;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero(), sum_sq = Eigen::Vector3d::Zero();
  Eigen::Vector3d stated = Eigen::Vector3d::Zero();
  for (int k = 0; k < runs; ++k) {
    sim.seed = 1000 + static_cast<std::uint64_t>(k);
    const std::optional<DwellNoise> noise = dwell_noise(simulate_position_table(sim));
    ASSERT_TRUE(noise.has_value());
    sum += noise->density;
    sum_sq += noise->density.cwiseAbs2();
    stated += noise->density_std;
  }
  for (int a = 0; a < 3; ++a) {
    const double mean = sum(a) / runs;
    const double spread = std::sqrt((sum_sq(a) - runs * mean * mean) / (runs - 1));
    EXPECT_NEAR(stated(a) / runs / spread, 1.0, 0.15) << "axis " << a;
  }
}

// The model's Allan variance of a Gauss-Markov part scales with its variance gm_sigma^2: the
// textbook curve sigma^2 (2x - 3 + 4 e^-x - e^-2x) / x^2 at x = T / tau, written out here.
TEST(Allan, ModelGaussMarkovCurveScalesWithItsVariance) {
  NoiseModel m;
  m.rate_hz = 100.0;
  m.axes[1].gm_sigma = 0.02;
  m.axes[1].gm_tau_s = 10.0;
  for (double T : {1.0, 10.0, 100.0}) {
    const double x = T / 10.0;
    const double want =
        0.02 * 0.02 * (2.0 * x - 3.0 + 4.0 * std::exp(-x) - std::exp(-2.0 * x)) / (x * x);
    EXPECT_NEAR(m.allan_variance(1, T), want, 1e-6 * want) << T;
  }
}

// kind() names the slow parts any axis has (reports and the noise-model file show it): a random
// walk on one axis alone, or next to a Gauss-Markov part on another, must be named.
TEST(NoiseModelKind, NamesTheSlowPartsOfAnyAxis) {
  NoiseModel m;
  m.axes[0].white_std = 1e-3;
  EXPECT_EQ(m.kind(), "white");
  m.axes[2].rw_density = 1e-4;
  EXPECT_EQ(m.kind(), "random_walk");
  m.axes[1].gm_sigma = 1e-3;
  m.axes[1].gm_tau_s = 20.0;
  EXPECT_EQ(m.kind(), "gauss_markov+random_walk");
  m.axes[2].rw_density = 0.0;
  EXPECT_EQ(m.kind(), "gauss_markov");
}

TEST(Allan, RefusesTooShortRecords) {
  EXPECT_THROW(overlapping_allan_deviation(std::vector<Eigen::Vector3d>(10), 100.0),
               std::invalid_argument);
  EXPECT_THROW(overlapping_allan_deviation(std::vector<Eigen::Vector3d>(100), 0.0),
               std::invalid_argument);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
