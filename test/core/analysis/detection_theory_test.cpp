// Issue 15 item 2: the detection power of the discrepancy analysis against a threshold computed
// independently (test/support/detection_theory.h: the Fisher information of the effect term with
// the base model projected out and the KNOWN noise, a max-T critical value from its own draws,
// Boost.Math's non-central chi-square), never from what analyze() reports.
//  - An effect hidden at the independent threshold of power p is named in a fraction of runs that
//    the binomial distribution with that p bounds (random devices, one per run).
//  - The thresholds analyze() reports (CandidateScore::detection_threshold) agree with the
//    independent ones.
#include "../../support/detection_theory.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "../../support/random_device.h"
#include "../../support/statistical_bounds.h"
#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

namespace dt = detection_theory;

SimulationOptions run_simulation(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  SimulationOptions so;
  so.truth = testing_devices::random_device(rng);
  so.protocol.steps_per_phase = 24;
  so.seed = seed * 13 + 5;
  return so;
}

dt::Problem problem_of(const SimulationOptions& so) {
  SimulationOptions clean = so;
  clean.noise_density = 0.0;  // only the timeline and sample counts are needed
  dt::Problem pr;
  pr.S = so.truth.S;
  pr.sigma = sample_noise_stds(so);
  pr.g = so.local_gravity;
  pr.dwells = dt::dwells_of(simulate_position_table(clean));
  return pr;
}

bool names(const AnalysisResult& a, const Effect& e) {
  for (const NamedEffect& n : a.effects)
    if (n.effect.kind == e.kind && n.effect.target == e.target) return true;
  return false;
}

// Acceptance region of the count named in `runs` runs at predicted power p: the binomial
// quantiles at 1.25e-4 on each side (4 cases x 2 sides: < 1e-3 in all),
// taken at p - allowance and p + allowance. The allowance (0.07) covers what the linear theory
// leaves out: the first-order expansion of angle effects and the selection among correlated
// candidates (a run whose strongest candidate is a look-alike may name that one). Measured over
// 600 runs each (seeds as below): quadratic_nonlinearity 0.512 and angle_offset 0.467 at
// p = 0.5, offset_drift 0.858 and axis_tilt 0.848 at p = 0.9: the analysis falls short of the
// theory by up to 0.05 near 90 % power (its reported 90 % thresholds are that much optimistic;
// bench/detection_bench.cpp measures the same as a ratio of thresholds).
constexpr double kAllowance = 0.07;
std::pair<int, int> rate_bounds(int runs, double p) {
  namespace sb = statistical_bounds;
  return {sb::binomial_lower(runs, std::max(0.0, p - kAllowance), 1.25e-4),
          sb::binomial_upper(runs, std::min(1.0, p + kAllowance), 1.25e-4)};
}

struct RateCase {
  EffectKind kind;
  double power;
};

class DetectionRate : public ::testing::TestWithParam<RateCase> {};

// Runs of random devices, each with the effect (target cycling through u/v/w or x/y/z, random
// sign) hidden at that run's independent threshold of power p: the count of runs naming it is
// binomial(runs, p) when the analysis is as powerful as the theory says (within the allowance).
// An analysis without the family-wise correction (critical value 3.84 instead of ~10) names an
// effect at the p = 0.5 threshold in ~0.9 of runs, one that wastes a third of the information in
// ~0.3: both fall outside the bounds.
TEST_P(DetectionRate, NamedAtTheIndependentThresholdAsOftenAsTheNoncentralChiSquareSays) {
  const RateCase rc = GetParam();
  const int runs = 150;
  const AnalysisOptions options;
  int named = 0;
  double sum_critical = 0.0;
  for (int run = 0; run < runs; ++run) {
    SimulationOptions so = run_simulation(31000 + 1000 * static_cast<std::uint64_t>(rc.kind) +
                                          static_cast<std::uint64_t>(run));
    Effect hidden{rc.kind, run % 3, 0.0};
    const dt::Theory t =
        dt::theory_for(problem_of(so), hidden, dt::candidate_family(false), options.alpha, 20000,
                       777 + static_cast<std::uint64_t>(run));
    sum_critical += t.critical_chi2;
    hidden.value = (run % 2 == 0 ? 1.0 : -1.0) * dt::threshold(t, rc.power);
    ASSERT_NEAR(dt::naming_probability(t, hidden.value), rc.power, 1e-6);
    so.truth.effects = {hidden};
    if (names(analyze(simulate_position_table(so), options), hidden)) ++named;
  }
  const std::pair<int, int> bounds = rate_bounds(runs, rc.power);
  std::printf(
      "%s: named in %d of %d runs at the p = %.2f threshold (bounds %d..%d), mean "
      "critical chi2 %.3f\n",
      effect_info(rc.kind).name, named, runs, rc.power, bounds.first, bounds.second,
      sum_critical / runs);
  EXPECT_GE(named, bounds.first);
  EXPECT_LE(named, bounds.second);
}

INSTANTIATE_TEST_SUITE_P(DetectionTheory, DetectionRate,
                         ::testing::Values(RateCase{EffectKind::QuadraticNonlinearity, 0.5},
                                           RateCase{EffectKind::AngleOffset, 0.5},
                                           RateCase{EffectKind::OffsetDrift, 0.9},
                                           RateCase{EffectKind::AxisTilt, 0.9}),
                         [](const ::testing::TestParamInfo<RateCase>& info) {
                           std::string name = effect_info(info.param.kind).name;
                           name.erase(std::remove(name.begin(), name.end(), '_'), name.end());
                           return name;
                         });

// The thresholds the analysis reports for every candidate of a clean run agree with the
// independent computation (the analysis uses the dwells' sample std and its own Monte Carlo
// draws: both move the threshold by about 1 %).
TEST(DetectionTheory, ReportedThresholdsAgreeWithTheIndependentOnes) {
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    const SimulationOptions so = run_simulation(500 + seed);
    const AnalysisOptions options;
    const AnalysisResult a = analyze(simulate_position_table(so), options);
    const dt::Problem pr = problem_of(so);
    const std::vector<Effect> family = dt::candidate_family(false);
    ASSERT_EQ(a.steps.front().candidates.size(), family.size());
    for (const CandidateScore& c : a.steps.front().candidates) {
      const dt::Theory t = dt::theory_for(pr, c.effect, family, options.alpha);
      SCOPED_TRACE(c.effect.label() + " seed " + std::to_string(seed));
      ASSERT_TRUE(c.identifiable);
      EXPECT_NEAR(c.estimate_std / t.sigma_value, 1.0, 0.03);
      EXPECT_NEAR(a.steps.front().critical_chi2 / t.critical_chi2, 1.0, 0.03);
      EXPECT_NEAR(c.detection_threshold / dt::threshold(t, options.detection_power), 1.0, 0.05);
    }
  }
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
