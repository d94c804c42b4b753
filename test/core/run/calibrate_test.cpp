// The pipeline calibrate(): its report equals the separate calls it replaces (fit, analyze,
// estimate_timing_lag beside the screen), the certificate follows the refit policy, and a failed
// analysis leaves the fit standing.
#include "accel_intrinsics/core/run/calibrate.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <optional>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

struct SimulatedRun {
  Recording recording;
  PositionTable table;
  RawStreams raw;
};

// A simulated run with a quadratic non-linearity of v and a timing lag, assembled as the node and
// offline_fit assemble it.
SimulatedRun simulated_run(std::uint64_t seed) {
  SimulationOptions sim;
  sim.seed = seed;
  sim.truth.S << 1.01, 0.01, -0.02, 0.015, 0.98, 0.01, -0.01, 0.02, 1.02;
  sim.truth.O << 0.1, -0.2, 0.05;
  sim.truth.effects = {Effect{EffectKind::QuadraticNonlinearity, 1, 4e-4},
                       Effect{EffectKind::TimingLag, 0, 0.02}};
  SimulatedRun run;
  run.recording = simulate_recording(sim);
  DwellAssembler assembler;
  feed_in_stamp_order(run.recording, &assembler);
  run.table = assembler.table();
  run.raw.commands = run.recording.commands;
  run.raw.samples = run.recording.samples;
  return run;
}

CalibrateOptions analyzing_options() {
  CalibrateOptions options;
  options.fit.local_gravity = 9.8123;
  options.analyze = true;
  options.analysis.monte_carlo_draws = 2000;
  options.analysis.local_gravity = 1.0;  // overridden by fit.local_gravity
  return options;
}

void expect_same_fit(const FitResult& a, const FitResult& b) {
  EXPECT_EQ(a.model_label(), b.model_label());
  EXPECT_EQ(a.S, b.S);
  EXPECT_EQ(a.O, b.O);
  EXPECT_EQ(a.local_gravity, b.local_gravity);
  EXPECT_EQ(a.chi2, b.chi2);
  EXPECT_EQ(a.intrinsics.responsivity, b.intrinsics.responsivity);
}

TEST(Calibrate, ReportEqualsTheSeparateCalls) {
  const SimulatedRun run = simulated_run(7);
  const CalibrateOptions options = analyzing_options();
  const CalibrationReport report = calibrate(run.table, &run.raw, options);

  const FitResult base = fit(run.table, options.fit);
  AnalysisOptions analysis_options = options.analysis;
  analysis_options.local_gravity = options.fit.local_gravity;
  const AnalysisResult analysis = analyze(run.table, analysis_options);
  const TimingLagEstimate lag =
      estimate_timing_lag(run.raw.commands, run.raw.samples, run.table, analysis.after_fit,
                          timing_lag_options_beside_screen());

  expect_same_fit(report.base_fit, base);
  expect_same_fit(report.certificate, base);  // policy "base"
  EXPECT_FALSE(report.certificate_is_refit);
  EXPECT_FALSE(report.certificate_refit_policy);
  EXPECT_TRUE(report.analysis_error.empty());
  ASSERT_TRUE(report.analysis.has_value());
  EXPECT_EQ(report.analysis->local_gravity, 9.8123);
  ASSERT_EQ(report.analysis->effects.size(), analysis.effects.size());
  ASSERT_FALSE(analysis.effects.empty()) << "the simulated quadratic term should be named";
  for (std::size_t i = 0; i < analysis.effects.size(); ++i) {
    EXPECT_EQ(report.analysis->effects[i].effect.label(), analysis.effects[i].effect.label());
    EXPECT_EQ(report.analysis->effects[i].effect.value, analysis.effects[i].effect.value);
    EXPECT_EQ(report.analysis->effects[i].p_value, analysis.effects[i].p_value);
  }
  expect_same_fit(report.analysis->after_fit, analysis.after_fit);
  ASSERT_TRUE(report.timing_lag.has_value());
  EXPECT_EQ(report.timing_lag->ok, lag.ok);
  EXPECT_EQ(report.timing_lag->lag_s, lag.lag_s);
  EXPECT_EQ(report.timing_lag->std_s, lag.std_s);
  EXPECT_EQ(report.timing_lag->p_value, lag.p_value);
  EXPECT_EQ(report.timing_lag->detected, lag.detected);
  EXPECT_TRUE(lag.detected) << lag.message;
}

TEST(Calibrate, CertificateIsTheRefitOnlyWhenAskedAndEffectsWereNamed) {
  const SimulatedRun run = simulated_run(7);
  CalibrateOptions options = analyzing_options();
  options.certificate_refit = true;
  const CalibrationReport report = calibrate(run.table, &run.raw, options);
  ASSERT_TRUE(report.analysis.has_value());
  ASSERT_FALSE(report.analysis->effects.empty());
  EXPECT_TRUE(report.certificate_refit_policy);
  EXPECT_TRUE(report.certificate_is_refit);
  expect_same_fit(report.certificate, report.analysis->after_fit);
  expect_same_fit(report.base_fit, fit(run.table, options.fit));
  EXPECT_NE(report.certificate.model_label(), report.base_fit.model_label());

  // Nothing to name: the refit policy keeps the base fit.
  SimulationOptions clean;
  clean.seed = 3;
  const PositionTable table = simulate_position_table(clean);
  const CalibrationReport plain = calibrate(table, nullptr, options);
  ASSERT_TRUE(plain.analysis.has_value());
  ASSERT_TRUE(plain.analysis->effects.empty()) << "seeded effect-free run";
  EXPECT_FALSE(plain.certificate_is_refit);
  expect_same_fit(plain.certificate, plain.base_fit);
  EXPECT_FALSE(plain.timing_lag.has_value()) << "no raw streams, no lag";
}

TEST(Calibrate, AnalysisFailureLeavesTheFit) {
  const SimulatedRun run = simulated_run(11);
  CalibrateOptions options = analyzing_options();
  options.certificate_refit = true;
  options.analysis.alpha = 2.0;  // invalid: analyze() refuses it
  const CalibrationReport report = calibrate(run.table, &run.raw, options);
  EXPECT_FALSE(report.analysis.has_value());
  EXPECT_FALSE(report.timing_lag.has_value());
  EXPECT_NE(report.analysis_error.find("alpha"), std::string::npos) << report.analysis_error;
  EXPECT_FALSE(report.certificate_is_refit);
  expect_same_fit(report.certificate, fit(run.table, options.fit));
}

TEST(Calibrate, WithoutAnalysisOnlyTheFitAndAFailedFitThrows) {
  const SimulatedRun run = simulated_run(5);
  CalibrateOptions options;
  options.fit.model = FitModel::Eq4;
  const CalibrationReport report = calibrate(run.table, &run.raw, options);
  EXPECT_FALSE(report.analysis.has_value());
  EXPECT_FALSE(report.timing_lag.has_value());
  EXPECT_TRUE(report.analysis_error.empty());
  EXPECT_EQ(report.certificate.model, FitModel::Eq4);
  expect_same_fit(report.certificate, fit(run.table, options.fit));

  PositionTable no_z = run.table;
  no_z.rows.erase(std::remove_if(no_z.rows.begin(), no_z.rows.end(),
                                 [](const DwellRecord& r) { return r.phase == Phase::Z; }),
                  no_z.rows.end());
  EXPECT_THROW(calibrate(no_z, &run.raw, options), FitError);  // eq4 needs the three phases
  // joint fits two phases, but not one: the component along the rotation axis is unobservable.
  PositionTable x_only = no_z;
  x_only.rows.erase(std::remove_if(x_only.rows.begin(), x_only.rows.end(),
                                   [](const DwellRecord& r) { return r.phase == Phase::Y; }),
                    x_only.rows.end());
  EXPECT_THROW(calibrate(x_only, &run.raw, analyzing_options()), FitError);
}

// with_noise_model (the calibration node and offline_fit hand the run's noise model to both):
// the fit and the analysis are weighted with it; without one both stay white.
TEST(Calibrate, WithNoiseModelWeighsTheFitAndTheAnalysis) {
  SimulationOptions so;
  so.protocol.steps_per_phase = 8;
  so.protocol.initial_rest_s = 60.0;
  so.bias_gm_sigma = 0.002;
  so.bias_gm_tau_s = 10.0;
  so.seed = 6;
  const PositionTable table = simulate_position_table(so);
  CalibrateOptions options = analyzing_options();
  options.fit.local_gravity = so.local_gravity;
  options.analysis.monte_carlo_draws = 500;
  const CalibrateOptions white = with_noise_model(options, std::nullopt);
  EXPECT_TRUE(white.fit.noise_model.white());
  EXPECT_TRUE(white.analysis.noise_model.white());
  const CalibrationReport report =
      calibrate(table, nullptr, with_noise_model(options, true_noise_model(so)));
  EXPECT_FALSE(report.base_fit.noise_model.white());
  ASSERT_TRUE(report.analysis.has_value()) << report.analysis_error;
  EXPECT_FALSE(report.analysis->noise_model.white());
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
