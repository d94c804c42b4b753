// Monte Carlo check of the reported uncertainties: over many simulated runs of one device, the
// scatter of |u|, |v|, |w| and of the three angles must match (a) the standard uncertainties the
// fit reports, within 10 %, and (b) for the joint model, the Cramer-Rao bound computed from the
// Fisher information with the true noise, within 5 %.
//
// Statistical resolution: the relative standard error of a standard deviation estimated from M
// samples is 1 / sqrt(2 (M - 1)); with M = 5000 that is 1.0 %, so the 5 % criterion sits at
// five of those and a fit 5 % less efficient than the bound would be caught. (A linear fit of
// 72 dwells takes microseconds: 5000 runs of both models take well under a second.)
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/intrinsics.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

constexpr int kRuns = 5000;

SimulationOptions monte_carlo_setup() {
  SimulationOptions sim;
  sim.truth.S << 1.021, 0.013, -0.009,  //
      -0.017, 0.987, 0.021,             //
      0.008, -0.014, 1.012;
  sim.truth.O << 0.12, -0.31, 0.05;
  sim.protocol.steps_per_phase = 24;
  return sim;  // default noise density and rate
}

// Cramer-Rao bound of the joint model: for dwell means with true standard error
// sigma / sqrt(n) the Fisher information of accelerometer s is sum_rows h h^T / se^2 with
// h = (g f, 1); its inverse, propagated through the intrinsics Jacobian at the truth.
Eigen::Matrix<double, 6, 6> joint_cramer_rao(const SimulationOptions& sim,
                                             const PositionTable& table) {
  const double sigma = sample_noise_std(sim);
  Eigen::Matrix4d F = Eigen::Matrix4d::Zero();  // identical for u, v, w (same noise)
  for (const DwellRecord& row : table.rows) {
    const Eigen::Vector3d f = in_plane_direction(row.phase, row.angle_rad) * sim.local_gravity;
    const Eigen::Vector4d h(f(0), f(1), f(2), 1.0);
    F += h * h.transpose() * (static_cast<double>(row.n) / (sigma * sigma));
  }
  const Eigen::Matrix4d C = F.inverse();
  Eigen::Matrix<double, 9, 9> cov_S = Eigen::Matrix<double, 9, 9>::Zero();
  for (int s = 0; s < 3; ++s) cov_S.block<3, 3>(3 * s, 3 * s) = C.topLeftCorner<3, 3>();
  const Eigen::Matrix<double, 6, 9> J = intrinsics_jacobian(sim.truth.S);
  return J * cov_S * J.transpose();
}

struct Scatter {
  Eigen::Matrix<double, 6, 1> sum = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix<double, 6, 1> sum_sq = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix<double, 6, 1> reported = Eigen::Matrix<double, 6, 1>::Zero();
  int n = 0;
  Eigen::Matrix<double, 6, 1> truth;

  void add(const Intrinsics& in) {
    Eigen::Matrix<double, 6, 1> x, sd;
    x << in.responsivity, in.angles_rad;
    sd << in.responsivity_std, in.angles_std_rad;
    const Eigen::Matrix<double, 6, 1> d = x - truth;  // deviations from the truth: no offset loss
    sum += d;
    sum_sq += d.cwiseProduct(d);
    reported += sd;
    ++n;
  }
  Eigen::Matrix<double, 6, 1> std_dev() const {
    const Eigen::Matrix<double, 6, 1> mean = sum / n;
    return ((sum_sq - n * mean.cwiseProduct(mean)) / (n - 1)).cwiseSqrt();
  }
  Eigen::Matrix<double, 6, 1> mean_reported() const { return reported / n; }
};

const char* const kQuantity[6] = {"|u|", "|v|", "|w|", "theta_uv", "theta_vw", "theta_wu"};

TEST(MonteCarlo, ScatterMatchesReportedUncertaintyAndCramerRao) {
  SimulationOptions sim = monte_carlo_setup();
  const Intrinsics truth = intrinsics_from_vectors(sim.truth.S);
  Scatter joint, eq4;
  joint.truth << truth.responsivity, truth.angles_rad;
  eq4.truth = joint.truth;
  Eigen::Matrix<double, 6, 6> crb = Eigen::Matrix<double, 6, 6>::Zero();
  FitOptions eq4_options;
  eq4_options.model = FitModel::Eq4;
  for (int run = 0; run < kRuns; ++run) {
    sim.seed = 1000 + run;
    const PositionTable table = simulate_position_table(sim);
    if (run == 0) crb = joint_cramer_rao(sim, table);
    joint.add(fit(table).intrinsics);
    eq4.add(fit(table, eq4_options).intrinsics);
  }
  const Eigen::Matrix<double, 6, 1> bound = crb.diagonal().cwiseSqrt();
  std::printf("%-9s %12s %12s %12s %12s %12s\n", "quantity", "joint sd", "reported", "CRB",
              "eq4 sd", "eq4 reported");
  for (int i = 0; i < 6; ++i)
    std::printf("%-9s %12.4g %12.4g %12.4g %12.4g %12.4g\n", kQuantity[i], joint.std_dev()(i),
                joint.mean_reported()(i), bound(i), eq4.std_dev()(i), eq4.mean_reported()(i));
  for (int i = 0; i < 6; ++i) {
    SCOPED_TRACE(kQuantity[i]);
    const double scatter = joint.std_dev()(i);
    EXPECT_NEAR(scatter / joint.mean_reported()(i), 1.0, 0.10)
        << "joint scatter " << scatter << " reported " << joint.mean_reported()(i);
    EXPECT_NEAR(scatter / bound(i), 1.0, 0.05)
        << "joint scatter " << scatter << " CRB " << bound(i);
    EXPECT_NEAR(eq4.std_dev()(i) / eq4.mean_reported()(i), 1.0, 0.10)
        << "eq4 scatter " << eq4.std_dev()(i) << " reported " << eq4.mean_reported()(i);
    // No estimator beats the bound (beyond the Monte Carlo resolution).
    EXPECT_GT(eq4.std_dev()(i) / bound(i), 0.95);
    // Unbiased to well within the scatter.
    EXPECT_LT(std::abs(joint.sum(i) / kRuns), 4.0 * scatter / std::sqrt(kRuns));
  }
}

// The same check for a fit with an effect term through Ceres (fewer runs: it is slower).
TEST(MonteCarlo, EffectFitUncertaintyMatchesScatter) {
  constexpr int kEffectRuns = 1000;
  SimulationOptions sim = monte_carlo_setup();
  sim.truth.effects = {make_effect("quadratic_nonlinearity", "u", 2e-4)};
  FitOptions opt;
  opt.effects = {make_effect("quadratic_nonlinearity", "u", 0.0)};
  double sum = 0.0, sum_sq = 0.0, reported = 0.0;
  for (int run = 0; run < kEffectRuns; ++run) {
    sim.seed = 5000 + run;
    const FitResult r = fit(simulate_position_table(sim), opt);
    const double d = r.effects[0].value - 2e-4;
    sum += d;
    sum_sq += d * d;
    reported += r.effects_std[0];
  }
  const double mean = sum / kEffectRuns;
  const double scatter = std::sqrt((sum_sq - kEffectRuns * mean * mean) / (kEffectRuns - 1));
  // Resolution 1 / sqrt(2 * 999) = 2.2 %: allow 10 %.
  std::printf("K2 scatter %.4g reported %.4g\n", scatter, reported / kEffectRuns);
  EXPECT_NEAR(scatter / (reported / kEffectRuns), 1.0, 0.10);
  EXPECT_LT(std::abs(mean), 4.0 * scatter / std::sqrt(kEffectRuns));
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
