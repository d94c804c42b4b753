// best_slow_amplitude (slow_part_fit.h) against a posterior worked out in closed form here.
#include "accel_intrinsics/core/noise/slow_part_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>

namespace accel_intrinsics {
namespace core {
namespace {

// The amplitude's posterior mean and relative variance are what the slow part's scale and its
// uncertainty (slow_scale_rel_var) rest on: pin both against an exact posterior. With M = I
// (n components) and every w_i^2 = 3, B + a M = (1 + a) I and, with v = 1 + a, the restricted
// likelihood is v^(-n/2) exp(-3n / (2 v)) and Jeffreys' prior sqrt(I(a)) = sqrt(n / 2) / v: the
// posterior of v is inverse-gamma with shape alpha = n/2 and scale beta = 3n/2 (its mass below
// v = 1, a < 0, is negligible for n = 100), so E[a] = beta / (alpha - 1) - 1 and
// var(a) = beta^2 / ((alpha - 1)^2 (alpha - 2)).
TEST(SlowAmplitude, PosteriorMeanAndRelativeVarianceOfAnInverseGammaCase) {
  const int n = 100;
  const Eigen::VectorXd w = Eigen::VectorXd::Constant(n, std::sqrt(3.0));
  const Eigen::MatrixXd M = Eigen::MatrixXd::Identity(n, n);
  const SlowAmplitude fit = best_slow_amplitude(w, M);
  const double alpha = 0.5 * n, beta = 1.5 * n;
  const double mean = beta / (alpha - 1.0) - 1.0;  // 2.0612
  const double variance = beta * beta / ((alpha - 1.0) * (alpha - 1.0) * (alpha - 2.0));
  EXPECT_NEAR(fit.amplitude, mean, 1e-3 * mean);
  EXPECT_NEAR(fit.relative_variance, variance / (mean * mean), 1e-3 * variance / (mean * mean));
  // The likelihood's maximum over a >= 0 is at v = 3 (a = 2), up to the grid's spacing.
  const double at_max = -0.5 * n * (std::log(3.0) + 1.0);
  EXPECT_NEAR(fit.log_likelihood, at_max, 0.1);
  EXPECT_LE(fit.log_likelihood, at_max);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
