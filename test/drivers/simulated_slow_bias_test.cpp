// The stand's simulated accelerometer with a slow bias (docs/design.md section 12): its parameters
// are checked as ROS parameters name them, each sample carries the one slow-bias process at its
// time, and a random walk's increments have the variance the configured density says.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/drivers/accelerometer_source.h"

namespace accel_intrinsics {
namespace {

OrientationProvider z_up() {
  return [](double, Eigen::Matrix3d* R) {
    *R = Eigen::Matrix3d::Identity();  // f = (0, 0, g)
    return OrientationStatus::Available;
  };
}

// Samples from t = 0 to until_s (a poll hands out at most 10 s of samples).
std::vector<core::ImuSample> samples_until(SimulatedAccelerometer* sensor, double until_s) {
  std::vector<core::ImuSample> samples;
  for (double t = 0.0; t <= until_s + 1e-9; t += 1.0) sensor->poll(t, &samples);
  return samples;
}

std::string rejection(const SimulatedAccelerometerOptions& o) {
  try {
    o.validate();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(SimulatedSlowBias, BadParametersAreRejectedByTheirParameterNames) {
  SimulatedAccelerometerOptions o;
  o.bias_random_walk = -1e-4;
  EXPECT_NE(rejection(o).find("bias/random_walk must be finite and >= 0"), std::string::npos)
      << rejection(o);
  o.bias_random_walk = 0.0;
  o.bias_gm_tau_s = std::nan("");
  EXPECT_NE(rejection(o).find("bias/gm_tau_s"), std::string::npos) << rejection(o);
  o.bias_gm_tau_s = 0.0;
  o.bias_gm_sigma = 1e-3;
  EXPECT_EQ(rejection(o), "bias/gm_sigma needs a positive bias/gm_tau_s");
  o.bias_gm_tau_s = 30.0;
  EXPECT_EQ(rejection(o), "");
}

TEST(SimulatedSlowBias, EachSampleCarriesTheProcessAtItsTime) {
  SimulatedAccelerometerOptions o;
  o.noise_density = 0.0;
  o.rate_hz = 50.0;
  o.seed = 7;
  o.bias_gm_sigma = 2e-3;
  o.bias_gm_tau_s = 5.0;
  o.bias_random_walk = 1e-4;
  SimulatedAccelerometer sensor(o, z_up());
  const std::vector<core::ImuSample> samples = samples_until(&sensor, 20.0);
  ASSERT_EQ(samples.size(), 1001u);
  // The same process drawn here, sample by sample; the device is the identity with zero offset,
  // so what is left after the true outputs is the bias alone.
  core::SlowBiasProcess expected(o.bias_gm_sigma, o.bias_gm_tau_s, o.bias_random_walk, o.seed);
  const Eigen::Vector3d truth(0.0, 0.0, o.local_gravity);
  double largest = 0.0;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const Eigen::Vector3d b = k == 0 ? expected.value() : expected.advance(1.0 / o.rate_hz);
    const Eigen::Vector3d bias = samples[k].outputs - truth;
    EXPECT_LT((bias - b).norm(), 1e-12) << "sample " << k;
    largest = std::max(largest, bias.cwiseAbs().maxCoeff());
  }
  EXPECT_GT(largest, 1e-4);  // the bias is there at all (about 2e-3 expected)
}

TEST(SimulatedSlowBias, RandomWalkIncrementsHaveTheConfiguredVariance) {
  SimulatedAccelerometerOptions o;
  o.noise_density = 0.0;
  o.rate_hz = 20.0;
  o.bias_random_walk = 3e-4;  // (m/s^2)/sqrt(s)
  SimulatedAccelerometer sensor(o, z_up());
  const std::vector<core::ImuSample> samples = samples_until(&sensor, 400.0);
  const Eigen::Vector3d truth(0.0, 0.0, o.local_gravity);
  // Increments over 1 s (20 samples): variance random_walk^2 * 1 s, independent across seconds
  // and axes: 1200 of them; their sample variance has a relative standard deviation of
  // sqrt(2 / 1200) = 4 %, so 20 % is more than 4 sigma.
  double sum_sq = 0.0;
  int n = 0;
  for (std::size_t k = 20; k < samples.size(); k += 20) {
    const Eigen::Vector3d d = (samples[k].outputs - truth) - (samples[k - 20].outputs - truth);
    sum_sq += d.squaredNorm();
    n += 3;
  }
  ASSERT_GE(n, 1197);
  EXPECT_NEAR(sum_sq / n / (o.bias_random_walk * o.bias_random_walk), 1.0, 0.2);
}

}  // namespace
}  // namespace accel_intrinsics
