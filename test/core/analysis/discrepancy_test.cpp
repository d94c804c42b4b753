// Discrepancy analysis on data with hidden effects (issue 5): random devices, mountings, noise
// levels and seeds; each hidden effect at several times its detection threshold must be named
// with the right name and target, recovered within k sigma, and the chi-square must come back
// inside its band (k and the band from the normal and chi-square quantiles, Bonferroni over the
// trials, so that a correct analysis fails a test in fewer than 1e-3 runs). Effect-free data
// must name something at the rate alpha, checked against a binomial bound.
#include "accel_intrinsics/core/analysis/discrepancy.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>
#include <sstream>
#include <string>

#include "../../support/analysis_checks.h"
#include "../../support/random_device.h"
#include "../../support/statistical_bounds.h"
#include "../../support/written_runs.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/noise/slow_part_fit.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

using analysis_checks::describe;
using analysis_checks::detection_threshold;
using analysis_checks::expect_chi2_in_band;
using analysis_checks::find_candidate;
using analysis_checks::find_named;
using analysis_checks::trial_bands;
using analysis_checks::TrialBands;
using testing_devices::random_device;

SimulationOptions random_simulation(std::uint64_t seed, bool two_way = false) {
  std::mt19937_64 rng(seed);
  SimulationOptions so;
  so.truth = random_device(rng);
  std::uniform_real_distribution<double> density(150e-6, 400e-6);
  so.noise_density = density(rng) * kStandardGravity;
  so.protocol.steps_per_phase = 24;
  so.protocol.two_way = two_way;
  so.seed = seed * 7 + 3;
  return so;
}

struct HiddenCase {
  EffectKind kind;
  bool two_way;
};

class DiscrepancyHiddenEffect : public ::testing::TestWithParam<HiddenCase> {};

TEST_P(DiscrepancyHiddenEffect, NamedRecoveredAndGapClosed) {
  const HiddenCase hc = GetParam();
  // Six trials: every target twice, 3, 5 and 10 times the detection threshold, both signs.
  const double multiples[] = {3.0, 5.0, 10.0, 3.0, 5.0, 10.0};
  // The bands over all 7 x 6 trials of the suite (every instance spends 1/7 of 1e-3).
  const TrialBands bands = trial_bands(7 * 6, 3);
  int trial = 0;
  for (double multiple : multiples) {
    const std::uint64_t seed =
        100 * (static_cast<std::uint64_t>(hc.kind) + 1) + static_cast<std::uint64_t>(trial);
    SimulationOptions so = random_simulation(seed, hc.two_way);
    const int target = trial % 3;
    const double threshold = detection_threshold(so, hc.kind, target);
    ASSERT_GT(threshold, 0.0);
    const double sign = trial % 2 == 0 ? 1.0 : -1.0;
    Effect hidden{hc.kind, target, sign * multiple * threshold};
    so.truth.effects = {hidden};
    const AnalysisResult a = analyze(simulate_position_table(so));
    SCOPED_TRACE(hidden.label() + " = " + std::to_string(hidden.value) + " (" +
                 std::to_string(multiple) + " x threshold): " + describe(a));
    ASSERT_FALSE(a.effects.empty());
    EXPECT_EQ(a.effects.front().effect.label(), hidden.label());
    const NamedEffect* e = find_named(a, hc.kind, target);
    ASSERT_NE(e, nullptr);
    EXPECT_LE(e->p_value, 0.05);
    EXPECT_GT(e->std, 0.0);
    EXPECT_LE(std::abs(e->effect.value - hidden.value), bands.k * e->std);
    expect_chi2_in_band(a.after.summary, bands.tail);
    EXPECT_LT(a.after.summary.chi2, a.before.summary.chi2);
    // Out of sample too (issue 23): the cross-validated chi2 per point (time-block folds) drops
    // when the effect is added, at its step and overall.
    EXPECT_LT(a.after.cv.cv_chi2_per_point, a.before.cv.cv_chi2_per_point);
    EXPECT_LT(e->cv_after, e->cv_before);
    ++trial;
  }
}

INSTANTIATE_TEST_SUITE_P(Discrepancy, DiscrepancyHiddenEffect,
                         ::testing::Values(HiddenCase{EffectKind::QuadraticNonlinearity, false},
                                           HiddenCase{EffectKind::CubicNonlinearity, false},
                                           HiddenCase{EffectKind::AngleOffset, false},
                                           HiddenCase{EffectKind::AngleScale, false},
                                           HiddenCase{EffectKind::AxisTilt, false},
                                           HiddenCase{EffectKind::OffsetDrift, false},
                                           HiddenCase{EffectKind::Backlash, true}),
                         [](const ::testing::TestParamInfo<HiddenCase>& info) {
                           std::string name = effect_info(info.param.kind).name;
                           name.erase(std::remove(name.begin(), name.end(), '_'), name.end());
                           return name;
                         });

TEST(Discrepancy, EffectFreeDataFalseAlarmRateWithinAlpha) {
  // Each effect-free run names something with probability alpha (AnalysisOptions: 0.025, half
  // the 5 % the requirement allows), up to the Monte Carlo error of the max-T critical values
  // (draws per step; allowance 4 standard errors of a tail probability alpha). The count over
  // 200 runs is then at most binomial(200, p) and must stay below its 1 - 1e-3 quantile (a fixed
  // "at most 10" failed by chance in about 1 % of base seeds). A procedure at the 5 % of the
  // requirement would exceed the bound (15) in about 1 of 23 base seeds, one at 10 % in 6 of 7.
  const AnalysisOptions defaults;
  const double p = defaults.alpha + 4.0 * std::sqrt(defaults.alpha * (1.0 - defaults.alpha) /
                                                    defaults.monte_carlo_draws);
  const int runs = 200;
  const int bound = statistical_bounds::binomial_upper(runs, p, 1e-3);
  int runs_naming_something = 0;
  int twin_checks = 0;
  for (int seed = 0; seed < runs; ++seed) {
    const SimulationOptions so =
        random_simulation(10000 + static_cast<std::uint64_t>(seed), seed % 4 == 0);
    const PositionTable table = simulate_position_table(so);
    const AnalysisResult a = analyze(table);
    if (!a.effects.empty()) ++runs_naming_something;
    // The twin reproduces the fit's own residuals.
    if (seed % 50 == 0) {
      const std::vector<Eigen::Vector3d> r =
          twin_residuals(table, device_from_fit(a.before_fit), kStandardGravity);
      for (std::size_t i = 0; i < r.size(); ++i)
        EXPECT_LT((r[i] - a.before_fit.residuals[i]).norm(), 1e-9);
      ++twin_checks;
    }
  }
  EXPECT_EQ(twin_checks, 4);
  std::cout << "[ INFO     ] " << runs_naming_something << " of " << runs
            << " effect-free runs named an effect (bound " << bound << ")\n";
  EXPECT_LE(runs_naming_something, bound)
      << runs_naming_something << " of " << runs << " effect-free runs named an effect";
}

TEST(Discrepancy, TwoHiddenEffectsAreBothNamed) {
  // Per trial two recovery checks and the chi-square band.
  const TrialBands bands = trial_bands(3, 4);
  for (int trial = 0; trial < 3; ++trial) {
    SimulationOptions so = random_simulation(777 + static_cast<std::uint64_t>(trial));
    const int s = trial % 3, p = (trial + 1) % 3;
    const double t_quad = detection_threshold(so, EffectKind::QuadraticNonlinearity, s);
    const double t_off = detection_threshold(so, EffectKind::AngleOffset, p);
    so.truth.effects = {Effect{EffectKind::QuadraticNonlinearity, s, 4.0 * t_quad},
                        Effect{EffectKind::AngleOffset, p, -4.0 * t_off}};
    const AnalysisResult a = analyze(simulate_position_table(so));
    SCOPED_TRACE(describe(a));
    const NamedEffect* q = find_named(a, EffectKind::QuadraticNonlinearity, s);
    const NamedEffect* o = find_named(a, EffectKind::AngleOffset, p);
    ASSERT_NE(q, nullptr);
    ASSERT_NE(o, nullptr);
    EXPECT_LE(std::abs(q->effect.value - so.truth.effects[0].value), bands.k * q->std);
    EXPECT_LE(std::abs(o->effect.value - so.truth.effects[1].value), bands.k * o->std);
    expect_chi2_in_band(a.after.summary, bands.tail);
    EXPECT_GT(a.before.summary.reduced_chi2, a.after.summary.reduced_chi2);
  }
}

// p_raw and p_holm of every identifiable candidate at every step, computed here: p_raw =
// P(chi2(1) >= T) = erfc(sqrt(T / 2)); Holm's step-down over the m identifiable candidates in
// ascending p: the k-th (from 0) times (m - k), capped at 1, running maximum. Two hidden effects
// make two small p-values at the first step, where Holm (m - 1) and Bonferroni (m) differ.
TEST(Discrepancy, HolmAdjustedPValuesAsComputedByHand) {
  SimulationOptions so = random_simulation(4242);
  const double t_quad = detection_threshold(so, EffectKind::QuadraticNonlinearity, 0);
  const double t_off = detection_threshold(so, EffectKind::AngleOffset, 2);
  so.truth.effects = {Effect{EffectKind::QuadraticNonlinearity, 0, 3.0 * t_quad},
                      Effect{EffectKind::AngleOffset, 2, 3.0 * t_off}};
  const AnalysisResult a = analyze(simulate_position_table(so));
  SCOPED_TRACE(describe(a));
  ASSERT_FALSE(a.steps.empty());
  int sensitive = 0;  // candidates past the first where Holm and Bonferroni differ
  for (const ScreeningStep& step : a.steps) {
    std::vector<const CandidateScore*> ident;
    for (const CandidateScore& c : step.candidates) {
      if (!c.identifiable) continue;
      EXPECT_NEAR(c.p_raw, std::erfc(std::sqrt(c.score_chi2 / 2.0)), 1e-9 * c.p_raw + 1e-300)
          << c.effect.label();
      ident.push_back(&c);
    }
    std::vector<const CandidateScore*> sorted = ident;
    std::stable_sort(
        sorted.begin(), sorted.end(),
        [](const CandidateScore* x, const CandidateScore* y) { return x->p_raw < y->p_raw; });
    const double m = static_cast<double>(sorted.size());
    double running = 0.0;
    for (std::size_t k = 0; k < sorted.size(); ++k) {
      const double holm = std::min(1.0, (m - static_cast<double>(k)) * sorted[k]->p_raw);
      running = std::max(running, holm);
      EXPECT_NEAR(sorted[k]->p_holm, running, 1e-12 * running)
          << sorted[k]->effect.label() << " k " << k;
      if (k > 0 && m * sorted[k]->p_raw < 1.0 && holm >= running && sorted[k]->p_raw > 1e-280) {
        ++sensitive;
      }
    }
  }
  EXPECT_GT(sensitive, 0) << "no candidate where Holm and Bonferroni differ: the check is blind";
  // The gaps' degrees of freedom: 3 N residuals minus the 12 of S and O and one per effect, and
  // the chi-square of the gap is the fit's.
  const int residuals = 3 * static_cast<int>(a.before_fit.residuals.size());
  EXPECT_EQ(a.before.summary.dof, residuals - 12);
  EXPECT_EQ(a.after.summary.dof, residuals - 12 - static_cast<int>(a.after_fit.effects.size()));
  EXPECT_NEAR(a.before.summary.reduced_chi2, a.before.summary.chi2 / (residuals - 12),
              1e-12 * a.before.summary.reduced_chi2);
}

TEST(Discrepancy, OneWayAngleOffsetIsAmbiguousWithBacklash) {
  SimulationOptions so = random_simulation(4242);
  const double t = detection_threshold(so, EffectKind::AngleOffset, 1);
  so.truth.effects = {Effect{EffectKind::AngleOffset, 1, 5.0 * t}};
  const AnalysisResult a = analyze(simulate_position_table(so));
  ASSERT_FALSE(a.effects.empty());
  EXPECT_EQ(a.effects.front().effect.label(), "angle_offset[y]");
  bool found = false;
  for (const Ambiguity& amb : a.ambiguous) {
    if (std::find(amb.candidates.begin(), amb.candidates.end(), "backlash[y]") !=
        amb.candidates.end()) {
      found = true;
      EXPECT_NE(amb.separating_experiment.find("two-way"), std::string::npos);
    }
  }
  EXPECT_TRUE(found);
  // Backlash is not screened on a one-way sweep, and the notes say why.
  for (const ScreeningStep& s : a.steps)
    EXPECT_EQ(find_candidate(s, EffectKind::Backlash, 1), nullptr);
}

TEST(Discrepancy, WithTwoWaySweepBacklashIsSeparatedFromAngleOffset) {
  SimulationOptions so = random_simulation(4343, true);
  const double t = detection_threshold(so, EffectKind::Backlash, 2);
  so.truth.effects = {Effect{EffectKind::Backlash, 2, 6.0 * t}};
  const AnalysisResult a = analyze(simulate_position_table(so));
  SCOPED_TRACE(describe(a));
  ASSERT_FALSE(a.effects.empty());
  EXPECT_EQ(a.effects.front().effect.label(), "backlash[z]");
  EXPECT_EQ(find_named(a, EffectKind::AngleOffset, 2), nullptr);
}

TEST(Discrepancy, TermAbsorbedByOffsetsIsUnidentifiableAndNeverNamed) {
  // A table without times (every dwell at the same instant): offset drift is exactly a constant,
  // which the offsets O absorb; it must be reported unidentifiable, never named.
  const SimulationOptions so = random_simulation(99);
  PositionTable table = simulate_position_table(so);
  for (DwellRecord& row : table.rows) {
    row.t_start_s = 100.0;
    row.t_end_s = 102.0;
  }
  const AnalysisResult a = analyze(table);
  int absorbed = 0;
  for (const CandidateScore& c : a.unidentifiable) {
    if (c.effect.kind == EffectKind::OffsetDrift) ++absorbed;
    EXPECT_LT(c.information_ratio, 1e-6);
  }
  EXPECT_EQ(absorbed, 3);
  for (const NamedEffect& e : a.effects) EXPECT_NE(e.effect.kind, EffectKind::OffsetDrift);
  for (const CandidateScore& c : a.steps.front().candidates) {
    if (c.effect.kind == EffectKind::OffsetDrift) {
      EXPECT_FALSE(c.identifiable);
    }
  }
}

TEST(Discrepancy, ScoreStatisticMatchesRefitDeltaChi2) {
  // The screening statistic is the linearized likelihood-ratio delta chi2; the nonlinear refit
  // of a small effect must agree closely.
  SimulationOptions so = random_simulation(31337);
  const double t = detection_threshold(so, EffectKind::CubicNonlinearity, 2);
  so.truth.effects = {Effect{EffectKind::CubicNonlinearity, 2, 4.0 * t}};
  const AnalysisResult a = analyze(simulate_position_table(so));
  ASSERT_FALSE(a.effects.empty());
  const NamedEffect& e = a.effects.front();
  EXPECT_EQ(e.effect.label(), "cubic_nonlinearity[w]");
  EXPECT_NEAR(e.delta_chi2, e.score_chi2, 0.02 * e.score_chi2 + 0.5);
}

// The analysis JSON and the residual CSV of such a run: test/io/analysis_report_test.cpp.
TEST(Discrepancy, QuadraticTermShowsAtHarmonicTwoBeforeAndNotAfter) {
  SimulationOptions so = random_simulation(2024);
  const double t = detection_threshold(so, EffectKind::QuadraticNonlinearity, 1);
  so.truth.effects = {Effect{EffectKind::QuadraticNonlinearity, 1, 5.0 * t}};
  const PositionTable table = simulate_position_table(so);
  const AnalysisResult a = analyze(table);
  ASSERT_FALSE(a.effects.empty());
  EXPECT_EQ(a.effects.front().effect.label(), "quadratic_nonlinearity[v]");
  EXPECT_GT(a.before.summary.rms, a.after.summary.rms);
  // The quadratic term of v shows at harmonic 2 of the angle, before and not after.
  double h2_before = 0, h2_after = 0;
  for (const CellGap& c : a.before.cells) {
    if (c.accelerometer == 1) h2_before += c.harmonic_power[2];
  }
  for (const CellGap& c : a.after.cells) {
    if (c.accelerometer == 1) h2_after += c.harmonic_power[2];
  }
  EXPECT_GT(h2_before, 3.0 * h2_after);
}

TEST(Discrepancy, DetectionThresholdFromNoncentralChiSquare) {
  // 90 % power of a 5 % two-sided z-test: lambda = (1.95996 + 1.28155)^2 = 10.5074.
  EXPECT_NEAR(noncentrality_for_power(3.841459, 0.9), 10.5074, 0.01);
  EXPECT_THROW(noncentrality_for_power(-1.0, 0.9), std::invalid_argument);
  AnalysisOptions bad;
  bad.alpha = 1.5;
  EXPECT_THROW(validate(bad), std::invalid_argument);
}

// The slow part fitted to a run (slow_part_from_run) is the restricted likelihood of the residuals
// outside the column space of the base model's Jacobian by all 12 of its parameters (S and O): the
// same as slow_part_from_residuals given that Jacobian, here taken by central differences of the
// model's prediction. The run is written here: 3 phases x 8 steps of 2 s, a random walk added to
// every dwell mean.
TEST(Discrepancy, SlowPartFromRunProjectsOutEveryParameterOfTheBaseModel) {
  PositionTable table = written_runs::three_phase_table(8, 200, 0.01);
  Device truth;
  truth.S << 1.01, 0.002, -0.003, 0.001, 0.99, 0.004, -0.002, 0.003, 1.02;
  truth.O << 0.05, -0.03, 0.02;
  const double g = kStandardGravity;
  const std::vector<DwellGeometry> geoms = dwell_geometries(table);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Vector3d walk = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    walk += 2e-3 * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    const Eigen::Vector3d white(normal(rng), normal(rng), normal(rng));
    table.rows[i].mean = predict_outputs(truth, geoms[i], g) + walk + 1e-3 * white;
  }
  FitOptions options;
  options.local_gravity = g;
  for (int s = 0; s < 3; ++s) {
    options.noise_model.axes[s].white_std = 0.01;
    options.noise_model.axes[s].rw_density = 1e-3;
  }
  const NoiseModel from_run = slow_part_from_run(table, options);

  FitOptions white_options = options;
  white_options.noise_model = NoiseModel();
  const FitResult base = fit(table, white_options);
  const std::vector<Eigen::Vector3d> se = base.standard_errors.size() == table.rows.size()
                                              ? base.standard_errors
                                              : dwell_standard_errors(table);
  const Device at = device_from_fit(base);
  const Eigen::Index n = 3 * static_cast<Eigen::Index>(table.rows.size());
  Eigen::MatrixXd J(n, 12);
  for (int j = 0; j < 12; ++j) {
    const double h = 1e-3;
    Device plus = at, minus = at;
    if (j < 9) {
      plus.S(j / 3, j % 3) += h;
      minus.S(j / 3, j % 3) -= h;
    } else {
      plus.O(j - 9) += h;
      minus.O(j - 9) -= h;
    }
    for (std::size_t r = 0; r < table.rows.size(); ++r) {
      const Eigen::Vector3d d =
          (predict_outputs(plus, geoms[r], g) - predict_outputs(minus, geoms[r], g)) / (2 * h);
      for (int s = 0; s < 3; ++s) J(3 * static_cast<Eigen::Index>(r) + s, j) = d(s) / se[r](s);
    }
  }
  const NoiseModel reference =
      slow_part_from_residuals(table, options.noise_model, base.residuals, se, J);
  for (int s = 0; s < 3; ++s) {
    const AxisNoiseModel& a = from_run.axes[s];
    const AxisNoiseModel& b = reference.axes[s];
    EXPECT_TRUE(b.slow()) << "axis " << s << ": the walk was not seen";
    EXPECT_NEAR(a.rw_density, b.rw_density, 1e-6 * b.rw_density + 1e-12) << "axis " << s;
    EXPECT_NEAR(a.gm_sigma, b.gm_sigma, 1e-6 * b.gm_sigma + 1e-12) << "axis " << s;
    EXPECT_NEAR(a.gm_tau_s, b.gm_tau_s, 1e-6 * b.gm_tau_s + 1e-12) << "axis " << s;
  }
}

// The gap's trend_z is the z-statistic of the slope of the normalized residuals against time:
// sum (t - mean t) z / sqrt(sum (t - mean t)^2), which has unit variance without a trend and no
// unit. The run is written here from eq. (4) (R = S g f(angle) + O, 3 phases x 12 steps of 2 s),
// with white noise and a drift of u; z is formed here from the fit's S and O. The same run with
// its clock in minutes instead of seconds (the fit has no time term) gives the same statistics.
TEST(Discrepancy, TrendZIsTheSlopeStatisticOfTheNormalizedResidualsInAnyTimeUnit) {
  using written_runs::mid_time;
  using written_runs::unit_force;
  Eigen::Matrix3d S;
  S << 1.02, 0.011, -0.014, -0.008, 0.991, 0.017, 0.012, -0.006, 1.007;
  const Eigen::Vector3d O(0.08, -0.15, 0.11);
  const double g = kStandardGravity, sample_std = 0.01, drift = 4e-5;  // m/s^2 per s of u
  const std::uint64_t n = 400;
  const double se = sample_std / std::sqrt(static_cast<double>(n));
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  PositionTable table = written_runs::three_phase_table(12, n, sample_std);
  for (DwellRecord& r : table.rows) {
    r.mean = S * (g * unit_force(r.phase, r.angle_rad)) + O +
             se * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    r.mean.x() += drift * mid_time(r);
  }
  const FitResult f = fit(table);
  const Gap gap = compute_gap(table, f);
  double t_mean = 0.0;
  for (const DwellRecord& r : table.rows) t_mean += mid_time(r);
  t_mean /= static_cast<double>(table.rows.size());
  double stt = 0.0;
  Eigen::Vector3d stz = Eigen::Vector3d::Zero();
  for (const DwellRecord& r : table.rows) {
    const double dt = mid_time(r) - t_mean;
    const Eigen::Vector3d z = (r.mean - f.S * (g * unit_force(r.phase, r.angle_rad)) - f.O) / se;
    stt += dt * dt;
    stz += dt * z;
  }
  for (int s = 0; s < 3; ++s) {
    const double expected = stz(s) / std::sqrt(stt);
    EXPECT_NEAR(gap.trend_z[s], expected, 1e-6 * (1.0 + std::abs(expected))) << "axis " << s;
  }
  EXPECT_GT(gap.trend_z[0], 5.0) << "the drift of u is not seen";
  EXPECT_LT(std::abs(gap.trend_z[1]), 4.0);
  EXPECT_LT(std::abs(gap.trend_z[2]), 4.0);

  PositionTable minutes = table;
  for (DwellRecord& r : minutes.rows) {
    r.t_start_s /= 60.0;
    r.t_end_s /= 60.0;
  }
  const Gap in_minutes = compute_gap(minutes, fit(minutes));
  for (int s = 0; s < 3; ++s)
    EXPECT_NEAR(in_minutes.trend_z[s], gap.trend_z[s], 1e-9 * (1.0 + std::abs(gap.trend_z[s])))
        << "axis " << s;
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
