// The joint fit with effect terms (the Ceres path, src/core/fit/effects_fit.cpp) is the weighted
// least-squares estimate, as the closed-form path without them is: for a term that is linear in
// its value (offset_drift) the estimate is computed here in closed form and the two must agree.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "../../support/written_runs.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/constants.h"

namespace accel_intrinsics {
namespace core {
namespace {

using written_runs::mid_time;
using written_runs::unit_force;

// A run written from eq. (4) with a drift of w, R = S g f(angle) + O + d_w (t - t0) e_w + noise
// (3 phases x 12 steps, dwells of 2 s from t0 = 0, equal standard errors): the fit with an
// offset_drift[w] term must land on the least-squares minimum to 1e-6 of each standard uncertainty
// (it does to round-off). A solver stopped by a loose tolerance (Ceres' default relative cost
// change of 1e-6) ends about 1e-3 of a standard uncertainty short of it on such a small term.
TEST(EffectsFit, DriftTermFitIsTheClosedFormLeastSquaresEstimate) {
  Eigen::Matrix3d S;
  S << 1.02, 0.011, -0.014, -0.008, 0.991, 0.017, 0.012, -0.006, 1.007;
  const Eigen::Vector3d O(0.08, -0.15, 0.11);
  const double g = kStandardGravity, sample_std = 0.02, drift = 1.5e-5;  // (m/s^2)/s
  const std::uint64_t n = 200;
  const double se = sample_std / std::sqrt(static_cast<double>(n));
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal(0.0, 1.0);
  PositionTable table = written_runs::three_phase_table(12, n, sample_std);
  table.time_origin_s = 0.0;
  for (DwellRecord& r : table.rows) {
    r.mean = S * (g * unit_force(r.phase, r.angle_rad)) + O +
             se * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    r.mean.z() += drift * mid_time(r);
  }
  FitOptions options;
  options.local_gravity = g;
  options.effects.push_back(Effect{EffectKind::OffsetDrift, 2, 0.0});
  const FitResult f = fit(table, options);
  ASSERT_EQ(f.effects.size(), 1u);

  // Closed form, one accelerometer at a time (equal weights): R_s on [g f, 1] (and t for w).
  const Eigen::Index rows = static_cast<Eigen::Index>(table.rows.size());
  for (int s = 0; s < 3; ++s) {
    const Eigen::Index cols = s == 2 ? 5 : 4;
    Eigen::MatrixXd X(rows, cols);
    Eigen::VectorXd y(rows);
    for (Eigen::Index i = 0; i < rows; ++i) {
      const DwellRecord& r = table.rows[static_cast<std::size_t>(i)];
      X.block<1, 3>(i, 0) = (g * unit_force(r.phase, r.angle_rad)).transpose();
      X(i, 3) = 1.0;
      if (s == 2) X(i, 4) = mid_time(r);
      y(i) = r.mean(s);
    }
    const Eigen::VectorXd b = X.colPivHouseholderQr().solve(y);
    for (int j = 0; j < 3; ++j) {
      const double std_s = std::sqrt(f.covariance(3 * s + j, 3 * s + j));
      EXPECT_NEAR(f.S(s, j), b(j), 1e-6 * std_s) << "S(" << s << ", " << j << ")";
    }
    EXPECT_NEAR(f.O(s), b(3), 1e-6 * f.O_std(s)) << "O(" << s << ")";
    if (s == 2) {
      EXPECT_NEAR(f.effects[0].value, b(4), 1e-6 * f.effects_std[0]) << "drift of w";
    }
  }
  // The drift is seen (about 2 standard uncertainties) and the estimate is near the truth.
  EXPECT_NEAR(f.effects[0].value, drift, 4.0 * f.effects_std[0]);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
