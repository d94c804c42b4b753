// Comparisons (comparison.h): E_n of two simulated runs of one device in different mountings,
// a changed device flagged, the reference value and degrees of equivalence against a hand
// computation, and the refusals.
#include "accel_intrinsics/core/analysis/comparison.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <random>

#include "../../support/random_device.h"
#include "../../support/statistical_bounds.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

// The nine parameters with U = 2 x the fit's standard uncertainty (type A: the simulation has no
// rig errors, so type A is the whole uncertainty).
ComparedResult compared(const FitResult& fit, const std::string& name) {
  ComparedResult r;
  r.name = name;
  r.local_gravity = fit.local_gravity;
  for (int i = 0; i < 3; ++i) {
    r.value[i] = fit.intrinsics.responsivity(i);
    r.expanded[i] = 2.0 * fit.intrinsics.responsivity_std(i);
    r.value[3 + i] = rad_to_deg(fit.intrinsics.angles_rad(i));
    r.expanded[3 + i] = 2.0 * rad_to_deg(fit.intrinsics.angles_std_rad(i));
    r.value[6 + i] = fit.O(i);
    r.expanded[6 + i] = 2.0 * fit.O_std(i);
  }
  return r;
}

// The device in another mounting: the triad rotated by a random rotation in the DUT frame (rows of
// S rotate, S' = S Q^T); intrinsics and offsets unchanged, the cross-sensitivity matrix not.
Device remounted(const Device& d, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  Device out = d;
  out.S = d.S * q.toRotationMatrix().transpose();
  return out;
}

FitResult simulated_fit(const Device& truth, std::uint64_t seed) {
  SimulationOptions sim;
  sim.truth = truth;
  sim.seed = seed;
  return fit(simulate_position_table(sim));
}

TEST(Comparison, SameDeviceInDifferentMountingsIsConsistentIn95PercentOfPairs) {
  std::mt19937_64 rng(2026);
  const int pairs = std::getenv("PAIRS") ? std::atoi(std::getenv("PAIRS")) : 200;
  std::array<int, kComparedParameters> within{};
  int all_within = 0;
  for (int k = 0; k < pairs; ++k) {
    const Device device = testing_devices::random_device(rng);
    const FitResult a = simulated_fit(remounted(device, rng), 1000 + 2 * k);
    const FitResult b = simulated_fit(remounted(device, rng), 1001 + 2 * k);
    const Comparison c = compare({compared(a, "A"), compared(b, "B")});
    for (int p = 0; p < kComparedParameters; ++p)
      if (std::abs(c.parameters[p].E_n[0]) <= 1.0) ++within[p];
    if (c.consistent) ++all_within;
  }
  // k = 2 covers 95.45 % of a normal E_n, so the "at least 95 % of 200 pairs" sits at the
  // nominal rate: per parameter the count is binomial(200, 0.9545), 190.9 +- 2.9, and asserting
  // >= 190 for each of nine parameters would fail by chance about half the time. Asserted: each
  // parameter's count at least the binomial(pairs, 0.95) quantile at 1e-3 / 9, so a comparison
  // that covers at least 95 % fails this test in fewer than 1e-3 runs whatever the seed (issue
  // 15). The pooled count over the nine parameters is only printed: the nine E_n of one pair
  // share two fits, so the pooled count is not binomial, and a pooled ">= 95 %" failed for 2 of
  // 40 other base seeds. With PAIRS=3000 in the environment every parameter came out between
  // 95.1 % and 96.2 % (2853..2887 of 3000), all nine at once in 67 %.
  const int lowest = statistical_bounds::binomial_lower(pairs, 0.95, 1e-3 / kComparedParameters);
  int pooled = 0;
  for (int p = 0; p < kComparedParameters; ++p) {
    pooled += within[p];
    EXPECT_GE(within[p], lowest) << kComparisonParameterNames[p];
    std::cout << "[ comparison ] " << kComparisonParameterNames[p] << ": |E_n| <= 1 in "
              << within[p] << " of " << pairs << " pairs (bound " << lowest << ")\n";
  }
  std::cout << "[ comparison ] pooled: " << pooled << " of " << kComparedParameters * pairs << "\n";
  std::cout << "[ comparison ] all nine within in " << all_within << " of " << pairs << " pairs\n";
}

TEST(Comparison, ResponsivityChangedByFiveExpandedUncertaintiesIsFlagged) {
  std::mt19937_64 rng(7);
  const Device device = testing_devices::random_device(rng);
  const FitResult a = simulated_fit(remounted(device, rng), 11);
  const double U = 2.0 * a.intrinsics.responsivity_std(0);
  Device changed = device;
  changed.S.row(0) *= 1.0 + 5.0 * U / device.S.row(0).norm();
  const FitResult b = simulated_fit(remounted(changed, rng), 12);
  const Comparison c = compare({compared(a, "A"), compared(b, "B")});
  EXPECT_FALSE(c.consistent);
  EXPECT_GT(std::abs(c.parameters[0].E_n[0]), 1.0);
  EXPECT_LT(c.parameters[0].E_n[0], 0.0);  // A minus B, B larger
  // Sanity: the same comparison without the change is consistent for responsivity_u.
  const FitResult b0 = simulated_fit(remounted(device, rng), 12);
  EXPECT_LE(std::abs(compare({compared(a, "A"), compared(b0, "B")}).parameters[0].E_n[0]), 1.0);
}

TEST(Comparison, ReferenceValueAndDegreesOfEquivalenceAsComputedByHand) {
  // Three results of one parameter: x = 1.0, 1.2, 0.9 with U = 0.2, 0.4, 0.2 (k = 2):
  // u = 0.1, 0.2, 0.1; weights 100, 25, 100; x_ref = (100 + 30 + 90) / 225 = 0.977777...;
  // u_ref^2 = 1/225; d_1 = 0.022222, U(d_1) = 2 sqrt(0.01 - 1/225) = 0.149071;
  // d_2 = 0.222222, U(d_2) = 2 sqrt(0.04 - 1/225) = 0.377124 -> E_n = 0.589256.
  std::vector<ComparedResult> rs(3);
  const double x[3] = {1.0, 1.2, 0.9}, U[3] = {0.2, 0.4, 0.2};
  for (int i = 0; i < 3; ++i) {
    rs[i].name = "r" + std::to_string(i);
    rs[i].local_gravity = kStandardGravity;
    rs[i].value.fill(x[i]);
    rs[i].expanded.fill(U[i]);
  }
  const Comparison c = compare(rs);
  const ParameterComparison& p = c.parameters[0];
  EXPECT_NEAR(p.reference, 220.0 / 225.0, 1e-12);
  EXPECT_NEAR(p.reference_expanded, 2.0 / 15.0, 1e-12);
  EXPECT_NEAR(p.degrees_of_equivalence[0], 1.0 - 220.0 / 225.0, 1e-12);
  EXPECT_NEAR(p.degrees_of_equivalence_expanded[0], 2.0 * std::sqrt(0.01 - 1.0 / 225.0), 1e-12);
  EXPECT_NEAR(p.E_n[1], (1.2 - 220.0 / 225.0) / (2.0 * std::sqrt(0.04 - 1.0 / 225.0)), 1e-12);
  EXPECT_NEAR(p.E_n[2], (0.9 - 220.0 / 225.0) / (2.0 * std::sqrt(0.01 - 1.0 / 225.0)), 1e-12);
  EXPECT_TRUE(c.consistent);  // |E_n| = 0.149, 0.589, 0.522
}

TEST(Comparison, RefusesDifferentGravityAndMissingUncertainties) {
  ComparedResult a, b;
  a.name = "A.json";
  b.name = "B.json";
  a.local_gravity = 9.80665;
  b.local_gravity = 9.8012;
  a.value.fill(1.0);
  b.value.fill(1.0);
  a.expanded.fill(0.1);
  b.expanded.fill(0.1);
  try {
    compare({a, b});
    FAIL();
  } catch (const ComparisonError& e) {
    EXPECT_NE(std::string(e.what()).find("g = 9.8012"), std::string::npos) << e.what();
  }
  b.local_gravity = a.local_gravity;
  b.expanded[4] = std::nan("");
  try {
    compare({a, b});
    FAIL();
  } catch (const ComparisonError& e) {
    EXPECT_NE(std::string(e.what()).find("B.json: angle_vw has no uncertainty"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(compare({a}), ComparisonError);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
