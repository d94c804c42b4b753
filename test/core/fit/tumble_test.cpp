// The hand tumble (docs/design.md section 11): rests found in the stream, |P (mean - O)| = g,
// coverage and the next pose. Truth comes from core::simulate_hand_tumble (the one model) and, for
// the rest detector's edge cases, from streams written here sample by sample.
#include "accel_intrinsics/core/fit/tumble.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <random>
#include <sstream>

#include "../../support/statistical_bounds.h"
#include "accel_intrinsics/core/analysis/tumble_analysis.h"
#include "accel_intrinsics/core/dwells/rest_detection.h"
#include "accel_intrinsics/core/dwells/samples_file.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/noise/rest_accumulator.h"
#include "accel_intrinsics/core/run/tumble_session.h"
#include "accel_intrinsics/core/simulation/tumble_simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

constexpr double kG = kStandardGravity;

// Up directions that cover every axis both ways: the six faces, the twelve edges, eight corners.
std::vector<Eigen::Vector3d> spread_directions() {
  std::vector<Eigen::Vector3d> out;
  for (int a = -1; a <= 1; ++a)
    for (int b = -1; b <= 1; ++b)
      for (int c = -1; c <= 1; ++c)
        if (a != 0 || b != 0 || c != 0) out.push_back(Eigen::Vector3d(a, b, c).normalized());
  return out;
}

PositionTable table_of(const RestDetection& d) {
  PositionTable t;
  t.rows = d.rests;
  return t;
}

// The nine intrinsics of a device (responsivities, angles in rad, offsets).
Eigen::Matrix<double, 9, 1> truth_of(const Device& d) {
  const Intrinsics in = intrinsics_from_vectors(d.S);
  Eigen::Matrix<double, 9, 1> v;
  v << in.responsivity, in.angles_rad, d.O;
  return v;
}

Eigen::Matrix<double, 9, 1> estimate_of(const FitResult& r) {
  Eigen::Matrix<double, 9, 1> v;
  v << r.intrinsics.responsivity, r.intrinsics.angles_rad, r.O;
  return v;
}

Eigen::Matrix<double, 9, 1> std_of(const FitResult& r) {
  Eigen::Matrix<double, 9, 1> v;
  v << r.intrinsics.responsivity_std, r.intrinsics.angles_std_rad, r.O_std;
  return v;
}

TEST(Tumble, NoiseFreeRestsGiveTheIntrinsicsExactly) {
  TumbleSimulationOptions o;
  o.truth = random_tumble_device(7);
  o.noise_density = 0.0;
  o.up_directions = spread_directions();
  const TumbleRecording rec = simulate_hand_tumble(o);
  const RestDetection found = detect_rests(rec.samples);
  ASSERT_EQ(found.rests.size(), rec.rests.size());
  const FitResult r = fit(table_of(found));
  EXPECT_EQ(r.model, FitModel::Tumble);
  EXPECT_LT((estimate_of(r) - truth_of(o.truth)).cwiseAbs().maxCoeff(), 1e-9);
  // The sensor frame: S lower-triangular with a positive diagonal.
  EXPECT_EQ(r.S(0, 1), 0.0);
  EXPECT_EQ(r.S(0, 2), 0.0);
  EXPECT_EQ(r.S(1, 2), 0.0);
  EXPECT_GT(r.S.diagonal().minCoeff(), 0.0);
  // G = S S^T is the mounting-free part of S.
  EXPECT_LT((r.S * r.S.transpose() - o.truth.S * o.truth.S.transpose()).norm(), 1e-9);
  EXPECT_TRUE(tumble_coverage(r, table_of(found)).complete());
}

// The live session (tumble_session.h) on a simulated tumble fed sample by sample: the rests as
// the offline detection finds them, one at a time; before the first fit the pose asked for next
// is the fixed sequence written out here (each axis up and down, then the corners, unit vectors);
// once fitted the same intrinsics as the offline tumble fit.
TEST(TumbleSession, RestsOneAtATimeTheStartingPosesThenTheFit) {
  TumbleSimulationOptions o;
  o.truth = random_tumble_device(5);
  o.seed = 21;
  const TumbleRecording rec = simulate_hand_tumble(o);
  const RestDetection found = detect_rests(rec.samples);
  ASSERT_GE(found.rests.size(), 12u);
  TumbleSessionOptions so;
  TumbleSession session(so);
  const double c = 1.0 / std::sqrt(3.0);
  const Eigen::Vector3d expected_poses[] = {{0, 0, 1},   {0, 0, -1},  {1, 0, 0},  {-1, 0, 0},
                                            {0, 1, 0},   {0, -1, 0},  {c, c, c},  {-c, -c, c},
                                            {c, -c, -c}, {-c, c, -c}, {c, -c, c}, {-c, c, c}};
  EXPECT_EQ(session.progress().rests, 0u);
  EXPECT_TRUE(session.progress().next_up.isApprox(expected_poses[0], 1e-15));
  std::size_t last = 0;
  for (const ImuSample& sample : rec.samples) {
    if (!session.add_sample(sample.stamp_s, sample.outputs)) continue;
    const TumbleProgress& p = session.progress();
    EXPECT_EQ(p.rests, last + 1) << "one rest at a time";
    last = p.rests;
    if (p.rests < so.min_rests) {
      EXPECT_FALSE(p.fitted);
      EXPECT_NEAR(p.next_up.norm(), 1.0, 1e-12) << p.rests;
      EXPECT_TRUE(p.next_up.isApprox(expected_poses[p.rests % 12], 1e-12)) << p.rests;
    }
  }
  session.finish();
  const TumbleProgress& p = session.progress();
  EXPECT_EQ(p.rests, found.rests.size());
  ASSERT_TRUE(p.fitted) << p.fit_error;
  EXPECT_EQ(p.samples, rec.samples.size());
  const FitResult offline = fit(table_of(found));
  const FitResult live = fit(session.table());
  EXPECT_LT((estimate_of(live) - estimate_of(offline)).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(p.next_up.norm(), 1.0, 1e-9);
}

// A live session whose first rest is 120 s under a slow bias: it accumulates that rest's samples as
// they come (the detected dwell source feeds the dwell assembler, whose release observers feed a
// LongRestRecorder) and weighs its report with their noise model: the model offline_fit's rule
// gives for the same rests from the whole record. A session without a long rest stays white.
TEST(TumbleSession, FirstLongRestGivesTheReportItsNoiseModel) {
  TumbleSimulationOptions o;
  o.truth = random_tumble_device(9);
  o.seed = 23;
  o.initial_rest_s = 120.0;
  o.bias_gm_sigma = 0.003;
  o.bias_gm_tau_s = 20.0;
  const TumbleRecording rec = simulate_hand_tumble(o);
  TumbleSession session{TumbleSessionOptions()};
  std::vector<double> stamps;
  std::vector<Eigen::Vector3d> outputs;
  for (const ImuSample& sample : rec.samples) {
    session.add_sample(sample.stamp_s, sample.outputs);
    stamps.push_back(sample.stamp_s);
    outputs.push_back(sample.outputs);
  }
  session.finish();
  const std::optional<NoiseModel> live = session.noise_model();
  const std::optional<NoiseModel> whole = noise_model_of_run(session.table(), stamps, outputs);
  ASSERT_TRUE(live.has_value());
  ASSERT_TRUE(whole.has_value());
  EXPECT_FALSE(live->white());
  EXPECT_EQ(live->rest_samples, whole->rest_samples);
  EXPECT_GT(live->rest_samples, static_cast<std::size_t>(100.0 * o.rate_hz));
  for (int s = 0; s < 3; ++s) {
    EXPECT_EQ(live->axes[s].white_std, whole->axes[s].white_std) << s;
    EXPECT_EQ(live->axes[s].gm_sigma, whole->axes[s].gm_sigma) << s;
    EXPECT_EQ(live->axes[s].gm_tau_s, whole->axes[s].gm_tau_s) << s;
    EXPECT_EQ(live->axes[s].rw_density, whole->axes[s].rw_density) << s;
  }
  // The rest's blocks: 30 of 4 s (edges within a sub-block of the rest accumulator, at most
  // 2 x 120 s / 4096, of the equal-duration ones: docs/noise.md), every sample of the rest in one.
  ASSERT_EQ(live->rest_blocks.size(), static_cast<std::size_t>(kRestBlocks));
  std::size_t in_blocks = 0;
  for (const DwellRecord& b : live->rest_blocks) {
    in_blocks += b.n;
    EXPECT_NEAR(b.t_end_s - b.t_start_s, 4.0, 0.05 + 2.0 * 120.0 / RestAccumulator::kSubBlocks);
  }
  EXPECT_EQ(in_blocks, live->rest_samples);
  ASSERT_EQ(live->rest_blocks.size(), whole->rest_blocks.size());
  for (std::size_t b = 0; b < live->rest_blocks.size(); ++b) {
    EXPECT_EQ(live->rest_blocks[b].n, whole->rest_blocks[b].n) << b;
    EXPECT_EQ(live->rest_blocks[b].mean, whole->rest_blocks[b].mean) << b;
  }
  // The report: the rest's slow part fitted again to the whole tumble, as calibrate() does.
  const CalibrationReport report = session.report(CalibrateOptions());
  const NoiseModel fitted = slow_part_from_tumble(session.table(), *live);
  EXPECT_EQ(report.certificate.noise_model.source, fitted.source);
  EXPECT_EQ(report.certificate.noise_model.kind(), fitted.kind());
  EXPECT_EQ(report.certificate.noise_model.rest_samples, live->rest_samples);

  // Nothing to fit the slow part to without the rest's blocks (a model given, not measured), and
  // a white model stays white.
  NoiseModel given = *live;
  given.rest_blocks.clear();
  const NoiseModel unchanged = slow_part_from_tumble(session.table(), given);
  EXPECT_EQ(unchanged.source, given.source);
  for (int s = 0; s < 3; ++s) EXPECT_EQ(unchanged.axes[s].gm_sigma, given.axes[s].gm_sigma) << s;
  EXPECT_TRUE(slow_part_from_tumble(session.table(), NoiseModel()).white());
  EXPECT_NE(fitted.source.find("long rest's blocks"), std::string::npos) << fitted.source;

  TumbleSimulationOptions short_first = o;
  short_first.initial_rest_s = 5.0;
  TumbleSession plain{TumbleSessionOptions()};
  for (const ImuSample& sample : simulate_hand_tumble(short_first).samples)
    plain.add_sample(sample.stamp_s, sample.outputs);
  plain.finish();
  EXPECT_FALSE(plain.noise_model().has_value());
  EXPECT_TRUE(plain.report(CalibrateOptions()).certificate.noise_model.white());
}

// The simulator's noise_density is the one-sided density, as the gimbal simulator's: the sample
// std is noise_density * sqrt(rate / 2) (times noise_scale per axis), seen in the pooled std of
// the rests it makes (thousands of samples: 3 %).
// The residuals and their RMS on an inexact (noisy) tumble, computed here: each rest mean minus
// its projection on the fitted ellipsoid, m - (S g a_hat + O) with a = P (m - O); RMS over the
// 3 N components. The effect-term form's RMS over its own residuals, also over 3 N.
TEST(Tumble, ResidualsAndTheirRmsOverThreeN) {
  TumbleSimulationOptions o;
  o.truth = random_tumble_device(4);
  o.seed = 17;
  const TumbleRecording rec = simulate_hand_tumble(o);
  const PositionTable t = table_of(detect_rests(rec.samples));
  const FitResult r = fit(t);
  ASSERT_EQ(r.residuals.size(), t.rows.size());
  const Eigen::Matrix3d P = r.S.inverse();
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < t.rows.size(); ++i) {
    const Eigen::Vector3d a = P * (t.rows[i].mean - r.O);
    const Eigen::Vector3d residual =
        t.rows[i].mean - (r.S * (r.local_gravity * a.normalized()) + r.O);
    EXPECT_LT((r.residuals[i] - residual).norm(), 1e-9) << i;
    sum_sq += residual.squaredNorm();
  }
  const double rms = std::sqrt(sum_sq / (3.0 * static_cast<double>(t.rows.size())));
  EXPECT_GT(rms, 1e-5);
  EXPECT_NEAR(r.residual_rms, rms, 1e-9 * rms);
  const FitResult e = fit_tumble_with_effects(t, {}, r.local_gravity);
  double sum_e = 0.0;
  for (const Eigen::Vector3d& v : e.residuals) sum_e += v.squaredNorm();
  const double rms_e = std::sqrt(sum_e / (3.0 * static_cast<double>(e.residuals.size())));
  EXPECT_NEAR(e.residual_rms, rms_e, 1e-9 * rms_e);
  EXPECT_NEAR(e.residual_rms / r.residual_rms, 1.0, 0.2);  // both forms see the same scatter
}

// Each rest's statistics written out: the samples from its first to its last stamp, their mean
// and sample standard deviation (n - 1). (A rest joined across a short disturbance leaves the
// disturbance out: those are skipped, and most rests are plain.)
TEST(RestDetection, RestMeanAndStdAreThoseOfItsSamples) {
  TumbleSimulationOptions o;
  o.truth = random_tumble_device(9);
  o.seed = 41;
  const TumbleRecording rec = simulate_hand_tumble(o);
  const RestDetection found = detect_rests(rec.samples);
  int checked = 0;
  for (const DwellRecord& r : found.rests) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero(), sum_sq = Eigen::Vector3d::Zero();
    std::uint64_t n = 0;
    for (const ImuSample& s : rec.samples) {
      if (s.stamp_s < r.t_start_s || s.stamp_s > r.t_end_s) continue;
      sum += s.outputs;
      ++n;
    }
    if (n != r.n) continue;
    const Eigen::Vector3d mean = sum / static_cast<double>(n);
    for (const ImuSample& s : rec.samples) {
      if (s.stamp_s < r.t_start_s || s.stamp_s > r.t_end_s) continue;
      sum_sq += (s.outputs - mean).cwiseAbs2();
    }
    const Eigen::Vector3d std_dev = (sum_sq / static_cast<double>(n - 1)).cwiseSqrt();
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(r.mean(k), mean(k), 1e-9) << "rest at " << r.t_start_s;
      EXPECT_NEAR(r.std(k), std_dev(k), 1e-9 * std_dev(k)) << "rest at " << r.t_start_s;
    }
    ++checked;
  }
  EXPECT_GE(checked, static_cast<int>(found.rests.size()) / 2);
  EXPECT_GE(checked, 5);
}

TEST(TumbleSimulator, SampleStdIsTheOneSidedDensity) {
  TumbleSimulationOptions o;
  o.truth = random_tumble_device(8);
  o.seed = 33;
  o.noise_scale = Eigen::Vector3d(1.0, 2.0, 0.5);
  const TumbleRecording rec = simulate_hand_tumble(o);
  const RestDetection found = detect_rests(rec.samples);
  ASSERT_GE(found.rests.size(), 10u);
  Eigen::Vector3d sum_sq = Eigen::Vector3d::Zero();
  double dof = 0.0;
  for (const DwellRecord& r : found.rests) {
    sum_sq += static_cast<double>(r.n - 1) * r.std.cwiseAbs2();
    dof += static_cast<double>(r.n - 1);
  }
  for (int a = 0; a < 3; ++a) {
    const double expected = o.noise_scale(a) * o.noise_density * std::sqrt(o.rate_hz / 2.0);
    EXPECT_NEAR(std::sqrt(sum_sq(a) / dof), expected, 0.03 * expected) << a;
  }
}

TEST(Tumble, RestsFoundMatchTheTrueRests) {
  TumbleSimulationOptions o;
  o.truth = random_tumble_device(3);
  o.seed = 11;
  const TumbleRecording rec = simulate_hand_tumble(o);
  const RestDetection found = detect_rests(rec.samples);
  ASSERT_EQ(found.rests.size(), rec.rests.size());
  for (std::size_t i = 0; i < rec.rests.size(); ++i) {
    // Every found rest lies inside its true rest (trimmed), and covers most of it.
    EXPECT_GE(found.rests[i].t_start_s, rec.rests[i].t_start_s - 1e-9) << i;
    EXPECT_LE(found.rests[i].t_end_s, rec.rests[i].t_end_s + 1e-9) << i;
    EXPECT_GT(found.rests[i].t_end_s - found.rests[i].t_start_s,
              rec.rests[i].t_end_s - rec.rests[i].t_start_s - 1.5)
        << i;
  }
}

// Coverage of the stated uncertainties over many simulated tumbles (random devices, random
// poses, hand accelerations, the rests found by the detector): z = (estimate - truth) / std of
// each of the nine intrinsics; sum of z^2 over the runs against its chi-square band.
TEST(Tumble, UncertaintiesCoverTheTruthOverManySeeds) {
  const int runs = 120;
  Eigen::Matrix<double, 9, 1> sum_z2 = Eigen::Matrix<double, 9, 1>::Zero();
  int fitted = 0;
  for (int seed = 1; seed <= runs; ++seed) {
    TumbleSimulationOptions o;
    o.truth = random_tumble_device(1000 + seed);
    o.seed = seed;
    o.poses = 30;
    o.rest_min_s = 3.5;  // at least 2 s (rest-min-s) after trimming
    o.rest_max_s = 5.0;
    o.noise_scale = Eigen::Vector3d(1.0, 2.0, 0.7);
    const TumbleRecording rec = simulate_hand_tumble(o);
    const RestDetection found = detect_rests(rec.samples);
    ASSERT_EQ(found.rests.size(), rec.rests.size()) << "seed " << seed;
    const FitResult r = fit(table_of(found));
    const Eigen::Matrix<double, 9, 1> z =
        (estimate_of(r) - truth_of(o.truth)).cwiseQuotient(std_of(r));
    sum_z2 += z.cwiseProduct(z);
    ++fitted;
  }
  ASSERT_EQ(fitted, runs);
  const auto band = statistical_bounds::chi2_band(runs, 1e-3 / 18.0);
  for (int k = 0; k < 9; ++k) {
    EXPECT_GT(sum_z2(k), band.first) << "parameter " << k << ": uncertainties too large";
    EXPECT_LT(sum_z2(k), band.second) << "parameter " << k << ": uncertainties too small";
  }
}

TEST(Tumble, RawCountsWithQuantization) {
  TumbleSimulationOptions o;
  Device d = random_tumble_device(21, 0.03, 0.01, 0.3);
  // An accelerometer in counts: 1670 counts per m/s^2, offsets near mid-scale.
  d.S *= 1670.0;
  d.O = Eigen::Vector3d(33100.0, 33330.0, 32950.0) + d.O * 100.0;
  o.truth = d;
  o.noise_density = 2.0 / std::sqrt(50.0);  // ~2 counts a sample at 100 Hz
  o.quantization = 1.0;
  o.poses = 26;
  o.seed = 5;
  const TumbleRecording rec = simulate_hand_tumble(o);
  const RestDetection found = detect_rests(rec.samples);
  ASSERT_EQ(found.rests.size(), rec.rests.size());
  const FitResult r = fit(table_of(found));
  const Eigen::Matrix<double, 9, 1> z = (estimate_of(r) - truth_of(d)).cwiseQuotient(std_of(r));
  EXPECT_LT(z.cwiseAbs().maxCoeff(), statistical_bounds::normal_k(1e-3 / 9.0)) << z.transpose();
  EXPECT_NEAR(r.intrinsics.responsivity(0), d.S.row(0).norm(), 0.01 * d.S.row(0).norm());
}

TEST(Tumble, TooFewRestsNamesHowManyMore) {
  TumbleSimulationOptions o;
  o.truth = random_tumble_device(2);
  o.poses = 6;
  const RestDetection found = detect_rests(simulate_hand_tumble(o).samples);
  ASSERT_EQ(found.rests.size(), 7u);
  try {
    fit(table_of(found));
    FAIL() << "no error";
  } catch (const FitError& e) {
    EXPECT_NE(std::string(e.what()).find("7 rests, at least 10 needed (3 more)"), std::string::npos)
        << e.what();
  }
}

TEST(Tumble, RestsInOnePlaneDoNotDetermineTheIntrinsics) {
  // Turning about z only: z always horizontal, the w axis never sees gravity along it.
  TumbleSimulationOptions o;
  o.truth = random_tumble_device(4);
  for (int k = 0; k < 16; ++k) {
    const double a = 2.0 * M_PI * k / 16.0;
    o.up_directions.push_back(Eigen::Vector3d(std::cos(a), std::sin(a), 0.0));
  }
  o.noise_density = 0.0;
  const RestDetection found = detect_rests(simulate_hand_tumble(o).samples);
  PositionTable t = table_of(found);
  t.rows.erase(t.rows.begin());  // the first rest lies flat (z up): drop it
  try {
    fit(t);
    FAIL() << "no error";
  } catch (const FitError& e) {
    EXPECT_NE(std::string(e.what()).find("turn the device"), std::string::npos) << e.what();
  }
}

TEST(Tumble, CoverageNamesTheMissingDirection) {
  TumbleSimulationOptions o;
  o.truth.S = Eigen::Matrix3d::Identity();
  o.truth.O.setZero();
  // Every direction with z up or level: no rest with w (the z axis here) pointing down.
  for (const Eigen::Vector3d& u : spread_directions())
    if (u.z() >= 0.0) o.up_directions.push_back(u);
  o.seed = 9;
  const RestDetection found = detect_rests(simulate_hand_tumble(o).samples);
  const FitResult r = fit(table_of(found));
  const TumbleCoverage c = tumble_coverage(r, table_of(found));
  ASSERT_EQ(c.missing.size(), 1u);
  EXPECT_NE(c.missing[0].find("no rest with w pointing down within 45 deg"), std::string::npos)
      << c.missing[0];
  EXPECT_NEAR(c.closest_deg[2][1], 90.0, 1.0);
}

TEST(Tumble, MixedTablesAreRefused) {
  PositionTable t;
  DwellRecord a;
  a.orientation_unknown = true;
  a.n = 10;
  a.mean = Eigen::Vector3d(0, 0, kG);
  DwellRecord b = a;
  b.orientation_unknown = false;
  t.rows = {a, a, a, a, a, a, a, a, a, a, b};
  EXPECT_THROW(fit(t), FitError);
  t.rows.pop_back();
  FitOptions eq4;
  eq4.model = FitModel::Eq4;
  EXPECT_THROW(fit(t, eq4), FitError);
}

// Rests at the suggested poses lower the largest relative uncertainty faster than rests at random
// poses, over seeds (simulated rests with their noise, refitted after each).
TEST(Tumble, SuggestedPoseBeatsARandomPose) {
  int suggestion_wins = 0;
  const int seeds = 40;
  for (int seed = 1; seed <= seeds; ++seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal(0.0, 1.0);
    // The suggestion is in the sensor frame: a device whose axes are (nearly) its case's, as a
    // person holding it reads them.
    const Device d = random_tumble_device(500 + seed, 0.02, 0.005, 0.2, false);
    const Eigen::Vector3d se(0.002, 0.002, 0.002);
    auto rest_at = [&](const Eigen::Vector3d& up) {
      DwellRecord r;
      r.orientation_unknown = true;
      r.n = 400;
      r.std = se * std::sqrt(400.0);
      r.mean = d.S * (kG * up.normalized()) + d.O;
      for (int k = 0; k < 3; ++k) r.mean(k) += se(k) * normal(rng);
      return r;
    };
    auto random_up = [&]() {
      return Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
    };
    // A lopsided start: twelve rests, all with z up-ish.
    PositionTable start;
    while (start.rows.size() < 12) {
      Eigen::Vector3d u = random_up();
      if (u.z() < 0.2) continue;
      start.rows.push_back(rest_at(u));
    }
    auto largest = [](const FitResult& r) {
      double worst = 0.0;
      for (const RelativeUncertainty& u : relative_uncertainties(r))
        worst = std::max(worst, u.value);
      return worst;
    };
    // Four more rests: each at the pose suggested by the fit so far, or each at a random pose.
    PositionTable guided = start, unguided = start;
    for (int step = 0; step < 4; ++step) {
      const FitResult so_far = fit(guided);
      const PoseSuggestion s = suggest_next_pose(so_far, guided);
      EXPECT_LE(s.largest_after, largest(so_far) * (1.0 + 1e-12));
      EXPECT_FALSE(s.words.empty());
      guided.rows.push_back(rest_at(s.up));
      unguided.rows.push_back(rest_at(random_up()));
    }
    if (largest(fit(guided)) < largest(fit(unguided))) ++suggestion_wins;
  }
  // Far more often than a coin would (binomial(40, 0.5) upper tail at 1e-3).
  EXPECT_GT(suggestion_wins, statistical_bounds::binomial_upper(seeds, 0.5, 1e-3))
      << suggestion_wins;
}

TEST(Tumble, DescribePoseInWords) {
  EXPECT_EQ(describe_pose(Eigen::Vector3d(0, 0, 1)), "z axis pointing straight up");
  EXPECT_EQ(describe_pose(Eigen::Vector3d(-1, 0.05, 0)), "x axis pointing straight down");
  EXPECT_EQ(describe_pose(Eigen::Vector3d(1, 0, -1)), "x axis 45 deg up, z axis 45 deg down");
}

// ---- the tumble's discrepancy analysis --------------------------------------------------------

TumbleRecording analysis_tumble(std::uint64_t seed, const std::vector<Effect>& effects) {
  TumbleSimulationOptions o;
  o.truth = random_tumble_device(700 + seed);
  o.truth.effects = effects;
  o.seed = seed;
  o.poses = 30;
  o.rest_min_s = 3.5;
  o.rest_max_s = 5.0;
  return simulate_hand_tumble(o);
}

// Without effects the nuisance-direction form gives the tumble fit's intrinsics.
TEST(TumbleAnalysis, BaseFormAgreesWithTheTumbleFit) {
  const TumbleRecording rec = analysis_tumble(1, {});
  const PositionTable t = table_of(detect_rests(rec.samples));
  const FitResult a = fit_tumble(t);
  const FitResult b = fit_tumble_with_effects(t, {}, kG);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(a.intrinsics.responsivity(k), b.intrinsics.responsivity(k),
                0.1 * a.intrinsics.responsivity_std(k));
    EXPECT_NEAR(a.intrinsics.responsivity_std(k), b.intrinsics.responsivity_std(k),
                0.1 * a.intrinsics.responsivity_std(k));
  }
  EXPECT_EQ(a.dof, b.dof);
}

// Holm's step-down written out: at every step the candidates in ascending p, the k-th (from 0)
// times (m - k), capped at 1, running maximum.
void expect_holm_by_hand(const TumbleAnalysis& a) {
  for (const std::vector<TumbleEffectTest>& step : a.steps) {
    std::vector<double> p;
    for (const TumbleEffectTest& t : step) p.push_back(t.p_raw);
    std::vector<std::size_t> order(p.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t x, std::size_t y) { return p[x] < p[y]; });
    double running = 0.0;
    for (std::size_t k = 0; k < order.size(); ++k) {
      running = std::max(running, std::min(1.0, static_cast<double>(p.size() - k) * p[order[k]]));
      EXPECT_NEAR(step[order[k]].p_holm, running, 1e-12 * running) << step[order[k]].effect.label();
    }
  }
}

TEST(TumbleAnalysis, HiddenNonLinearityAndDriftAreNamedAndRecovered) {
  // K2 of 2e-4 /(m/s^2): 0.02 m/s^2 at 1 g, about 20 standard errors of a rest mean.
  const std::vector<std::pair<Effect, double>> cases = {
      {make_effect("quadratic_nonlinearity", "v", 2e-4), 0.0},
      {make_effect("offset_drift", "w", 1e-4), 0.0}};
  for (const auto& c : cases) {
    const TumbleRecording rec = analysis_tumble(3, {c.first});
    const PositionTable t = table_of(detect_rests(rec.samples));
    const TumbleAnalysis a = analyze_tumble(t);
    expect_holm_by_hand(a);
    ASSERT_FALSE(a.named.empty()) << c.first.label();
    EXPECT_EQ(a.named.front().effect.label(), c.first.label());
    EXPECT_NEAR(a.after.effects[0].value, c.first.value,
                statistical_bounds::normal_k(1e-3) * a.after.effects_std[0])
        << c.first.label();
    EXPECT_LT(a.after.reduced_chi2, a.before.reduced_chi2);
    EXPECT_FALSE(a.not_screened.empty());
  }
}

TEST(TumbleAnalysis, EffectFreeTumblesRarelyNameAnything) {
  const int runs = 40;
  int named = 0;
  for (int seed = 1; seed <= runs; ++seed) {
    const TumbleRecording rec = analysis_tumble(100 + seed, {});
    named += analyze_tumble(table_of(detect_rests(rec.samples))).named.empty() ? 0 : 1;
  }
  // Holm at alpha 0.025 per run: the count against binomial(40, 0.025) at 1e-3.
  EXPECT_LE(named, statistical_bounds::binomial_upper(runs, 0.025, 1e-3)) << named;
}

// ---- rest detection: edge cases written sample by sample ------------------------------------

struct StreamWriter {
  double rate_hz = 100.0;
  double t = 0.0;
  double noise = 0.01;
  std::mt19937_64 rng{42};
  std::normal_distribution<double> normal{0.0, 1.0};
  std::vector<ImuSample> samples;
  // Specific force direction `up` plus an extra acceleration, identity device.
  void hold(const Eigen::Vector3d& up, double seconds,
            const std::function<Eigen::Vector3d(double)>& extra = nullptr) {
    const long n = std::lround(seconds * rate_hz);
    for (long i = 0; i < n; ++i) {
      const double local = i / rate_hz;
      Eigen::Vector3d f = kG * up.normalized();
      if (extra) f += extra(local);
      for (int k = 0; k < 3; ++k) f(k) += noise * normal(rng);
      samples.push_back(ImuSample{t, f});
      t += 1.0 / rate_hz;
    }
  }
  // Turn from `from` to `to` at a steady angular rate.
  void turn(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double seconds) {
    const Eigen::Vector3d a = from.normalized(), b = to.normalized();
    const double angle = std::acos(std::clamp(a.dot(b), -1.0, 1.0));
    const Eigen::Vector3d axis = a.cross(b).normalized();
    const long n = std::lround(seconds * rate_hz);
    for (long i = 0; i < n; ++i) {
      const Eigen::Vector3d up = Eigen::AngleAxisd(angle * i / n, axis) * a;
      Eigen::Vector3d f = kG * up;
      for (int k = 0; k < 3; ++k) f(k) += noise * normal(rng);
      samples.push_back(ImuSample{t, f});
      t += 1.0 / rate_hz;
    }
  }
};

const Eigen::Vector3d kZ(0, 0, 1), kX(1, 0, 0), kY(0, 1, 0);

TEST(RestDetection, SlowTurnIsNotARest) {
  StreamWriter w;
  w.hold(kZ, 5.0);
  w.turn(kZ, kX, 1.0);
  w.hold(kX, 5.0);
  // 45 degrees in 15 s: 3 deg/s, smooth (small std) but the mean moves.
  w.turn(kX, Eigen::Vector3d(1, 1, 0), 15.0);
  w.hold(Eigen::Vector3d(1, 1, 0), 5.0);
  const RestDetection d = detect_rests(w.samples);
  ASSERT_EQ(d.rests.size(), 3u);
  EXPECT_NEAR(d.rests[2].mean.x(), kG / std::sqrt(2.0), 0.01);
  for (const DwellRecord& r : d.rests) EXPECT_LT(r.t_end_s - r.t_start_s, 5.0 + 1e-9);
}

TEST(RestDetection, JoltInsideARestIsCutOutAndTheRestKept) {
  StreamWriter w;
  w.hold(kZ, 5.0);
  w.turn(kZ, kY, 1.0);
  w.hold(kY, 4.0);
  w.hold(kY, 0.15, [](double) { return Eigen::Vector3d(3.0, -2.0, 4.0); });  // a knock
  w.hold(kY, 4.0);
  const RestDetection d = detect_rests(w.samples);
  ASSERT_EQ(d.rests.size(), 2u);
  EXPECT_GT(d.rests[1].t_end_s - d.rests[1].t_start_s, 7.0);
  bool named = false;
  for (const RejectedSpan& s : d.rejected) named |= s.reason.find("jolt") != std::string::npos;
  EXPECT_TRUE(named);
  EXPECT_NEAR(d.rests[1].mean.y(), kG, 0.005);
}

TEST(RestDetection, ShortShakeInsideARest) {
  StreamWriter w;
  w.hold(kX, 4.0);
  w.hold(kX, 0.6,
         [](double t) { return Eigen::Vector3d(0.0, 1.5 * std::sin(2 * M_PI * 6 * t), 0.8); });
  w.hold(kX, 4.0);
  const RestDetection d = detect_rests(w.samples);
  ASSERT_EQ(d.rests.size(), 1u);
  EXPECT_NEAR(d.rests[0].mean.x(), kG, 0.005);
}

TEST(RestDetection, SoftSurfaceWobbleIsTrimmed) {
  StreamWriter w;
  w.hold(kZ, 5.0);
  w.turn(kZ, kX, 1.0);
  // Put down on foam: a 3 Hz wobble decaying with 0.4 s, then still.
  w.hold(kX, 6.0, [](double t) -> Eigen::Vector3d {
    return Eigen::Vector3d(0.0, 0.0, 1.2 * std::exp(-t / 0.4) * std::sin(2 * M_PI * 3 * t));
  });
  const RestDetection d = detect_rests(w.samples);
  ASSERT_EQ(d.rests.size(), 2u);
  // The wobble's part is not in the mean.
  EXPECT_NEAR(d.rests[1].mean.z(), 0.0, 0.003);
  EXPECT_GT(d.rests[1].t_start_s, 6.0 + 0.5);
}

TEST(RestDetection, TooShortRestsAreListedWithTheReason) {
  StreamWriter w;
  w.hold(kZ, 5.0);
  w.turn(kZ, kX, 1.0);
  w.hold(kX, 1.4);
  w.turn(kX, kY, 1.0);
  w.hold(kY, 5.0);
  RestDetectionOptions o;
  o.min_rest_s = 2.0;
  const RestDetection d = detect_rests(w.samples, o);
  ASSERT_EQ(d.rests.size(), 2u);
  bool named = false;
  for (const RejectedSpan& s : d.rejected) {
    if (s.reason.find("too short") != std::string::npos && s.t_start_s > 6.0 && s.t_end_s < 7.5)
      named = true;
  }
  EXPECT_TRUE(named);
  o.min_rest_s = 0.3;
  EXPECT_EQ(detect_rests(w.samples, o).rests.size(), 3u);
}

TEST(RestDetection, StreamingDetectorMatchesTheBatch) {
  TumbleSimulationOptions o;
  o.truth = random_tumble_device(8);
  o.seed = 17;
  o.poses = 12;
  const TumbleRecording rec = simulate_hand_tumble(o);
  const RestDetection batch = detect_rests(rec.samples);
  RestDetector live;
  std::vector<DwellRecord> rests;
  for (const ImuSample& s : rec.samples) {
    live.add(s.stamp_s, s.outputs);
    for (DwellRecord& r : live.take_rests()) rests.push_back(r);
  }
  live.finish();
  for (DwellRecord& r : live.take_rests()) rests.push_back(r);
  ASSERT_EQ(rests.size(), batch.rests.size());
  for (std::size_t i = 0; i < rests.size(); ++i) {
    // The live quiet level is learned as it goes: the same rests, trimmed alike.
    EXPECT_NEAR(rests[i].t_start_s, batch.rests[i].t_start_s, 0.5) << i;
    EXPECT_NEAR(rests[i].t_end_s, batch.rests[i].t_end_s, 0.5) << i;
  }
}

TEST(RestDetection, GapAndBadStreams) {
  StreamWriter w;
  w.hold(kZ, 3.0);
  w.t += 2.0;  // two seconds lost
  w.hold(kZ, 3.0);
  const RestDetection d = detect_rests(w.samples);
  EXPECT_EQ(d.rests.size(), 2u);
  bool named = false;
  for (const RejectedSpan& s : d.rejected)
    named |= s.reason.find("gap in the stream") != std::string::npos;
  EXPECT_TRUE(named);
  std::vector<ImuSample> back = w.samples;
  std::swap(back[5], back[6]);
  EXPECT_THROW(detect_rests(back), std::invalid_argument);
  EXPECT_THROW(detect_rests(std::vector<ImuSample>(3)), std::invalid_argument);
  RestDetectionOptions bad;
  bad.min_rest_s = -1.0;
  EXPECT_THROW(detect_rests(w.samples, bad), std::invalid_argument);
}

// ---- samples files ------------------------------------------------------------------------

TEST(SamplesFile, ReadsCommaWhitespaceHeaderAndComments) {
  std::istringstream comma("t,x,y,z\n0.0,1,2,3\n0.01,1.5,2.5,3.5\n");
  EXPECT_EQ(read_samples(comma).size(), 2u);
  // imu_tk's layout: whitespace, exponent notation, no header.
  std::istringstream spaces(
      "   2.9840000e-02   3.3108000e+04   3.3329000e+04   3.6429000e+04\n"
      "# a comment\n\n   3.9857000e-02   3.3096000e+04   3.3336000e+04   3.6437000e+04\n");
  const std::vector<ImuSample> s = read_samples(spaces);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_DOUBLE_EQ(s[1].stamp_s, 3.9857e-02);
  EXPECT_DOUBLE_EQ(s[1].outputs.z(), 36437.0);
  std::ostringstream out;
  write_samples(out, s);
  std::istringstream again(out.str());
  const std::vector<ImuSample> back = read_samples(again);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].outputs, s[0].outputs);
}

TEST(SamplesFile, ErrorsNameTheLineAndTheField) {
  auto error_of = [](const std::string& text) {
    std::istringstream in(text);
    try {
      read_samples(in, "f.txt");
    } catch (const SamplesFileError& e) {
      return std::string(e.what());
    }
    return std::string("(none)");
  };
  EXPECT_NE(error_of("t,x,y,z\n0,1,2\n").find("f.txt:2: expected 4 fields"), std::string::npos);
  EXPECT_NE(error_of("0,1,2,3\n1,1,nan,3\n").find("f.txt:2: field y"), std::string::npos);
  EXPECT_NE(error_of("1,1,2,3\n0.5,1,2,3\n").find("t goes back"), std::string::npos);
  EXPECT_NE(error_of("t,x,y,z\n").find("no samples"), std::string::npos);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
