// Tests of the intrinsic parameters (docs/design.md section 1), their GUM propagation, the
// conversion from a measured cross-sensitivity matrix, and the mounting invariance of fitted
// intrinsics.
#include "accel_intrinsics/core/model/intrinsics.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "../../support/statistical_bounds.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

using Matrix9d = Eigen::Matrix<double, 9, 9>;

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  return q.toRotationMatrix();
}

Device triad_near_identity(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> scale(-0.03, 0.03);
  std::normal_distribution<double> misalign(0.0, deg_to_rad(1.0));
  std::uniform_real_distribution<double> offset(-0.4, 0.4);
  Device d;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) d.S(i, j) = i == j ? 1.0 + scale(rng) : misalign(rng);
    d.O(i) = offset(rng);
  }
  return d;
}

Matrix9d random_covariance(std::mt19937_64& rng, double scale) {
  std::normal_distribution<double> n(0.0, scale);
  Eigen::Matrix<double, 9, 12> A;
  for (int i = 0; i < 9; ++i)
    for (int j = 0; j < 12; ++j) A(i, j) = n(rng);
  return A * A.transpose();
}

TEST(Intrinsics, OrthonormalTriad) {
  const Intrinsics in = intrinsics_from_vectors(Eigen::Matrix3d::Identity());
  for (int i = 0; i < 3; ++i) {
    EXPECT_DOUBLE_EQ(in.responsivity(i), 1.0);
    EXPECT_NEAR(in.angles_rad(i), kPi / 2, 1e-15);
    EXPECT_EQ(in.responsivity_std(i), 0.0);
  }
}

TEST(Intrinsics, KnownVectors) {
  Eigen::Matrix3d S;
  const double a = deg_to_rad(80.0);
  S.row(0) = Eigen::Vector3d(2.0, 0.0, 0.0).transpose();
  S.row(1) = 1.5 * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0).transpose();
  S.row(2) = 0.5 * Eigen::Vector3d(0.0, 0.0, 1.0).transpose();
  const Intrinsics in = intrinsics_from_vectors(S);
  EXPECT_NEAR(in.responsivity(0), 2.0, 1e-15);
  EXPECT_NEAR(in.responsivity(1), 1.5, 1e-15);
  EXPECT_NEAR(in.responsivity(2), 0.5, 1e-15);
  EXPECT_NEAR(in.angles_rad(0), a, 1e-15);        // uv
  EXPECT_NEAR(in.angles_rad(1), kPi / 2, 1e-15);  // vw
  EXPECT_NEAR(in.angles_rad(2), kPi / 2, 1e-15);  // wu
}

TEST(Intrinsics, JacobianMatchesCentralDifferences) {
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::Matrix3d S = triad_near_identity(rng).S;
    if (trial == 4) S.row(1) = S.row(0) * 0.7 + S.row(1) * 0.01;  // nearly parallel u, v
    const Eigen::Matrix<double, 6, 9> J = intrinsics_jacobian(S);
    for (int k = 0; k < 9; ++k) {
      const double h = 1e-6;
      Eigen::Matrix3d Sp = S, Sm = S;
      Sp(k / 3, k % 3) += h;
      Sm(k / 3, k % 3) -= h;
      const Intrinsics p = intrinsics_from_vectors(Sp), m = intrinsics_from_vectors(Sm);
      Eigen::Matrix<double, 6, 1> fd;
      fd << (p.responsivity - m.responsivity) / (2 * h), (p.angles_rad - m.angles_rad) / (2 * h);
      for (int i = 0; i < 6; ++i)
        EXPECT_NEAR(J(i, k), fd(i), 1e-7 * std::max(1.0, std::abs(fd(i))));
    }
  }
}

TEST(Intrinsics, PropagatesCovarianceLinearly) {
  std::mt19937_64 rng(6);
  const Eigen::Matrix3d S = triad_near_identity(rng).S;
  const Matrix9d cov = random_covariance(rng, 1e-4);
  const Intrinsics in = intrinsics_from_vectors(S, cov);
  const Eigen::Matrix<double, 6, 9> J = intrinsics_jacobian(S);
  const Eigen::Matrix<double, 6, 6> want = J * cov * J.transpose();
  EXPECT_LT((in.covariance - want).cwiseAbs().maxCoeff(), 1e-15);
  for (int i = 0; i < 3; ++i) {
    EXPECT_DOUBLE_EQ(in.responsivity_std(i), std::sqrt(in.covariance(i, i)));
    EXPECT_DOUBLE_EQ(in.angles_std_rad(i), std::sqrt(in.covariance(3 + i, 3 + i)));
  }
}

TEST(Intrinsics, ParallelAndAntiparallelVectorsGiveNoNaN) {
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  S.row(1) = 3.0 * S.row(0);  // theta_uv = 0
  Matrix9d cov = Matrix9d::Identity() * 1e-6;
  Intrinsics in = intrinsics_from_vectors(S, cov);
  EXPECT_TRUE(in.covariance.allFinite());
  EXPECT_EQ(in.angles_rad(0), 0.0);
  S.row(1) = -2.0 * S.row(0) + Eigen::RowVector3d(0, 1e-17, 0);  // theta_uv = pi to round-off
  in = intrinsics_from_vectors(S, cov);
  EXPECT_TRUE(in.covariance.allFinite());
  EXPECT_NEAR(in.angles_rad(0), kPi, 1e-15);
  // Tiny but resolvable angles keep full precision (arccos of a rounded cosine would not).
  S = Eigen::Matrix3d::Identity();
  S.row(1) = Eigen::RowVector3d(1.0, 1e-9, 0.0);
  in = intrinsics_from_vectors(S);
  EXPECT_NEAR(in.angles_rad(0), 1e-9, 1e-22);
}

TEST(Intrinsics, FromCrossSensitivityMatchesVectors) {
  std::mt19937_64 rng(8);
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::Matrix3d S = triad_near_identity(rng).S;
    const Matrix9d cov_S = random_covariance(rng, 1e-4);
    const Intrinsics direct = intrinsics_from_vectors(S, cov_S);
    // Propagate cov_S to P with a finite-difference Jacobian of the inverse (independent of the
    // analytic dP = -P dS P used by the code) and back through intrinsics_from_cross_sensitivity.
    const Eigen::Matrix3d P = S.inverse();
    Matrix9d Jp;
    for (int k = 0; k < 9; ++k) {
      const double h = 1e-7;
      Eigen::Matrix3d Sp = S, Sm = S;
      Sp(k / 3, k % 3) += h;
      Sm(k / 3, k % 3) -= h;
      const Eigen::Matrix3d d = (Sp.inverse() - Sm.inverse()) / (2 * h);
      for (int j = 0; j < 9; ++j) Jp(j, k) = d(j / 3, j % 3);
    }
    const Intrinsics via_p = intrinsics_from_cross_sensitivity(P, Jp * cov_S * Jp.transpose());
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(via_p.responsivity(i), direct.responsivity(i), 1e-13);
      EXPECT_NEAR(via_p.angles_rad(i), direct.angles_rad(i), 1e-13);
      EXPECT_NEAR(via_p.responsivity_std(i) / direct.responsivity_std(i), 1.0, 1e-6);
      EXPECT_NEAR(via_p.angles_std_rad(i) / direct.angles_std_rad(i), 1.0, 1e-6);
    }
  }
}

TEST(Intrinsics, SingularCrossSensitivityThrows) {
  Eigen::Matrix3d P = Eigen::Matrix3d::Identity();
  P.row(2) = P.row(0) + P.row(1);
  EXPECT_THROW(intrinsics_from_cross_sensitivity(P), std::invalid_argument);
  P = Eigen::Matrix3d::Identity();
  P(1, 1) = std::nan("");
  EXPECT_THROW(intrinsics_from_cross_sensitivity(P), std::invalid_argument);
  EXPECT_THROW(intrinsics_from_cross_sensitivity(Eigen::Matrix3d::Zero()), std::invalid_argument);
}

// ---- with the fit ------------------------------------------------------------------------

SimulationOptions mounted(const Device& triad, const Eigen::Matrix3d& R, double noise,
                          std::uint64_t seed) {
  SimulationOptions sim;
  sim.truth = triad;
  sim.truth.S = triad.S * R.transpose();  // same sensor, DUT frame rotated by R
  sim.noise_density = noise;
  sim.seed = seed;
  return sim;
}

TEST(Intrinsics, MountingInvarianceNoiseFree) {
  std::mt19937_64 rng(12);
  for (int trial = 0; trial < 6; ++trial) {
    const Device triad = triad_near_identity(rng);
    const Eigen::Matrix3d R = random_rotation(rng);
    for (FitModel model : {FitModel::Joint, FitModel::Eq4}) {
      SCOPED_TRACE(std::string(model_name(model)) + " trial " + std::to_string(trial));
      FitOptions opt;
      opt.model = model;
      const FitResult a =
          fit(simulate_position_table(mounted(triad, Eigen::Matrix3d::Identity(), 0, 1)), opt);
      const FitResult b = fit(simulate_position_table(mounted(triad, R, 0, 1)), opt);
      for (int i = 0; i < 3; ++i) {
        EXPECT_LT(std::abs(b.intrinsics.responsivity(i) / a.intrinsics.responsivity(i) - 1), 1e-9);
        EXPECT_LT(std::abs(b.intrinsics.angles_rad(i) / a.intrinsics.angles_rad(i) - 1), 1e-9);
      }
      EXPECT_GT((a.cross_sensitivity - b.cross_sensitivity).norm(), 0.1);
    }
  }
}

// The same triad in two mountings, 30 random triads and rotations: each intrinsic parameter's
// difference over the combined uncertainty is N(0, 1), so per model the count of the 180
// differences beyond 2 is binomial(180, 0.0455) (the six of a trial are nearly independent),
// bounded at the 1.25e-4 quantiles on both sides: < 1e-3 failures for a correct fit, any seeds.
TEST(Intrinsics, MountingInvarianceWithNoise) {
  namespace sb = statistical_bounds;
  std::mt19937_64 rng(13);
  const int trials = 30;
  int beyond_2[2] = {0, 0};
  for (int trial = 0; trial < trials; ++trial) {
    const Device triad = triad_near_identity(rng);
    const Eigen::Matrix3d R = random_rotation(rng);
    const double noise = SimulationOptions().noise_density;
    for (FitModel model : {FitModel::Joint, FitModel::Eq4}) {
      SCOPED_TRACE(std::string(model_name(model)) + " trial " + std::to_string(trial));
      FitOptions opt;
      opt.model = model;
      const FitResult a = fit(
          simulate_position_table(mounted(triad, Eigen::Matrix3d::Identity(), noise, 100 + trial)),
          opt);
      const FitResult b = fit(simulate_position_table(mounted(triad, R, noise, 200 + trial)), opt);
      for (int i = 0; i < 3; ++i) {
        const double sr =
            std::hypot(a.intrinsics.responsivity_std(i), b.intrinsics.responsivity_std(i));
        const double sa =
            std::hypot(a.intrinsics.angles_std_rad(i), b.intrinsics.angles_std_rad(i));
        EXPECT_GT(sr, 0.0);
        EXPECT_GT(sa, 0.0);
        const int m = model == FitModel::Joint ? 0 : 1;
        if (std::abs(a.intrinsics.responsivity(i) - b.intrinsics.responsivity(i)) > 2 * sr)
          ++beyond_2[m];
        if (std::abs(a.intrinsics.angles_rad(i) - b.intrinsics.angles_rad(i)) > 2 * sa)
          ++beyond_2[m];
      }
      // P changes by far more than its uncertainty.
      const Eigen::Matrix3d dP = a.cross_sensitivity - b.cross_sensitivity;
      const Eigen::Matrix3d sP =
          (a.cross_sensitivity_std.array().square() + b.cross_sensitivity_std.array().square())
              .sqrt()
              .matrix();
      EXPECT_GT(dP.cwiseQuotient(sP).cwiseAbs().maxCoeff(), 50.0);
    }
  }
  const double p2 = std::erfc(2.0 / std::sqrt(2.0));
  const int n = 6 * trials;
  const int lo = sb::binomial_lower(n, p2, 1.25e-4), hi = sb::binomial_upper(n, p2, 1.25e-4);
  for (int m = 0; m < 2; ++m) {
    std::printf("%s: %d of %d intrinsic differences beyond 2 std (bounds %d..%d)\n",
                m == 0 ? "joint" : "eq4", beyond_2[m], n, lo, hi);
    EXPECT_GE(beyond_2[m], lo);
    EXPECT_LE(beyond_2[m], hi);
  }
}

TEST(Intrinsics, FromFittedCrossSensitivityEqualFittedIntrinsics) {
  std::mt19937_64 rng(14);
  SimulationOptions sim;
  sim.truth = triad_near_identity(rng);
  sim.truth.S = sim.truth.S * random_rotation(rng).transpose();
  const PositionTable table = simulate_position_table(sim);
  for (FitModel model : {FitModel::Joint, FitModel::Eq4}) {
    SCOPED_TRACE(model_name(model));
    FitOptions opt;
    opt.model = model;
    const FitResult r = fit(table, opt);
    // Covariance of P from the fit's covariance of S: dP = -P dS P.
    const Eigen::Matrix3d& P = r.cross_sensitivity;
    Matrix9d J;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k)
          for (int l = 0; l < 3; ++l) J(3 * i + j, 3 * k + l) = -P(i, k) * P(l, j);
    const Matrix9d cov_S = r.covariance.topLeftCorner<9, 9>();
    const Matrix9d cov_P = J * cov_S * J.transpose();
    for (int k = 0; k < 9; ++k)
      EXPECT_NEAR(std::sqrt(cov_P(k, k)), r.cross_sensitivity_std(k / 3, k % 3), 1e-12);
    const Intrinsics from_p = intrinsics_from_cross_sensitivity(P, cov_P);
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(from_p.responsivity(i), r.intrinsics.responsivity(i), 1e-12);
      EXPECT_NEAR(from_p.angles_rad(i), r.intrinsics.angles_rad(i), 1e-12);
      EXPECT_NEAR(from_p.responsivity_std(i) / r.intrinsics.responsivity_std(i), 1.0, 1e-9);
      EXPECT_NEAR(from_p.angles_std_rad(i) / r.intrinsics.angles_std_rad(i), 1.0, 1e-9);
    }
  }
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
