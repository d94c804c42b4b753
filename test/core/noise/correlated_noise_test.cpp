// Noise that is not white (issue 23, docs/design.md section 12): the noise model of a long rest,
// the generalized least-squares fit it drives, the discrepancy analysis under a slow bias, and the
// cross-validated (out-of-sample) gap. Monte Carlo counts are kept small so the core suite stays
// quick; bench/ holds nothing of this (the counts here are what was run).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "../../support/statistical_bounds.h"
#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/analysis/tumble_analysis.h"
#include "accel_intrinsics/core/dwells/rest_detection.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/noise/rest_accumulator.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/core/simulation/tumble_simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

// ---- the covariance formulas against brute-force sums ------------------------------------------

double brute_covariance(const std::function<double(double, double)>& k, double a0, double a1,
                        double b0, double b1) {
  const int m = 400;
  double sum = 0.0;
  for (int i = 0; i < m; ++i) {
    const double t = a0 + (a1 - a0) * (i + 0.5) / m;
    for (int j = 0; j < m; ++j) sum += k(t, b0 + (b1 - b0) * (j + 0.5) / m);
  }
  return sum / (static_cast<double>(m) * m);
}

TEST(NoiseModel, SlowCovarianceMatchesTheDoubleIntegral) {
  NoiseModel m;
  m.axes[0].gm_sigma = 0.002;
  m.axes[0].gm_tau_s = 7.0;
  m.axes[1].rw_density = 3e-4;
  const double origin = 1.0;
  auto gm = [&](double t, double s) { return 0.002 * 0.002 * std::exp(-std::abs(t - s) / 7.0); };
  auto rw = [&](double t, double s) { return 9e-8 * (std::min(t, s) - origin); };
  const double cases[][4] = {{2, 4, 2, 4},  {2, 4, 10, 13}, {10, 13, 2, 4},
                             {2, 12, 5, 8}, {1, 61, 1, 61}, {3, 3.5, 40, 41}};
  for (const auto& c : cases) {
    SCOPED_TRACE(std::to_string(c[0]) + ".." + std::to_string(c[1]) + " x " + std::to_string(c[2]) +
                 ".." + std::to_string(c[3]));
    const double g = m.slow_covariance(0, c[0], c[1], c[2], c[3], origin);
    EXPECT_NEAR(g, brute_covariance(gm, c[0], c[1], c[2], c[3]), 1e-3 * std::abs(g) + 1e-14);
    const double r = m.slow_covariance(1, c[0], c[1], c[2], c[3], origin);
    EXPECT_NEAR(r, brute_covariance(rw, c[0], c[1], c[2], c[3]), 1e-3 * std::abs(r) + 1e-14);
  }
  // The variance of a dwell mean: white / n plus the slow part; long dwells approach sigma^2 2
  // tau / T (Gauss-Markov), short ones sigma^2.
  m.axes[0].white_std = 0.01;
  EXPECT_NEAR(m.variance_of_mean(0, 2.0, 200.0), 1e-4 / 200.0 + m.slow_covariance(0, 0, 2, 0, 2, 0),
              1e-18);
  EXPECT_NEAR(m.slow_covariance(0, 0, 1e-4, 0, 1e-4, 0), 4e-6, 1e-9);
  EXPECT_NEAR(m.slow_covariance(0, 0, 7000, 0, 7000, 0) / (4e-6 * 2 * 7.0 / 7000), 1.0, 2e-3);
}

// ---- the noise model of a record written here from the equations (not by the simulator) -------

// White noise plus an AR(1) bias b_k = phi b_{k-1} + sqrt(1 - phi^2) sigma xi_k (the exact
// discretization of a Gauss-Markov process), plus a random walk.
std::vector<Eigen::Vector3d> ar1_record(std::uint64_t seed, std::size_t n, double rate,
                                        double white, double sigma, double tau, double rw) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double phi = std::exp(-1.0 / (rate * tau));
  Eigen::Vector3d b(sigma * normal(rng), sigma * normal(rng), sigma * normal(rng));
  Eigen::Vector3d walk = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> out(n);
  for (std::size_t k = 0; k < n; ++k) {
    for (int s = 0; s < 3; ++s) {
      b(s) = phi * b(s) + std::sqrt(1.0 - phi * phi) * sigma * normal(rng);
      walk(s) += rw / std::sqrt(rate) * normal(rng);
      out[k](s) = 9.0 * (s == 2) + b(s) + walk(s) + white * normal(rng);
    }
  }
  return out;
}

TEST(NoiseModel, EstimatedFromAnAr1RecordWrittenInTheTest) {
  // A long record (40 tau) pins the model down: sigma within 35 % (one record of 40 tau: the
  // variance of a Gauss-Markov process is known to about sqrt(2 tau / T) = 22 %, and the fit
  // shares the low Allan points with the random-walk term; axis u of this seed comes out 28 %
  // low), tau within a factor 2, white within 3 %, the variance of a 2 s dwell mean within a
  // factor 2. The same estimator on a 120 s rest is much rougher (see the Monte Carlo below).
  const double rate = 50.0, white = 0.004, sigma = 0.0015, tau = 30.0;
  const std::vector<Eigen::Vector3d> x = ar1_record(7, 60000, rate, white, sigma, tau, 0.0);
  const NoiseModel m = estimate_noise_model(x, rate);
  EXPECT_EQ(m.kind().find("gauss_markov"), 0u) << m.kind();
  for (int s = 0; s < 3; ++s) {
    SCOPED_TRACE(s);
    EXPECT_NEAR(m.axes[s].white_std / white, 1.0, 0.03);
    EXPECT_NEAR(m.axes[s].gm_sigma / sigma, 1.0, 0.35);
    EXPECT_GT(m.axes[s].gm_tau_s, tau / 2.0);
    EXPECT_LT(m.axes[s].gm_tau_s, tau * 2.0);
    // The dwell-mean variance the estimate predicts for a 2 s dwell, against the truth.
    NoiseModel truth;
    truth.axes[s] = {white, sigma, tau, 0.0};
    const double ratio = m.variance_of_mean(s, 2.0, 100.0) / truth.variance_of_mean(s, 2.0, 100.0);
    EXPECT_GT(ratio, 0.5);
    EXPECT_LT(ratio, 2.0);
  }
  // White data: the slow part stays negligible against the white part of a 2 s dwell mean.
  const std::vector<Eigen::Vector3d> w = ar1_record(8, 12000, 100.0, white, 0.0, 1.0, 0.0);
  const NoiseModel mw = estimate_noise_model(w, 100.0);
  for (int s = 0; s < 3; ++s) {
    const double white_var = white * white / 200.0;
    EXPECT_LT(mw.variance_of_mean(s, 2.0, 200.0), 1.5 * white_var) << s;
  }
  EXPECT_THROW(estimate_noise_model(std::vector<Eigen::Vector3d>(50), 100.0),
               std::invalid_argument);
}

// ---- the long rest ---------------------------------------------------------------------------

TEST(NoiseModel, FindLongRest) {
  SimulationOptions so;
  so.protocol.steps_per_phase = 6;
  so.noise_density = 1e-3;
  PositionTable t = simulate_position_table(so);
  EXPECT_FALSE(find_long_rest(t).has_value());
  EXPECT_FALSE(find_long_rest(t, 120.0).has_value());
  so.protocol.initial_rest_s = 120.0;
  t = simulate_position_table(so);
  const std::vector<ScheduledPosition> schedule = build_schedule(so.protocol);
  EXPECT_NEAR(schedule.front().dwell_end_s - schedule.front().settled_s, 120.0, 1e-9);
  EXPECT_NEAR(schedule[1].dwell_end_s - schedule[1].settled_s, so.protocol.dwell_s, 1e-9);
  std::optional<LongRest> r = find_long_rest(t, 120.0);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->row, 0u);
  EXPECT_NE(r->reason.find("initial rest"), std::string::npos);
  // Without the protocol's figure: 10 x the median dwell serves (an old recording).
  r = find_long_rest(t);
  ASSERT_TRUE(r.has_value());
  EXPECT_NE(r->reason.find("median"), std::string::npos);
  // 15 s is not 10 x 2 s... but 25 s is.
  t.rows[0].t_end_s = t.rows[0].t_start_s + 15.0;
  EXPECT_FALSE(find_long_rest(t).has_value());
  t.rows[3].t_end_s = t.rows[3].t_start_s + 25.0;
  r = find_long_rest(t);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->row, 3u);
  // A tumble: the first rest of at least 30 s.
  for (DwellRecord& row : t.rows) row.orientation_unknown = true;
  EXPECT_FALSE(find_long_rest(t).has_value());
  t.rows[5].t_end_s = t.rows[5].t_start_s + 31.0;
  r = find_long_rest(t);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->row, 5u);
}

TEST(NoiseModel, LongRestRecorderKeepsTheRestOfALiveRun) {
  // A live run as the calibration node sees it: the assembler releases events and samples in
  // stamp order to the recorder, which accumulates the first dwell's samples only; its noise model
  // is the one of the whole recording's samples.
  SimulationOptions so;
  so.protocol.steps_per_phase = 6;
  so.protocol.initial_rest_s = 60.0;
  so.rate_hz = 50.0;
  so.bias_gm_sigma = 0.002;
  so.bias_gm_tau_s = 10.0;
  so.seed = 4;
  const Recording recording = simulate_recording(so);
  DwellAssembler assembler;
  LongRestRecorder recorder;
  assembler.set_release_observers([&recorder](const GimbalEvent& e) { recorder.add_command(e); },
                                  [&recorder](const ImuSample& s) { recorder.add_sample(s); });
  feed_in_stamp_order(recording, &assembler);
  const PositionTable& table = assembler.table();
  ASSERT_FALSE(table.rows.empty());
  // The dwell's samples, and one stamped with the MOVING that ends it (the rest's span is closed).
  EXPECT_GE(recorder.samples(), table.rows.front().n);
  EXPECT_LE(recorder.samples(), table.rows.front().n + 1);
  std::vector<double> stamps;
  std::vector<Eigen::Vector3d> outputs;
  for (const ImuSample& s : recording.samples) {
    stamps.push_back(s.stamp_s);
    outputs.push_back(s.outputs);
  }
  const std::optional<NoiseModel> whole = noise_model_of_run(table, stamps, outputs, 60.0);
  const std::optional<NoiseModel> kept = recorder.noise_model(table, 60.0);
  ASSERT_TRUE(whole.has_value());
  ASSERT_TRUE(kept.has_value());
  EXPECT_EQ(kept->rest_samples, whole->rest_samples);
  for (int s = 0; s < 3; ++s) {
    EXPECT_EQ(kept->axes[s].white_std, whole->axes[s].white_std);
    EXPECT_EQ(kept->axes[s].gm_sigma, whole->axes[s].gm_sigma);
  }
  EXPECT_FALSE(kept->white());
  // Started over: nothing kept until the next first SETTLED.
  recorder.clear();
  EXPECT_EQ(recorder.samples(), 0u);
  EXPECT_FALSE(recorder.noise_model(table, 60.0).has_value());
}

// ---- the issue's scenario ----------------------------------------------------------------------

// N = 24, 2 s dwells, a 120 s first dwell, a Gauss-Markov bias of 0.0015 m/s^2 and 30 s.
SimulationOptions issue_scenario(std::uint64_t seed) {
  SimulationOptions so;
  so.protocol.steps_per_phase = 24;
  so.protocol.dwell_s = 2.0;
  so.protocol.initial_rest_s = 120.0;
  so.noise_density = 300e-6 * kStandardGravity;
  so.bias_gm_sigma = 0.0015;
  so.bias_gm_tau_s = 30.0;
  so.seed = seed;
  return so;
}

// The noise model as a recorded run gives it: estimated from the first dwell's raw samples.
NoiseModel estimated_model(const PositionTable& table, const RestSamples& rest,
                           double initial_rest_s) {
  const std::optional<NoiseModel> m =
      noise_model_of_run(table, rest.stamps_s, rest.outputs, initial_rest_s);
  if (!m) throw std::runtime_error("no noise model");
  return *m;
}

struct Coverage {
  double sum_sq = 0.0;
  int count = 0;
  double rms() const { return std::sqrt(sum_sq / count); }
  void add(double z) {
    sum_sq += z * z;
    ++count;
  }
};

// z-scores of |u|, |v|, |w|, the three angles and the offsets against the truth.
void add_z(const FitResult& f, const SimulationOptions& so, Coverage* c, bool offsets) {
  const Intrinsics truth = intrinsics_from_vectors(so.truth.S);
  for (int s = 0; s < 3; ++s) {
    c->add((f.intrinsics.responsivity(s) - truth.responsivity(s)) /
           f.intrinsics.responsivity_std(s));
    c->add((f.intrinsics.angles_rad(s) - truth.angles_rad(s)) / f.intrinsics.angles_std_rad(s));
    if (offsets) c->add((f.O(s) - so.truth.O(s)) / f.O_std(s));
  }
}

TEST(CorrelatedNoise, CoverageOfTheReportedUncertaintiesGaussMarkov) {
  // 60 runs of the issue's scenario. With the white weights the z-scores spread far beyond 1
  // (the issue saw 5 sigma); with the noise model (true, and as estimated from the 120 s rest)
  // the RMS z-score is 1 within the chi-square band of 60 runs (per parameter; pooled over the
  // 9 parameters the bands below are conservative). The rest's model alone is about 20 % short
  // (a 120 s rest gives the slow part to about +-40 %): band 0.75 .. 1.35. As calibrate() fits
  // (slow_part_from_run: the rest's blocks and the dwells, the amplitude's posterior mean, the
  // covariance widened for the estimated scale) it is held to the band of the true model.
  // Measured when written: 0.95 true, 1.24 rest's model, 1.10 fitted to the run (1.23 with the
  // likelihood's maximum, no blocks and no widening).
  const int runs = 60;
  Coverage white, true_model, estimated, refined;
  for (int k = 0; k < runs; ++k) {
    const SimulationOptions so = issue_scenario(500 + static_cast<std::uint64_t>(k));
    RestSamples rest;
    const PositionTable table = simulate_position_table(so, &rest);
    FitOptions fo;
    add_z(fit(table, fo), so, &white, true);
    fo.noise_model = true_noise_model(so);
    const FitResult ft = fit(table, fo);
    EXPECT_EQ(ft.noise_model.kind(), "gauss_markov");
    ASSERT_TRUE(ft.correlation != nullptr);
    add_z(ft, so, &true_model, true);
    fo.noise_model = estimated_model(table, rest, so.protocol.initial_rest_s);
    add_z(fit(table, fo), so, &estimated, true);
    // As calibrate() fits: the rest's slow part fitted again to the run's dwell means.
    fo.noise_model = slow_part_from_run(table, fo);
    add_z(fit(table, fo), so, &refined, true);
  }
  std::cout << "[ INFO     ] Gauss-Markov coverage, RMS z over " << runs
            << " runs x 9 parameters: white " << white.rms() << ", true model " << true_model.rms()
            << ", estimated model " << estimated.rms() << ", estimated and fitted to the run "
            << refined.rms() << "\n";
  const std::pair<double, double> band = statistical_bounds::chi2_band(runs, 1e-3);
  const double lo = std::sqrt(band.first / runs), hi = std::sqrt(band.second / runs);
  EXPECT_GT(white.rms(), 1.5);  // the problem: white weights are overconfident
  EXPECT_GT(true_model.rms(), lo);
  EXPECT_LT(true_model.rms(), hi);
  EXPECT_GT(estimated.rms(), 0.75);
  EXPECT_LT(estimated.rms(), 1.35);
  EXPECT_GT(refined.rms(), lo);
  EXPECT_LT(refined.rms(), hi);
}

TEST(CorrelatedNoise, CoverageOfTheReportedUncertaintiesRandomWalk) {
  // A random-walk bias (1e-4 (m/s^2)/sqrt(s): 2 mm/s^2 after 400 s). Responsivities and angles,
  // with the true model and as calibrate() reports (the rest's model fitted again to the run),
  // and the offsets apart, all held to the chi-square band. Measured when written: white 1.84,
  // true model 1.02, fitted to the run 0.96; offsets true model 1.02, fitted to the run 0.91.
  // The offsets carry the walk's excursion over the run, so they rest on the walk's density,
  // which one run pins only to tens of percent: with the likelihood's maximum as the amplitude
  // they were at 2.27 (a third of the axes found next to no walk), 1.98 with the covariance
  // widened for the estimated scale, 1.26 with the posterior mean, 0.91 with the rest's blocks.
  const int runs = 60;
  Coverage white, true_model, refined, refined_offsets, true_offsets;
  for (int k = 0; k < runs; ++k) {
    SimulationOptions so = issue_scenario(900 + static_cast<std::uint64_t>(k));
    so.bias_gm_sigma = 0.0;
    so.bias_random_walk = 1e-4;
    RestSamples rest;
    const PositionTable table = simulate_position_table(so, &rest);
    FitOptions fo;
    add_z(fit(table, fo), so, &white, false);
    fo.noise_model = true_noise_model(so);
    EXPECT_EQ(fo.noise_model.kind(), "random_walk");
    const FitResult ft = fit(table, fo);
    add_z(ft, so, &true_model, false);
    for (int s = 0; s < 3; ++s) true_offsets.add((ft.O(s) - so.truth.O(s)) / ft.O_std(s));
    // As calibrate() reports: the rest's model fitted again to the run.
    fo.noise_model = estimated_model(table, rest, so.protocol.initial_rest_s);
    fo.noise_model = slow_part_from_run(table, fo);
    EXPECT_NE(fo.noise_model.source.find("the long rest's 30 blocks"), std::string::npos)
        << fo.noise_model.source;
    const FitResult fr = fit(table, fo);
    add_z(fr, so, &refined, false);
    for (int s = 0; s < 3; ++s) refined_offsets.add((fr.O(s) - so.truth.O(s)) / fr.O_std(s));
  }
  std::cout << "[ INFO     ] random-walk coverage, RMS z over " << runs
            << " runs x 6 parameters: white " << white.rms() << ", true model " << true_model.rms()
            << ", estimated and fitted to the run " << refined.rms() << "; offsets: true model "
            << true_offsets.rms() << ", fitted to the run " << refined_offsets.rms() << "\n";
  const std::pair<double, double> band = statistical_bounds::chi2_band(runs, 1e-3);
  const double lo = std::sqrt(band.first / runs), hi = std::sqrt(band.second / runs);
  EXPECT_GT(white.rms(), 1.3);
  EXPECT_GT(true_model.rms(), lo);
  EXPECT_LT(true_model.rms(), hi);
  EXPECT_GT(refined.rms(), lo);
  EXPECT_LT(refined.rms(), hi);
  EXPECT_GT(true_offsets.rms(), lo);
  EXPECT_LT(true_offsets.rms(), hi);
  EXPECT_GT(refined_offsets.rms(), lo);
  EXPECT_LT(refined_offsets.rms(), hi);
  // These seeds' figure without the rest's blocks (1.26) is inside the band too: held apart.
  EXPECT_LT(refined_offsets.rms(), 1.15);
}

// ---- the hand tumble under a slow bias
// -----------------------------------------------------------

// A hand tumble (30 poses, 3.5-5 s rests, a 120 s first rest as the README recommends) with a
// slow bias; its rests found
// in the stream as offline_fit finds them.
struct SlowTumble {
  TumbleSimulationOptions options;
  PositionTable table;
  std::vector<double> stamps;
  std::vector<Eigen::Vector3d> outputs;
};

SlowTumble slow_tumble(std::uint64_t seed, double gm_sigma, double gm_tau_s, double random_walk,
                       const std::vector<Effect>& effects = {}) {
  SlowTumble t;
  t.options.truth = random_tumble_device(3000 + seed);
  t.options.truth.effects = effects;
  t.options.seed = seed;
  t.options.poses = 30;
  t.options.initial_rest_s = 120.0;
  t.options.rest_min_s = 3.5;
  t.options.rest_max_s = 5.0;
  t.options.bias_gm_sigma = gm_sigma;
  t.options.bias_gm_tau_s = gm_tau_s;
  t.options.bias_random_walk = random_walk;
  const TumbleRecording rec = simulate_hand_tumble(t.options);
  t.table.rows = detect_rests(rec.samples).rests;
  for (const ImuSample& s : rec.samples) {
    t.stamps.push_back(s.stamp_s);
    t.outputs.push_back(s.outputs);
  }
  return t;
}

TEST(CorrelatedNoise, TumbleSimulatorSlowBiasIsTheGimbalSimulatorsProcess) {
  // The white draws of a seed are the same with the bias on; the difference of the two streams
  // is the slow bias, whose first-rest Allan fit finds a slow part.
  SlowTumble plain = slow_tumble(5, 0.0, 0.0, 0.0);
  SlowTumble biased = slow_tumble(5, 0.003, 20.0, 0.0);
  ASSERT_EQ(plain.outputs.size(), biased.outputs.size());
  SlowBiasProcess process(0.003, 20.0, 0.0, 5);
  const double dt = 1.0 / plain.options.rate_hz;
  Eigen::Vector3d b = process.value();
  for (std::size_t k = 0; k < plain.outputs.size(); ++k) {
    if (k > 0) b = process.advance(dt);
    if (k % 997 == 0) {
      EXPECT_LT((biased.outputs[k] - plain.outputs[k] - b).norm(), 1e-12) << k;
    }
  }
  const TumbleSimulationOptions& o = biased.options;
  EXPECT_EQ(true_noise_model(o).kind(), "gauss_markov");
  EXPECT_TRUE(true_noise_model(plain.options).white());
  TumbleSimulationOptions bad = o;
  bad.bias_gm_tau_s = 0.0;
  EXPECT_THROW(simulate_hand_tumble(bad), std::invalid_argument);
}

// The tumble's reported uncertainties under a slow bias, the tumble fit being generalized least
// squares across the rests with a noise model (tumble.h). RMS z-scores over 60 runs,
// responsivities and angles apart from the offsets (white / true model / estimated from the
// 120 s rest; seeds 6000.. and 7000..). Measured when written:
//   Gauss-Markov 0.003 m/s^2, 30 s: intrinsics 1.05 / 0.95 / 1.03, offsets 1.79 / 0.96 / 0.91
//   random walk 2e-4 (m/s^2)/sqrt(s): intrinsics 1.23 / 1.00 / 1.07, offsets 4.64 / 0.93 / 2.55
// Before, with each rest's variance inflated by its slow part alone (no correlation between
// rests): Gauss-Markov intrinsics 0.81 / 0.92, offsets 1.47 / 1.75; random walk intrinsics
// 1.04 / 1.07, offsets 4.80 / 4.65: the offsets were not covered, as neighbouring rests err
// together. With GLS everything is covered but the random walk's offsets with the estimated
// model: the offsets carry the walk's whole excursion over the 5 min run, and a 120 s rest sees a
// walk poorly (over seeds 7000..7007 the rest's fit found a walk on 16 of the 24 axes, a
// Gauss-Markov part instead on 6, mostly at the grid's lowest 0.5 s, and nothing on 2), so its
// model is usually short of the run's slow variance.
// The cure calibrate() applies, tumble.h slow_part_from_tumble: the slow part fitted again to the
// rest's blocks and the other rests together, a random walk kept where the data do not reject it
// with its amplitude's posterior mean (slow_part_fit.h best_slow_amplitude; fourth figure,
// measured when written): Gauss-Markov intrinsics 1.07, offsets 0.81; random walk intrinsics
// 1.00, offsets 0.91. Before, with the likelihood's maximum as the amplitude: random-walk offsets
// 1.32 (the walk's density comes from about ten rests per axis, +-45 % over seeds 7000..7009,
// and the maximum sits low on many); tried before the walk rule: the best shape by likelihood
// alone, offsets 1.14 / 2.17; the rests alone without the rest's blocks, 1.74 / 3.35.
struct TumbleCoverage {
  // white, true model, estimated from the rest, estimated and fitted to the run (as calibrate())
  Coverage intrinsics[4];
  Coverage offsets[4];
};

TumbleCoverage tumble_coverage(double gm_sigma, double gm_tau_s, double random_walk,
                               std::uint64_t seed0, int runs) {
  TumbleCoverage c;
  for (int k = 0; k < runs; ++k) {
    const SlowTumble t =
        slow_tumble(seed0 + static_cast<std::uint64_t>(k), gm_sigma, gm_tau_s, random_walk);
    const std::optional<NoiseModel> estimated = noise_model_of_run(t.table, t.stamps, t.outputs);
    if (!estimated) throw std::runtime_error("no first rest of 30 s found");
    const NoiseModel models[4] = {NoiseModel(), true_noise_model(t.options), *estimated,
                                  slow_part_from_tumble(t.table, *estimated)};
    const Intrinsics in = intrinsics_from_vectors(t.options.truth.S);
    for (int m = 0; m < 4; ++m) {
      FitOptions fo;
      fo.noise_model = models[m];
      const FitResult f = fit(t.table, fo);
      for (int s = 0; s < 3; ++s) {
        c.intrinsics[m].add((f.intrinsics.responsivity(s) - in.responsivity(s)) /
                            f.intrinsics.responsivity_std(s));
        c.intrinsics[m].add((f.intrinsics.angles_rad(s) - in.angles_rad(s)) /
                            f.intrinsics.angles_std_rad(s));
        c.offsets[m].add((f.O(s) - t.options.truth.O(s)) / f.O_std(s));
      }
    }
  }
  std::cout << "[ INFO     ] tumble RMS z (white, true model, rest's model, fitted to the run): "
               "intrinsics "
            << c.intrinsics[0].rms() << " " << c.intrinsics[1].rms() << " " << c.intrinsics[2].rms()
            << " " << c.intrinsics[3].rms() << ", offsets " << c.offsets[0].rms() << " "
            << c.offsets[1].rms() << " " << c.offsets[2].rms() << " " << c.offsets[3].rms() << "\n";
  return c;
}

TEST(CorrelatedNoise, TumbleCoverageGaussMarkov) {
  const int runs = 60;
  const TumbleCoverage c = tumble_coverage(0.003, 30.0, 0.0, 6000, runs);
  const std::pair<double, double> band = statistical_bounds::chi2_band(runs, 1e-3);
  const double lo = std::sqrt(band.first / runs), hi = std::sqrt(band.second / runs);
  for (int m : {1, 2, 3}) {
    EXPECT_GT(c.intrinsics[m].rms(), lo) << m;
    EXPECT_LT(c.intrinsics[m].rms(), hi) << m;
    EXPECT_GT(c.offsets[m].rms(), lo) << m;
    EXPECT_LT(c.offsets[m].rms(), hi) << m;
  }
  EXPECT_GT(c.offsets[0].rms(), hi);  // white weights: the problem the model solves
}

TEST(CorrelatedNoise, TumbleCoverageRandomWalk) {
  const int runs = 60;
  const TumbleCoverage c = tumble_coverage(0.0, 0.0, 2e-4, 7000, runs);
  const std::pair<double, double> band = statistical_bounds::chi2_band(runs, 1e-3);
  const double lo = std::sqrt(band.first / runs), hi = std::sqrt(band.second / runs);
  for (int m : {1, 2, 3}) {
    EXPECT_GT(c.intrinsics[m].rms(), lo) << m;
    EXPECT_LT(c.intrinsics[m].rms(), hi) << m;
  }
  // The offsets: covered with the true model and fitted to the run as calibrate() does; with the
  // rest's estimate only better than white.
  EXPECT_GT(c.offsets[1].rms(), lo);
  EXPECT_LT(c.offsets[1].rms(), hi);
  EXPECT_GT(c.offsets[0].rms(), hi);
  EXPECT_LT(c.offsets[2].rms(), c.offsets[0].rms());
  EXPECT_GT(c.offsets[3].rms(), lo);
  EXPECT_LT(c.offsets[3].rms(), hi);
}

// The covariance widened for an estimated slow scale (noise.h estimated_scale_covariance) against
// what it stands for: Kackar and Harville's term Phi (Q - P Phi P) Phi is E[d d^T], d the
// derivative of the GLS estimate by the slow part's scale at fixed data. Here d comes from the
// fit itself, by central differences of the scale, over dwell means drawn in the test from the
// model's covariance (the Cholesky factor of each accelerometer's C = D R D), and its mean
// outer product is held to the widening the fit reports with a relative variance of 1 per axis
// ((Phi_A - Phi) / 2, noise-free means so that no chi-square scale enters).
TEST(CorrelatedNoise, WideningForAnEstimatedScaleIsTheEstimatesSensitivity) {
  SimulationOptions so;
  so.protocol.steps_per_phase = 12;
  so.protocol.dwell_s = 2.0;
  so.protocol.initial_rest_s = 30.0;
  so.noise_density = 0.0;
  PositionTable exact = simulate_position_table(so);
  for (DwellRecord& row : exact.rows) row.std = Eigen::Vector3d(0.02, 0.03, 0.025);
  NoiseModel model;
  model.axes[0] = {0.02, 0.0, 0.0, 2e-4};     // a walk on u
  model.axes[1] = {0.03, 0.002, 20.0, 0.0};   // Gauss-Markov on v
  model.axes[2] = {0.025, 0.001, 5.0, 1e-4};  // both on w
  FitOptions fo;
  fo.noise_model = model;
  const FitResult plain = fit(exact, fo);
  for (AxisNoiseModel& a : fo.noise_model.axes) a.slow_scale_rel_var = 1.0;
  const FitResult widened = fit(exact, fo);
  ASSERT_EQ(plain.reduced_chi2, widened.reduced_chi2);
  const Eigen::Matrix<double, 12, 12> expected = 0.5 * (widened.covariance - plain.covariance);
  EXPECT_GT(expected.diagonal().minCoeff(), 0.0);

  const std::vector<Eigen::Vector3d> se = dwell_standard_errors(exact);
  const std::shared_ptr<const DwellCorrelation> corr = dwell_correlation(exact, se, model);
  ASSERT_TRUE(corr != nullptr);
  auto scaled = [&](double factor) {
    FitOptions f;
    f.noise_model = model;
    for (AxisNoiseModel& a : f.noise_model.axes) {
      a.gm_sigma *= std::sqrt(factor);
      a.rw_density *= std::sqrt(factor);
    }
    return f;
  };
  const double eps = 1e-3;
  const FitOptions up = scaled(1.0 + eps), down = scaled(1.0 - eps);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int draws = 600;
  const Eigen::Index n = static_cast<Eigen::Index>(exact.rows.size());
  Eigen::Matrix<double, 12, 12> sum = Eigen::Matrix<double, 12, 12>::Zero();
  for (int k = 0; k < draws; ++k) {
    PositionTable noisy = exact;
    for (int s = 0; s < 3; ++s) {
      Eigen::VectorXd xi(n);
      for (Eigen::Index i = 0; i < n; ++i) xi(i) = normal(rng);
      const Eigen::VectorXd e = corr->L[s] * xi;
      for (Eigen::Index i = 0; i < n; ++i)
        noisy.rows[static_cast<std::size_t>(i)].mean(s) +=
            se[static_cast<std::size_t>(i)](s) * e(i);
    }
    const FitResult a = fit(noisy, up), b = fit(noisy, down);
    Eigen::Matrix<double, 12, 1> d;
    for (int j = 0; j < 9; ++j) d(j) = (a.S(j / 3, j % 3) - b.S(j / 3, j % 3)) / (2.0 * eps);
    for (int s = 0; s < 3; ++s) d(9 + s) = (a.O(s) - b.O(s)) / (2.0 * eps);
    sum += d * d.transpose();
  }
  const Eigen::Matrix<double, 12, 12> measured = sum / draws;
  // Each diagonal entry is a mean of 600 squares of a Gaussian: +-6 % (1 sigma); 25 % allowed.
  for (int j = 0; j < 12; ++j) {
    SCOPED_TRACE(j);
    EXPECT_NEAR(measured(j, j) / expected(j, j), 1.0, 0.25);
  }
  // That the test measures something: the walking u offset's widening is a visible part of its
  // variance (7 % here at a relative variance of 1).
  EXPECT_GT(expected(9, 9), 0.03 * plain.covariance(9, 9));
}

// A hand tumble under a random-walk bias written here from the equations, not by the tumble
// simulator: a device S, O of the test's own, a 120 s first rest and 30 poses of random
// orientation (3.5-5 s each), joined by 2 s turns (the gravity direction swept between poses with
// a hand's 3 Hz shake on top), every sample y = S (g up) + O + b + white, b a random walk summed
// here sample by sample. offline_fit's path runs on it: rests found in the stream, the noise
// model of the first rest, calibrate() (the slow part fitted to the tumble, the GLS fit). Over
// 40 tumbles the RMS z-scores of the responsivities and angles and of the offsets against the
// truth lie in the chi-square band. Measured when written: intrinsics 0.95, offsets 0.95. (It
// found that a first rest whose Allan fit looks white must not veto the slow part: on one of
// the 40 tumbles the rest's model was white on all three axes and that tumble's offsets were off
// by 10 sigma; the offsets' RMS z was 1.37 before NoiseModel::slow_part_to_fit.)
TEST(CorrelatedNoise, TumbleWrittenInTheTestWithARandomWalkIsCovered) {
  const double rate = 100.0, g = kStandardGravity, white = 0.03, walk = 2e-4;
  const int runs = 40;
  Coverage intrinsics, offsets;
  int walking_axes = 0;
  for (int k = 0; k < runs; ++k) {
    std::mt19937_64 rng(40000 + static_cast<std::uint64_t>(k));
    std::normal_distribution<double> normal(0.0, 1.0);
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) S(r, c) += (r == c ? 0.02 : 0.005) * normal(rng);
    const Eigen::Vector3d O(0.1 * normal(rng), 0.1 * normal(rng), 0.1 * normal(rng));
    auto random_up = [&]() {
      Eigen::Vector3d v(normal(rng), normal(rng), normal(rng));
      return v.normalized();
    };
    std::vector<ImuSample> samples;
    Eigen::Vector3d bias = Eigen::Vector3d::Zero();
    double t = 0.0;
    auto emit = [&](const Eigen::Vector3d& specific_force) {
      ImuSample x;
      x.stamp_s = t;
      for (int a = 0; a < 3; ++a) bias(a) += walk / std::sqrt(rate) * normal(rng);
      x.outputs = S * specific_force + O + bias;
      for (int a = 0; a < 3; ++a) x.outputs(a) += white * normal(rng);
      samples.push_back(x);
      t += 1.0 / rate;
    };
    Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
    for (int i = 0; i < static_cast<int>(120.0 * rate); ++i) emit(g * up);
    for (int pose = 0; pose < 30; ++pose) {
      const Eigen::Vector3d next = random_up();
      const int turn = static_cast<int>(2.0 * rate);
      for (int i = 1; i <= turn; ++i) {
        const double f = static_cast<double>(i) / turn;
        const double smooth = f * f * (3.0 - 2.0 * f);
        const Eigen::Vector3d dir = ((1.0 - smooth) * up + smooth * next).normalized();
        const double shake = 0.5 * std::sin(2.0 * M_PI * 3.0 * f * 2.0) * std::sin(M_PI * f);
        emit(g * dir + Eigen::Vector3d(shake, -shake, 0.5 * shake));
      }
      up = next;
      const int rest = static_cast<int>((3.5 + 1.5 * uniform(rng)) * rate);
      for (int i = 0; i < rest; ++i) emit(g * up);
    }
    PositionTable table;
    table.rows = detect_rests(samples).rests;
    ASSERT_GE(table.rows.size(), 25u) << k;
    std::vector<double> stamps;
    std::vector<Eigen::Vector3d> outputs;
    for (const ImuSample& x : samples) {
      stamps.push_back(x.stamp_s);
      outputs.push_back(x.outputs);
    }
    const std::optional<NoiseModel> model = noise_model_of_run(table, stamps, outputs);
    ASSERT_TRUE(model.has_value()) << k;
    CalibrateOptions options;
    options.fit.noise_model = *model;
    const CalibrationReport report = calibrate(table, nullptr, options);
    const FitResult& f = report.base_fit;
    ASSERT_EQ(f.model, FitModel::Tumble);
    for (int a = 0; a < 3; ++a)
      if (f.noise_model.axes[a].rw_density > 0.0) ++walking_axes;
    const Intrinsics truth = intrinsics_from_vectors(S);
    for (int a = 0; a < 3; ++a) {
      intrinsics.add((f.intrinsics.responsivity(a) - truth.responsivity(a)) /
                     f.intrinsics.responsivity_std(a));
      intrinsics.add((f.intrinsics.angles_rad(a) - truth.angles_rad(a)) /
                     f.intrinsics.angles_std_rad(a));
      offsets.add((f.O(a) - O(a)) / f.O_std(a));
    }
  }
  std::cout << "[ INFO     ] random-walk tumbles written in the test: RMS z intrinsics "
            << intrinsics.rms() << ", offsets " << offsets.rms() << "; a walk kept on "
            << walking_axes << " of " << 3 * runs << " axes\n";
  const std::pair<double, double> band = statistical_bounds::chi2_band(runs, 1e-3);
  const double lo = std::sqrt(band.first / runs), hi = std::sqrt(band.second / runs);
  EXPECT_GT(intrinsics.rms(), lo);
  EXPECT_LT(intrinsics.rms(), hi);
  EXPECT_GT(offsets.rms(), lo);
  EXPECT_LT(offsets.rms(), hi);
}

// The price of the posterior mean (slow_part_fit.h best_slow_amplitude) and of fitting a slow
// part to every run whose rest was recorded: on white data the run cannot exclude a small slow
// part, and the fit keeps what it cannot exclude. 40 gimbal runs of the issue's scenario with
// white noise only, calibrated as offline_fit does: the responsivities' standard uncertainties
// stay near the white fit's (median ratio at most 1.2), the offsets' grow by the walk the run
// cannot exclude (median ratio about 4; bounded here at 5 so that it cannot grow unnoticed), and
// the uncertainties are never overconfident (RMS z of the nine intrinsics and offsets below the
// chi-square band's top; it sits near its bottom). Measured when written: responsivities' median
// ratio 1.10, offsets' 3.83, RMS z 0.73 (a 300 s rest: 1.04, 3.83, 0.77).
TEST(CorrelatedNoise, WhiteRunWithARecordedRestPaysForTheSlowPartItCannotExclude) {
  const int runs = 40;
  Coverage coverage;
  std::vector<double> responsivity_ratios, offset_ratios;
  for (int k = 0; k < runs; ++k) {
    SimulationOptions so = issue_scenario(41000 + static_cast<std::uint64_t>(k));
    so.bias_gm_sigma = 0.0;
    RestSamples rest;
    const PositionTable table = simulate_position_table(so, &rest);
    CalibrateOptions options;
    options.fit.noise_model = estimated_model(table, rest, so.protocol.initial_rest_s);
    const CalibrationReport report = calibrate(table, nullptr, options);
    const FitResult white = fit(table, FitOptions());
    add_z(report.base_fit, so, &coverage, true);
    for (int s = 0; s < 3; ++s) {
      responsivity_ratios.push_back(report.base_fit.intrinsics.responsivity_std(s) /
                                    white.intrinsics.responsivity_std(s));
      offset_ratios.push_back(report.base_fit.O_std(s) / white.O_std(s));
    }
  }
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  std::cout << "[ INFO     ] white runs with a recorded rest: RMS z " << coverage.rms()
            << ", median std ratio to the white fit: responsivities " << median(responsivity_ratios)
            << ", offsets " << median(offset_ratios) << "\n";
  const std::pair<double, double> band = statistical_bounds::chi2_band(runs, 1e-3);
  EXPECT_LT(coverage.rms(), std::sqrt(band.second / runs));
  EXPECT_LT(median(responsivity_ratios), 1.2);
  EXPECT_GT(median(offset_ratios), 1.0);
  EXPECT_LT(median(offset_ratios), 5.0);
}

// GLS with a slow part too small to matter is the white fit: the residuals' covariance built from
// the rests' gradients reduces to the white sigmas (tumble fit and analysis alike).
TEST(CorrelatedNoise, TumbleGlsWithAVanishingSlowPartIsTheWhiteFit) {
  const SlowTumble t = slow_tumble(8200, 0.0, 0.0, 0.0);
  NoiseModel tiny = true_noise_model(t.options);
  for (AxisNoiseModel& a : tiny.axes) {
    a.gm_sigma = 1e-9;
    a.gm_tau_s = 30.0;
  }
  FitOptions fo;
  const FitResult white = fit(t.table, fo);
  fo.noise_model = tiny;
  const FitResult gls = fit(t.table, fo);
  EXPECT_EQ(gls.noise_model.kind(), "gauss_markov");
  EXPECT_TRUE(white.noise_model.white());
  EXPECT_NEAR(gls.chi2, white.chi2, 1e-6 * white.chi2);
  for (int s = 0; s < 3; ++s) {
    EXPECT_NEAR(gls.O(s), white.O(s), 1e-6 * white.O_std(s)) << s;
    EXPECT_NEAR(gls.O_std(s), white.O_std(s), 1e-6 * white.O_std(s)) << s;
    EXPECT_NEAR(gls.intrinsics.responsivity(s), white.intrinsics.responsivity(s),
                1e-6 * white.intrinsics.responsivity_std(s))
        << s;
  }
  const FitResult white_e = fit_tumble_with_effects(t.table, {}, kStandardGravity);
  const FitResult gls_e = fit_tumble_with_effects(t.table, {}, kStandardGravity, tiny);
  EXPECT_TRUE(gls_e.correlation != nullptr);
  EXPECT_NEAR(gls_e.chi2, white_e.chi2, 1e-6 * white_e.chi2);
  for (int s = 0; s < 3; ++s) {
    EXPECT_NEAR(gls_e.O(s), white_e.O(s), 1e-4 * white_e.O_std(s)) << s;
    EXPECT_NEAR(gls_e.O_std(s), white_e.O_std(s), 1e-4 * white_e.O_std(s)) << s;
  }
}

// Under a slow bias the two forms of the tumble fit (the scalar |P (m - O)| - g linearized in the
// mean, and the 3-vector form with a nuisance direction per rest) are the same GLS estimate to
// first order: the scalar residual is the contrast of the rest's mean that the direction cannot
// absorb (c_i^T S t = 0 for every t tangent to the sphere at the rest's direction).
TEST(CorrelatedNoise, TumbleGlsBaseFormAgreesWithTheTumbleFit) {
  const SlowTumble t = slow_tumble(8300, 0.003, 30.0, 0.0);
  FitOptions fo;
  fo.noise_model = true_noise_model(t.options);
  const FitResult a = fit(t.table, fo);
  const FitResult b = fit_tumble_with_effects(t.table, {}, kStandardGravity, fo.noise_model);
  EXPECT_EQ(a.dof, b.dof);
  EXPECT_NEAR(a.chi2, b.chi2, 0.01 * a.chi2);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(a.intrinsics.responsivity(k), b.intrinsics.responsivity(k),
                0.1 * a.intrinsics.responsivity_std(k));
    EXPECT_NEAR(a.intrinsics.responsivity_std(k), b.intrinsics.responsivity_std(k),
                0.1 * a.intrinsics.responsivity_std(k));
    EXPECT_NEAR(a.O(k), b.O(k), 0.1 * a.O_std(k));
    EXPECT_NEAR(a.O_std(k), b.O_std(k), 0.1 * a.O_std(k));
  }
  // The residuals reported are those of the means (measured minus model), not whitened ones:
  // whitened again with the result's correlation they give its chi2.
  ASSERT_TRUE(b.correlation != nullptr);
  Eigen::VectorXd z(3 * static_cast<Eigen::Index>(b.residuals.size()));
  for (std::size_t i = 0; i < b.residuals.size(); ++i)
    z.segment<3>(3 * static_cast<Eigen::Index>(i)) =
        b.residuals[i].cwiseQuotient(b.standard_errors[i]);
  const double unwhitened_chi2 = z.squaredNorm();
  b.correlation->whiten(z);
  EXPECT_NEAR(z.squaredNorm(), b.chi2, 1e-9 * b.chi2);
  EXPECT_GT(unwhitened_chi2, 2.0 * b.chi2);  // the slow bias: far above the white expectation
}

TEST(CorrelatedNoise, TumbleAnalysisWeighsTheRestsWithTheNoiseModel) {
  // Effect-free tumbles under a Gauss-Markov bias (seeds 8000..), analysed with the noise model
  // estimated from the first rest: every fit is GLS across the rests, its chi-square below the
  // white one (the first 40 also with white weights). An effect is named in at most the binomial
  // (1 - 1e-3) quantile at alpha. Measured when written: 5 of 200 with the rest's slow part fitted
  // again to the tumble as calibrate() does (7 of 200 with the rest's model alone: 4 cubic and 2
  // quadratic non-linearities, 1 offset drift), white weights 6 of 40; under a random walk 2 of
  // 100; before GLS (each rest's
  // variance inflated by its slow part) 4 of the first 40 and about 7.5 % over seeds 6000.. too,
  // mostly offset_drift: the rests' correlation read as a drift.
  // A hidden quadratic non-linearity is still named; calibrate() hands the fit's noise model to
  // the analysis.
  const int runs = 200, white_runs = 40;
  int named_white = 0, named_model = 0;
  TumbleAnalysisOptions ao;
  for (int k = 0; k < runs; ++k) {
    const SlowTumble t = slow_tumble(8000 + static_cast<std::uint64_t>(k), 0.003, 30.0, 0.0);
    const std::optional<NoiseModel> m = noise_model_of_run(t.table, t.stamps, t.outputs);
    ASSERT_TRUE(m.has_value());
    TumbleAnalysisOptions with_model = ao;
    with_model.noise_model = slow_part_from_tumble(t.table, *m);  // as calibrate() does
    const TumbleAnalysis a = analyze_tumble(t.table, with_model);
    EXPECT_EQ(a.noise_model.source, with_model.noise_model.source);
    if (!a.named.empty()) ++named_model;
    if (k >= white_runs) continue;
    const TumbleAnalysis white = analyze_tumble(t.table, ao);
    if (!white.named.empty()) ++named_white;
    EXPECT_LT(a.before.chi2, white.before.chi2);
  }
  std::cout << "[ INFO     ] effect-free slow-bias tumbles naming an effect: white weights "
            << named_white << "/" << white_runs << ", estimated model " << named_model << "/"
            << runs << "\n";
  EXPECT_LE(named_model, statistical_bounds::binomial_upper(runs, ao.alpha, 1e-3));

  // The same under a random-walk bias (2e-4 (m/s^2)/sqrt(s), seeds 8500..): the walk kept where
  // the data do not reject it must not turn into named drifts.
  const int walk_runs = 100;
  int named_walk = 0;
  for (int k = 0; k < walk_runs; ++k) {
    const SlowTumble t = slow_tumble(8500 + static_cast<std::uint64_t>(k), 0.0, 0.0, 2e-4);
    const std::optional<NoiseModel> m = noise_model_of_run(t.table, t.stamps, t.outputs);
    ASSERT_TRUE(m.has_value());
    TumbleAnalysisOptions with_model = ao;
    with_model.noise_model = slow_part_from_tumble(t.table, *m);
    if (!analyze_tumble(t.table, with_model).named.empty()) ++named_walk;
  }
  std::cout << "[ INFO     ] effect-free random-walk tumbles naming an effect: " << named_walk
            << "/" << walk_runs << "\n";
  EXPECT_LE(named_walk, statistical_bounds::binomial_upper(walk_runs, ao.alpha, 1e-3));

  const Effect hidden = make_effect("quadratic_nonlinearity", "v", 4e-4);
  const SlowTumble t = slow_tumble(8100, 0.003, 30.0, 0.0, {hidden});
  CalibrateOptions co;
  co.analyze = true;
  co.fit.noise_model = *noise_model_of_run(t.table, t.stamps, t.outputs);
  const CalibrationReport report = calibrate(t.table, nullptr, co);
  ASSERT_TRUE(report.tumble_analysis.has_value()) << report.analysis_error;
  EXPECT_FALSE(report.tumble_analysis->noise_model.white());
  ASSERT_FALSE(report.tumble_analysis->named.empty()) << report.tumble_analysis->stop_reason;
  EXPECT_EQ(report.tumble_analysis->named.front().effect.label(), hidden.label());
}

// ---- the analysis under a slow bias ------------------------------------------------------------

AnalysisOptions quick_analysis(const NoiseModel& model) {
  AnalysisOptions ao;
  ao.noise_model = model;
  ao.monte_carlo_draws = 2000;
  return ao;
}

TEST(CorrelatedNoise, IssueScenarioNamesNoPhysicalEffect) {
  // The issue's run: white weights name false effects; with the noise model estimated from the
  // 120 s rest nothing physical is named, and correlated_noise is.
  const SimulationOptions so = issue_scenario(23);
  RestSamples rest;
  const PositionTable table = simulate_position_table(so, &rest);
  const NoiseModel m = estimated_model(table, rest, 120.0);
  const AnalysisResult a = analyze(table, quick_analysis(m));
  EXPECT_TRUE(a.effects.empty()) << a.effects.front().effect.label();
  EXPECT_EQ(a.noise_model.kind().find("gauss_markov"), 0u) << a.noise_model.kind();
  EXPECT_TRUE(a.correlated_noise.named) << a.correlated_noise.reason;
  EXPECT_LT(a.correlated_noise.white_p_value, 0.025);  // white weights: the gap is "significant"
  EXPECT_TRUE(std::isfinite(a.before.cv.cv_chi2_per_point));
  EXPECT_EQ(a.before.cv.folds, 5);
}

TEST(CorrelatedNoise, FalseAlarmRateOnEffectFreeCorrelatedNoise) {
  // Effect-free runs of the issue's scenario, analysed with the noise model (a) true (seeds
  // 1000..1079) and (b) estimated from the 120 s rest (seeds 1000..1159): each must name something
  // in at most the binomial 1 - 1e-3 quantile at alpha (plus the Monte Carlo allowance of the
  // max-T calibration). (b) holds because the analysis fits the slow part again to the whole
  // run's dwell means (slow_part_from_run): the rest alone cannot tell a 30 s Gauss-Markov bias
  // from a 3 s one or a random walk, and with the rest's model taken as known 9 of 80 runs named
  // an effect (11 %). 160 runs, so that a rate of 11 % would fail here (bound 15 of 160).
  // Measured when written: (a) 2 of 80, (b) 3 of 160, white weights 10 of 10.
  const int runs_true = 80, runs_estimated = 160;
  const AnalysisOptions defaults = quick_analysis(NoiseModel());
  const double p = defaults.alpha + 4.0 * std::sqrt(defaults.alpha * (1.0 - defaults.alpha) /
                                                    defaults.monte_carlo_draws);
  int named_true = 0, named_estimated = 0, named_white = 0;
  for (int k = 0; k < runs_estimated; ++k) {
    const SimulationOptions so = issue_scenario(1000 + static_cast<std::uint64_t>(k));
    RestSamples rest;
    const PositionTable table = simulate_position_table(so, &rest);
    if (k < runs_true && !analyze(table, quick_analysis(true_noise_model(so))).effects.empty())
      ++named_true;
    const NoiseModel m = estimated_model(table, rest, 120.0);
    if (!analyze(table, quick_analysis(m)).effects.empty()) ++named_estimated;
    if (k < 10 && !analyze(table, quick_analysis(NoiseModel())).effects.empty()) ++named_white;
  }
  std::cout << "[ INFO     ] effect-free Gauss-Markov runs naming an effect: true model "
            << named_true << "/" << runs_true << ", estimated model " << named_estimated << "/"
            << runs_estimated << ", white weights " << named_white << "/10\n";
  EXPECT_LE(named_true, statistical_bounds::binomial_upper(runs_true, p, 1e-3));
  EXPECT_LE(named_estimated, statistical_bounds::binomial_upper(runs_estimated, p, 1e-3));
  EXPECT_GE(named_white, 5);  // the problem the noise model solves
}

// The detection threshold of `kind` on `target` under the noise model: from the first screening
// step of an effect-free run (the candidate's linearized std under GLS, and the max-T critical
// value).
double gls_threshold(const PositionTable& table, const NoiseModel& m, EffectKind kind, int target) {
  const AnalysisResult a = analyze(table, quick_analysis(m));
  for (const CandidateScore& c : a.steps.front().candidates)
    if (c.effect.kind == kind && c.effect.target == target) return c.detection_threshold;
  return 0.0;
}

TEST(CorrelatedNoise, HiddenEffectsAreNamedUnderCorrelatedNoise) {
  // A quadratic non-linearity on v at 4 times its detection threshold under the estimated noise
  // model, and a real linear offset drift on w at 8 times, hidden under the issue's slow bias:
  // the analysis names each first, and the out-of-sample gap drops when it is added. A drift
  // needs more: the slow part fitted to the run (slow_part_from_run) takes part of a drift for
  // slow noise. Measured when written, seeds 31..36: a drift at 4 times named in 2 of 6, at 6
  // times in 5 of 6, at 8 times in 6 of 6.
  struct Case {
    EffectKind kind;
    int target;
    double times_threshold;
  };
  // A second (false) effect beside the hidden one: allowed at the analysis' false-alarm rate
  // (FalseAlarmRateOnEffectFreeCorrelatedNoise), binomial (1 - 1e-3) over the 6 runs.
  int runs_with_extra = 0;
  for (const Case c :
       {Case{EffectKind::QuadraticNonlinearity, 1, 4.0}, Case{EffectKind::OffsetDrift, 2, 8.0}}) {
    for (std::uint64_t seed : {31u, 32u, 33u}) {
      SimulationOptions so = issue_scenario(seed);
      RestSamples rest;
      const PositionTable plain = simulate_position_table(so, &rest);
      const NoiseModel m = estimated_model(plain, rest, 120.0);
      const double threshold = gls_threshold(plain, m, c.kind, c.target);
      ASSERT_GT(threshold, 0.0);
      const Effect hidden{c.kind, c.target, c.times_threshold * threshold};
      so.truth.effects = {hidden};
      const PositionTable table = simulate_position_table(so, &rest);
      const AnalysisResult a = analyze(table, quick_analysis(estimated_model(table, rest, 120.0)));
      SCOPED_TRACE(hidden.label() + " seed " + std::to_string(seed));
      ASSERT_FALSE(a.effects.empty()) << a.stop_reason;
      EXPECT_EQ(a.effects.front().effect.label(), hidden.label());
      if (a.effects.size() > 1) ++runs_with_extra;
      EXPECT_LT(a.after.cv.cv_chi2_per_point, a.before.cv.cv_chi2_per_point);
      EXPECT_LT(a.effects.front().cv_after, a.effects.front().cv_before);
      EXPECT_LT(std::abs(a.effects.front().effect.value - hidden.value),
                4.0 * a.effects.front().std);
    }
  }
  EXPECT_LE(runs_with_extra, statistical_bounds::binomial_upper(6, 0.039, 1e-3));
}

TEST(CorrelatedNoise, Ar1TableWrittenInTheTestNamesNothingAndCovers) {
  // Dwell means written here from the equations R = S g f + O + bias + white (the AR(1) bias of
  // ar1_record, sampled at 50 Hz over the protocol's timeline), not by the simulator. Ten runs:
  // the analysis with the model estimated from the 120 s rest names an effect in at most the
  // binomial (1 - 1e-3) quantile at alpha (with the Monte Carlo allowance), and the z-scores of
  // the fitted S against the truth have RMS below 1.5.
  ProtocolOptions protocol;
  protocol.steps_per_phase = 24;
  protocol.initial_rest_s = 120.0;
  const std::vector<ScheduledPosition> schedule = build_schedule(protocol);
  const double rate = 50.0, g = kStandardGravity;
  Eigen::Matrix3d S;
  S << 1.01, 0.004, -0.003, 0.002, 0.99, 0.005, -0.001, 0.003, 1.02;
  const Eigen::Vector3d O(0.05, -0.03, 0.08);
  const std::size_t n = static_cast<std::size_t>(schedule.back().dwell_end_s * rate) + 2;
  int named = 0;
  Coverage cov;
  const int runs = 10;
  for (int k = 0; k < runs; ++k) {
    const std::vector<Eigen::Vector3d> noise =
        ar1_record(4000 + static_cast<std::uint64_t>(k), n, rate, 0.03, 0.0015, 30.0, 0.0);
    PositionTable table;
    table.time_origin_s = 0.0;
    std::vector<double> stamps;
    std::vector<Eigen::Vector3d> outputs;
    for (const ScheduledPosition& p : schedule) {
      DwellRecord row;
      row.phase = p.phase;
      row.step = p.step;
      row.angle_rad = p.angle_rad;
      row.t_start_s = p.settled_s;
      row.t_end_s = p.dwell_end_s;
      const Eigen::Vector3d f(p.phase == Phase::X ? 0.0 : std::sin(p.angle_rad),
                              p.phase == Phase::Y   ? 0.0
                              : p.phase == Phase::X ? std::sin(p.angle_rad)
                                                    : std::cos(p.angle_rad),
                              p.phase == Phase::Z ? 0.0 : std::cos(p.angle_rad));
      const Eigen::Vector3d truth = g * S * f + O;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero(), sum_sq = Eigen::Vector3d::Zero();
      std::vector<Eigen::Vector3d> xs;
      for (auto i = static_cast<std::size_t>(std::ceil(p.settled_s * rate));
           i < static_cast<std::size_t>(std::ceil(p.dwell_end_s * rate)); ++i) {
        // ar1_record puts 9 m/s^2 on w: take it off.
        const Eigen::Vector3d x = truth + noise[i] - Eigen::Vector3d(0, 0, 9.0);
        xs.push_back(x);
        sum += x;
        if (table.rows.empty()) {
          stamps.push_back(static_cast<double>(i) / rate);
          outputs.push_back(x);
        }
      }
      row.n = xs.size();
      row.mean = sum / static_cast<double>(row.n);
      for (const Eigen::Vector3d& x : xs) sum_sq += (x - row.mean).cwiseAbs2();
      row.std = (sum_sq / static_cast<double>(row.n - 1)).cwiseSqrt();
      table.rows.push_back(row);
    }
    const std::optional<NoiseModel> m = noise_model_of_run(table, stamps, outputs, 120.0);
    ASSERT_TRUE(m.has_value());
    const AnalysisResult a = analyze(table, quick_analysis(*m));
    if (!a.effects.empty()) ++named;
    const FitResult& f = a.before_fit;
    for (int j = 0; j < 9; ++j)
      cov.add((f.S(j / 3, j % 3) - S(j / 3, j % 3)) / std::sqrt(f.covariance(j, j)));
  }
  std::cout << "[ INFO     ] AR(1) tables written in the test: " << named << "/" << runs
            << " name an effect; RMS z of S " << cov.rms() << "\n";
  const AnalysisOptions defaults = quick_analysis(NoiseModel());
  const double p = defaults.alpha + 4.0 * std::sqrt(defaults.alpha * (1.0 - defaults.alpha) /
                                                    defaults.monte_carlo_draws);
  EXPECT_LE(named, statistical_bounds::binomial_upper(runs, p, 1e-3));
  EXPECT_LT(cov.rms(), 1.5);
  EXPECT_GT(cov.rms(), 0.6);
}

TEST(CorrelatedNoise, VocabularyEntry) {
  ASSERT_EQ(noise_entry_catalog().size(), 1u);
  EXPECT_STREQ(noise_entry_catalog().front().name, "correlated_noise");
  EXPECT_THROW(make_effect("correlated_noise", "u"), std::invalid_argument);
  // White data: not named, and the reason says why.
  SimulationOptions so = issue_scenario(3);
  so.bias_gm_sigma = 0.0;
  const PositionTable table = simulate_position_table(so);
  const AnalysisResult a = analyze(table, quick_analysis(NoiseModel()));
  EXPECT_FALSE(a.correlated_noise.named);
  EXPECT_EQ(a.correlated_noise.noise_model, "white");
  EXPECT_FALSE(a.correlated_noise.reason.empty());
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
