// The analysis documents of io: the analysis JSON carries the contract keys (docs/design.md section
// 2), the node's analysis document adds the timing lag and the certificate's model, the residual
// CSV has one line per residual.
#include "accel_intrinsics/io/analysis_report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "../support/random_device.h"
#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/io/residuals_csv.h"
#include "accel_intrinsics/io/text_report.h"

namespace accel_intrinsics {
namespace {

using namespace core;

// As discrepancy_test's random_simulation(2024): a random device, 24 steps per phase.
SimulationOptions random_simulation(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  SimulationOptions so;
  so.truth = testing_devices::random_device(rng);
  std::uniform_real_distribution<double> density(150e-6, 400e-6);
  so.noise_density = density(rng) * kStandardGravity;
  so.protocol.steps_per_phase = 24;
  so.seed = seed * 7 + 3;
  return so;
}

TEST(AnalysisReport, JsonHasContractKeysAndCsvHasOneLinePerResidual) {
  SimulationOptions so = random_simulation(2024);
  // Five times the theoretical detection threshold of the quadratic term of v.
  const AnalysisResult clean = analyze(simulate_position_table(so));
  double threshold = 0;
  for (const CandidateScore& c : clean.steps.front().candidates) {
    if (c.effect.kind == EffectKind::QuadraticNonlinearity && c.effect.target == 1) {
      threshold = c.detection_threshold;
    }
  }
  ASSERT_GT(threshold, 0.0);
  so.truth.effects = {Effect{EffectKind::QuadraticNonlinearity, 1, 5.0 * threshold}};
  const PositionTable table = simulate_position_table(so);
  const AnalysisResult a = analyze(table);
  const nlohmann::json j = nlohmann::json::parse(io::analysis_json_text(a));
  ASSERT_TRUE(j.contains("effects"));
  ASSERT_TRUE(j.contains("ambiguous"));
  ASSERT_TRUE(j["ambiguous"].is_array());
  ASSERT_FALSE(j["effects"].empty());
  for (const char* key : {"name", "target", "value", "std", "p_value"}) {
    EXPECT_TRUE(j["effects"][0].contains(key)) << key;
  }
  EXPECT_EQ(j["effects"][0]["name"], "quadratic_nonlinearity");
  EXPECT_EQ(j["effects"][0]["target"], "v");
  // What no residual can show (local gravity, always named) and what was not screened.
  ASSERT_FALSE(a.unobservable.empty());
  EXPECT_EQ(j.at("unobservable").get<std::vector<std::string>>(), a.unobservable);
  EXPECT_EQ(j.at("not_screened").get<std::vector<std::string>>(), a.not_screened);
  for (const char* when : {"before", "after"}) {
    EXPECT_TRUE(j["gap"][when]["reduced_chi2"].is_number()) << when;
    EXPECT_TRUE(j["gap"][when]["rms"].is_number()) << when;
    EXPECT_EQ(j["gap"][when]["by_phase_accelerometer"].size(), 9u);
  }
  EXPECT_GT(j["gap"]["before"]["rms"].get<double>(), j["gap"]["after"]["rms"].get<double>());
  // The screening's p-values, each under its own key.
  ASSERT_EQ(j["screening"].size(), a.steps.size());
  for (std::size_t s = 0; s < a.steps.size(); ++s) {
    const nlohmann::json& cands = j["screening"][s]["candidates"];
    ASSERT_EQ(cands.size(), a.steps[s].candidates.size());
    for (std::size_t k = 0; k < cands.size(); ++k) {
      const CandidateScore& c = a.steps[s].candidates[k];
      if (!c.identifiable) continue;
      EXPECT_EQ(cands[k]["p_raw"].get<double>(), c.p_raw);
      EXPECT_EQ(cands[k]["p_holm"].get<double>(), c.p_holm);
      EXPECT_EQ(cands[k]["p_value"].get<double>(), c.p_adjusted);
      EXPECT_EQ(cands[k]["score_chi2"].get<double>(), c.score_chi2);
    }
  }

  std::ostringstream csv;
  io::write_residuals_csv(csv, table, a.before_fit, a.after_fit);
  std::istringstream lines(csv.str());
  std::string line;
  int count = 0;
  std::getline(lines, line);
  EXPECT_EQ(line.rfind("phase,step,angle_rad,time_s,approach,accelerometer,measured,sigma", 0), 0u);
  // Each line: measured minus model is the residual, the residual over sigma its z, before
  // and after; measured is the dwell mean.
  while (std::getline(lines, line)) {
    std::vector<std::string> f;
    std::istringstream fields(line);
    for (std::string x; std::getline(fields, x, ',');) f.push_back(x);
    ASSERT_EQ(f.size(), 14u) << line;
    const double measured = std::stod(f[6]), sigma = std::stod(f[7]);
    const int row = count / 3, axis = count % 3;
    EXPECT_NEAR(measured, table.rows[static_cast<std::size_t>(row)].mean(axis), 1e-9) << line;
    for (int b : {8, 11}) {
      const double model = std::stod(f[b]), residual = std::stod(f[b + 1]), z = std::stod(f[b + 2]);
      EXPECT_NEAR(residual, measured - model, 1e-9) << line;
      EXPECT_NEAR(z, residual / sigma, 1e-6 * std::abs(residual / sigma) + 1e-9) << line;
    }
    ++count;
  }
  EXPECT_EQ(count, 3 * static_cast<int>(table.rows.size()));
}

TEST(AnalysisReport, NodeDocumentAddsTimingLagAndTheCertificate) {
  SimulationOptions sim;
  sim.seed = 7;
  sim.truth.S << 1.01, 0.01, -0.02, 0.015, 0.98, 0.01, -0.01, 0.02, 1.02;
  sim.truth.effects = {Effect{EffectKind::QuadraticNonlinearity, 1, 4e-4},
                       Effect{EffectKind::TimingLag, 0, 0.02}};
  const Recording recording = simulate_recording(sim);
  DwellAssembler assembler;
  feed_in_stamp_order(recording, &assembler);
  RawStreams raw{recording.commands, recording.samples};
  CalibrateOptions options;
  options.analyze = true;
  options.certificate_refit = true;
  options.analysis.monte_carlo_draws = 2000;
  const CalibrationReport report = calibrate(assembler.table(), &raw, options);
  ASSERT_TRUE(report.analysis && report.timing_lag);
  ASSERT_TRUE(report.timing_lag->detected) << report.timing_lag->message;

  io::ResultContext context;
  context.stamp_s = 1234.5;
  const nlohmann::json j = nlohmann::json::parse(io::analysis_json_text(report, context));
  EXPECT_EQ(j["certificate_model"], report.certificate.model_label());
  EXPECT_EQ(j["certificate_policy"], "refit");
  EXPECT_EQ(j["base_model"], "joint");
  EXPECT_EQ(j["refit_model"], report.analysis->after_fit.model_label());
  EXPECT_EQ(j["stamp"], 1234.5);
  EXPECT_EQ(j["timing_lag"]["value"], report.timing_lag->lag_s);
  EXPECT_EQ(j["effects"].back()["name"], "timing_lag");
  EXPECT_EQ(j["effects"].back()["target"], "all");
  EXPECT_EQ(j["effects"].size(), report.analysis->effects.size() + 1);

  // The text report: the certificate, then the analysis and the lag.
  std::ostringstream text;
  io::write_text_report(text, report, io::ResultContext());
  EXPECT_NE(text.str().find("model:         " + report.certificate.model_label()),
            std::string::npos)
      << text.str();
  EXPECT_NE(text.str().find("discrepancy analysis"), std::string::npos);
  EXPECT_NE(text.str().find("timing lag (raw streams): "), std::string::npos);

  CalibrationReport without = report;
  without.analysis.reset();
  EXPECT_THROW(io::analysis_json_text(without, context), std::invalid_argument);
}

}  // namespace
}  // namespace accel_intrinsics
