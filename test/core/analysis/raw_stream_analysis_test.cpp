// Tests of the raw-stream analyses: the timeline rebuilt from gimbal events, and the timing-lag
// estimate (recovery within its uncertainty on simulated recordings with random devices,
// mountings, noise, rates and seeds; the false-alarm rate on lag-free data; the time axes; the
// flag for recordings without move samples).
#include "accel_intrinsics/core/analysis/raw_stream_analysis.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "../../support/statistical_bounds.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

// A random non-orthogonal triad (scale errors of 1-3 %, misalignments of about 1 degree,
// offsets of a few tenths of m/s^2) in a random mounting (rotation of the DUT frame).
Device random_device(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> scale(0.01, 0.03);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> offset(-0.4, 0.4);
  Device d;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      d.S(i, j) =
          i == j ? 1.0 + (unit(rng) < 0 ? -1.0 : 1.0) * scale(rng) : deg_to_rad(1.0) * normal(rng);
    }
    d.O(i) = offset(rng);
  }
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  q.normalize();
  d.S = d.S * q.toRotationMatrix();
  return d;
}

SimulationOptions simulation(const Device& truth, double lag_s, double rate_hz,
                             std::uint64_t seed) {
  SimulationOptions sim;
  sim.truth = truth;
  if (lag_s != 0.0) sim.truth.effects.push_back(Effect{EffectKind::TimingLag, 0, lag_s});
  sim.rate_hz = rate_hz;
  sim.seed = seed;
  return sim;
}

struct SimulatedRun {
  Recording recording;
  PositionTable table;
  FitResult base;
};

SimulatedRun simulate_and_fit(const SimulationOptions& sim, const FitOptions& fit_options = {}) {
  SimulatedRun run;
  run.recording = simulate_recording(sim);
  DwellAssembler assembler;
  feed_in_stamp_order(run.recording, &assembler);
  run.table = assembler.table();
  run.base = fit(run.table, fit_options);
  return run;
}

void expect_same_schedule(const std::vector<ScheduledPosition>& got,
                          const std::vector<ScheduledPosition>& want, double tol) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(got[i].phase, want[i].phase) << i;
    EXPECT_EQ(got[i].step, want[i].step) << i;
    EXPECT_EQ(got[i].steps, want[i].steps) << i;
    EXPECT_EQ(got[i].angle_rad, want[i].angle_rad) << i;
    EXPECT_EQ(got[i].approach, want[i].approach) << i;
    EXPECT_NEAR(got[i].move_start_s, want[i].move_start_s, tol) << i;
    EXPECT_NEAR(got[i].settled_s, want[i].settled_s, tol) << i;
    EXPECT_NEAR(got[i].dwell_end_s, want[i].dwell_end_s, tol) << i;
  }
}

// One estimate against its truth in a test about something else (time axes, convergence, the
// noise scale): k std with a two-sided tail of 1e-4, so a correct estimator fails such a check in
// fewer than 1 of 10^4 seeds (3 std: 1 in 370). Unbiasedness over many seeds and rates is
// TimingLag.RecoveredWithinItsStdForRandomDevicesRatesAndSeeds.
const double kSingleRunK = statistical_bounds::normal_k(1e-4);

// The model along the moves fits to the noise: the reduced chi-square of n residuals is within
// 6 of its sigma sqrt(2 / n) of 1, plus 0.01 for the interpolated motion profile.
double reduced_chi2_tolerance(const TimingLagEstimate& est) {
  return 6.0 * std::sqrt(2.0 / (3.0 * static_cast<double>(est.samples_used))) + 0.01;
}

TEST(ScheduleFromCommands, ReproducesBuildScheduleOnSimulatedCommands) {
  std::vector<ProtocolOptions> protocols(6);
  protocols[1].steps_per_phase = 7;
  protocols[1].two_way = true;  // the turn repeats step N-1 with approach -1
  protocols[1].move_s = 0.37;
  protocols[1].settle_s = 0.11;
  protocols[1].dwell_s = 1.3;
  protocols[1].phase_change_s = 2.9;
  protocols[2].steps_per_phase = 5;
  protocols[2].move_s = 0.0;  // MOVING and SETTLED share a stamp: the order of events decides
  protocols[2].settle_s = 0.0;
  protocols[3].steps_per_phase = 3;
  protocols[3].two_way = true;
  protocols[3].phase_change_s = 0.0;
  protocols[4].steps_per_phase = 6;
  protocols[4].closing_position = true;  // step N at 2 pi, approached from below
  protocols[5].steps_per_phase = 4;
  protocols[5].closing_position = true;  // then down from 2 pi, approach -1
  protocols[5].two_way = true;
  for (std::size_t k = 0; k < protocols.size(); ++k) {
    SCOPED_TRACE(k);
    SimulationOptions sim;
    sim.protocol = protocols[k];
    sim.rate_hz = 20.0;
    const Recording rec = simulate_recording(sim);
    const std::vector<ScheduledPosition> want = build_schedule(sim.protocol);
    expect_same_schedule(schedule_from_commands(rec.commands), want, 0.0);

    // Absolute stamps and bag receive order: same timeline relative to the first command, and
    // relative to any explicit origin.
    std::vector<GimbalEvent> shifted = rec.commands;
    const double t0 = 1.7e9 + 0.123;
    for (GimbalEvent& e : shifted) e.stamp_s += t0;
    std::mt19937_64 rng(k);
    std::vector<GimbalEvent> shuffled = shifted;
    // Swap neighbours with distinct stamps only: events with equal stamps keep their order.
    for (std::size_t i = 1; i < shuffled.size(); ++i) {
      if (shuffled[i].stamp_s != shuffled[i - 1].stamp_s && rng() % 2 == 0)
        std::swap(shuffled[i], shuffled[i - 1]);
    }
    EXPECT_DOUBLE_EQ(first_command_stamp(shuffled), t0);
    expect_same_schedule(schedule_from_commands(shuffled), want, 1e-6);
    std::vector<ScheduledPosition> later = want;
    for (ScheduledPosition& p : later) {
      p.move_start_s -= 10.0;
      p.settled_s -= 10.0;
      p.dwell_end_s -= 10.0;
    }
    expect_same_schedule(schedule_from_commands(shuffled, t0 + 10.0), later, 1e-6);
  }
}

TEST(ScheduleFromCommands, IncompleteAndOutOfProtocolEvents) {
  SimulationOptions sim;
  sim.protocol.steps_per_phase = 4;
  sim.rate_hz = 20.0;
  const Recording rec = simulate_recording(sim);
  const std::vector<ScheduledPosition> full = build_schedule(sim.protocol);
  ASSERT_EQ(rec.commands.size(), 2 * full.size() + 1);

  // Aborted run: the last MOVING has no SETTLED and there is no DONE. The aborted move ends the
  // previous dwell and yields no position.
  std::vector<GimbalEvent> aborted(rec.commands.begin(), rec.commands.end() - 2);
  std::vector<ScheduledPosition> got = schedule_from_commands(aborted);
  ASSERT_EQ(got.size(), full.size() - 1);
  EXPECT_EQ(got.back().dwell_end_s, full.back().move_start_s);

  // Recording ends in a dwell: its end is unknown (+infinity).
  std::vector<GimbalEvent> open(rec.commands.begin(), rec.commands.end() - 1);
  got = schedule_from_commands(open);
  ASSERT_EQ(got.size(), full.size());
  EXPECT_TRUE(std::isinf(got.back().dwell_end_s));

  // A SETTLED for another step than the pending MOVING is ignored.
  std::vector<GimbalEvent> odd = rec.commands;
  odd[3].step += 1;  // the SETTLED of position 1
  got = schedule_from_commands(odd);
  ASSERT_EQ(got.size(), full.size() - 1);
  EXPECT_EQ(got[0].dwell_end_s, full[1].move_start_s);
  EXPECT_EQ(got[1].step, full[2].step);

  EXPECT_TRUE(schedule_from_commands(std::vector<GimbalEvent>{}).empty());
  EXPECT_TRUE(std::isnan(first_command_stamp({})));
}

TEST(PooledSampleStd, WeightsDwellsByDegreesOfFreedom) {
  PositionTable table;
  DwellRecord a, b, c;
  a.n = 11;
  a.std = Eigen::Vector3d(1.0, 2.0, 3.0);
  b.n = 31;
  b.std = Eigen::Vector3d(2.0, 2.0, 1.0);
  c.n = 1;  // no std: ignored
  c.std = Eigen::Vector3d(100.0, 100.0, 100.0);
  table.rows = {a, b, c};
  const Eigen::Vector3d pooled = pooled_sample_std(table);
  EXPECT_NEAR(pooled(0), std::sqrt((10 * 1.0 + 30 * 4.0) / 40.0), 1e-12);
  EXPECT_NEAR(pooled(1), 2.0, 1e-12);
  EXPECT_NEAR(pooled(2), std::sqrt((10 * 9.0 + 30 * 1.0) / 40.0), 1e-12);
  EXPECT_EQ(pooled_sample_std(PositionTable{}), Eigen::Vector3d::Zero());
}

TEST(TimingLag, RecoveredWithinItsStdForRandomDevicesRatesAndSeeds) {
  struct Case {
    double lag_s;
    double rate_hz;
  };
  // 2-20 ms at 100-400 Hz, both signs: many times the detection threshold (checked below).
  const std::vector<Case> cases = {{0.002, 100.0}, {0.005, 400.0},  {0.010, 200.0},
                                   {0.020, 100.0}, {-0.005, 200.0}, {0.003, 400.0}};
  std::mt19937_64 rng(20261121);
  std::uniform_real_distribution<double> density_ug(100.0, 600.0);
  for (std::size_t k = 0; k < cases.size(); ++k) {
    SimulationOptions sim =
        simulation(random_device(rng), cases[k].lag_s, cases[k].rate_hz, 1000 + k);
    sim.noise_density = density_ug(rng) * 1e-6 * kStandardGravity;
    sim.protocol.steps_per_phase = 12 + 4 * static_cast<std::uint32_t>(k % 3);
    sim.protocol.dwell_s = 1.5;
    sim.protocol.two_way = k == 5;  // return sweep: approach -1 and a turn without travel
    SCOPED_TRACE(::testing::Message()
                 << "lag " << cases[k].lag_s << " s at " << cases[k].rate_hz << " Hz, N "
                 << sim.protocol.steps_per_phase << (sim.protocol.two_way ? " two-way" : ""));
    const SimulatedRun run = simulate_and_fit(sim);
    const TimingLagEstimate est =
        estimate_timing_lag(run.recording.commands, run.recording.samples, run.table, run.base);
    ASSERT_TRUE(est.ok) << est.message;
    EXPECT_TRUE(est.converged) << est.message;
    EXPECT_FALSE(est.at_bound);
    EXPECT_FALSE(est.sigma_from_residuals);
    EXPECT_EQ(est.moves_used,
              (sim.protocol.two_way ? 6u : 3u) * (sim.protocol.steps_per_phase - 1));
    EXPECT_GT(std::abs(cases[k].lag_s), 4.0 * est.detection_threshold_s)
        << "the case is not well above threshold";
    // Every case within k std, k from the normal quantile so that all cases together fail a
    // correct estimator in < 1e-3 of seed sets (3 std each would fail ~1.6 % of them).
    const double k_std = statistical_bounds::normal_k(1e-3 / static_cast<double>(cases.size()));
    EXPECT_LT(std::abs(est.lag_s - cases[k].lag_s), k_std * est.std_s)
        << est.message << " (error " << (est.lag_s - cases[k].lag_s) * 1e3 << " ms)";
    EXPECT_TRUE(est.detected) << est.message;
    EXPECT_LT(est.p_value, 1e-6);
    // The p-value of the likelihood-ratio chi2(1) statistic, written out: erfc(sqrt(T / 2)).
    EXPECT_NEAR(est.p_value, std::erfc(std::sqrt(est.lr_chi2 / 2.0)),
                1e-9 * std::erfc(std::sqrt(est.lr_chi2 / 2.0)) + 1e-300);
    // A wrong profile or time axis would not fit to the noise.
    EXPECT_NEAR(est.reduced_chi2, 1.0, reduced_chi2_tolerance(est)) << est.message;
    const double sigma = sample_noise_std(sim);
    for (int s = 0; s < 3; ++s) EXPECT_NEAR(est.sample_sigma(s), sigma, 0.05 * sigma);
    EXPECT_NEAR(est.effect().value, est.lag_s, 0.0);
    EXPECT_EQ(est.effect().name(), "timing_lag");
  }
}

TEST(TimingLag, LagFreeDataFalseAlarmRateAndCalibration) {
  // 100 effect-free recordings: the count flagged at alpha = 5 % is binomial(100, 0.05), the sum
  // of the likelihood-ratio statistics chi2(100) (each chi2(1)), the sum of (estimate / std)^2
  // chi2(100), the count beyond 3 std binomial(100, 0.0027). Each bound is the quantile at 1.25e-4
  // (two-sided: 6.25e-5 a side), so a correct estimator fails the test in < 1e-3 of seeds.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> density_ug(150.0, 500.0);
  const int runs = 100;
  int flagged = 0;
  double sum_lr = 0.0, sum_z2 = 0.0;
  int beyond_3 = 0;
  for (int k = 0; k < runs; ++k) {
    SimulationOptions sim = simulation(random_device(rng), 0.0, 100.0, 5000 + k);
    sim.noise_density = density_ug(rng) * 1e-6 * kStandardGravity;
    sim.protocol.steps_per_phase = 8;
    sim.protocol.dwell_s = 1.0;
    sim.protocol.phase_change_s = 1.0;
    const SimulatedRun run = simulate_and_fit(sim);
    const TimingLagEstimate est =
        estimate_timing_lag(run.recording.commands, run.recording.samples, run.table, run.base);
    ASSERT_TRUE(est.ok) << est.message;
    if (est.detected) ++flagged;
    sum_lr += est.lr_chi2;
    const double z = est.lag_s / est.std_s;
    sum_z2 += z * z;
    if (std::abs(z) > 3.0) ++beyond_3;
    // Score and likelihood-ratio statistics agree near lag = 0.
    EXPECT_NEAR(est.score_chi2, est.lr_chi2, 0.02 * est.lr_chi2 + 1e-3);
  }
  namespace sb = statistical_bounds;
  const int flagged_max = sb::binomial_upper(runs, 0.05, 1.25e-4);
  const int beyond_max =
      sb::binomial_upper(runs, 2.0 * std::erfc(3.0 / std::sqrt(2.0)) / 2.0, 1.25e-4);
  const std::pair<double, double> band = sb::chi2_band(runs, 6.25e-5);
  std::printf(
      "lag-free: flagged %d (max %d), sum LR %.1f, sum z^2 %.1f (band %.1f..%.1f), "
      "beyond 3 std %d (max %d)\n",
      flagged, flagged_max, sum_lr, sum_z2, band.first, band.second, beyond_3, beyond_max);
  EXPECT_LE(flagged, flagged_max) << "false alarms at alpha = 0.05 in " << runs << " lag-free runs";
  EXPECT_GE(sum_lr, band.first);
  EXPECT_LE(sum_lr, band.second);
  EXPECT_GE(sum_z2, band.first);
  EXPECT_LE(sum_z2, band.second);
  EXPECT_LE(beyond_3, beyond_max);
}

TEST(TimingLag, TimeAxesAbsoluteStampsAndDriftOrigin) {
  // The same run with absolute stamps (all shifted by T) gives the same estimate; with offset
  // drift fitted, the drift term runs on t - t0 with t0 = the first command, and a wrong origin
  // shows as a misfit of the move samples.
  std::mt19937_64 rng(99);
  Device truth = random_device(rng);
  for (int s = 0; s < 3; ++s)
    truth.effects.push_back(Effect{EffectKind::OffsetDrift, s, 4e-4 * (s + 1)});
  SimulationOptions sim = simulation(truth, 0.008, 200.0, 42);
  sim.protocol.steps_per_phase = 12;
  FitOptions fit_options;
  for (int s = 0; s < 3; ++s)
    fit_options.effects.push_back(Effect{EffectKind::OffsetDrift, s, 0.0});
  const SimulatedRun run = simulate_and_fit(sim, fit_options);
  ASSERT_EQ(run.table.time_origin_s, 0.0);
  const TimingLagEstimate est =
      estimate_timing_lag(run.recording.commands, run.recording.samples, run.table, run.base);
  ASSERT_TRUE(est.ok) << est.message;
  EXPECT_LT(std::abs(est.lag_s - 0.008), kSingleRunK * est.std_s) << est.message;
  EXPECT_NEAR(est.reduced_chi2, 1.0, reduced_chi2_tolerance(est));

  const double T = 1.6e9 + 0.25;  // stamps of 2020s ROS time: 1e-7 s resolution in a double
  Recording shifted = run.recording;
  for (GimbalEvent& e : shifted.commands) e.stamp_s += T;
  for (ImuSample& s : shifted.samples) s.stamp_s += T;
  DwellAssembler assembler;
  feed_in_stamp_order(shifted, &assembler);
  ASSERT_EQ(assembler.table().time_origin_s, T);
  const FitResult base_shifted = fit(assembler.table(), fit_options);
  const TimingLagEstimate est_shifted =
      estimate_timing_lag(shifted.commands, shifted.samples, assembler.table(), base_shifted);
  ASSERT_TRUE(est_shifted.ok) << est_shifted.message;
  EXPECT_EQ(est_shifted.time_origin_s, T);
  EXPECT_NEAR(est_shifted.lag_s, est.lag_s, 0.05 * est.std_s);
  EXPECT_NEAR(est_shifted.std_s, est.std_s, 0.01 * est.std_s);

  // Explicit origin: the same as the table's; NaN means the first command (here the same).
  const Eigen::Vector3d sigma = pooled_sample_std(run.table);
  const TimingLagEstimate explicit_origin =
      estimate_timing_lag(run.recording.commands, run.recording.samples, run.base, 0.0, sigma);
  EXPECT_EQ(explicit_origin.lag_s, est.lag_s);
  const TimingLagEstimate nan_origin = estimate_timing_lag(
      run.recording.commands, run.recording.samples, run.base, std::nan(""), sigma);
  EXPECT_EQ(nan_origin.lag_s, est.lag_s);
  // A drift origin 100 s off moves the fitted offsets by d * 100 s along the whole run: the
  // move samples no longer fit.
  const TimingLagEstimate wrong =
      estimate_timing_lag(run.recording.commands, run.recording.samples, run.base, -100.0, sigma);
  EXPECT_GT(wrong.reduced_chi2, 3.0) << wrong.message;
}

TEST(TimingLag, FlagsRecordingsWithoutMoveSamples) {
  std::mt19937_64 rng(3);
  SimulationOptions sim = simulation(random_device(rng), 0.01, 100.0, 5);
  sim.protocol.steps_per_phase = 6;
  const SimulatedRun run = simulate_and_fit(sim);
  // Keep only the samples a dwell-only logger would keep: stamps inside [SETTLED, next MOVING).
  const std::vector<ScheduledPosition> schedule =
      schedule_from_commands(run.recording.commands, 0.0);
  std::vector<ImuSample> dwell_only;
  for (const ImuSample& s : run.recording.samples) {
    for (const ScheduledPosition& p : schedule) {
      if (s.stamp_s >= p.settled_s && s.stamp_s < p.dwell_end_s) {
        dwell_only.push_back(s);
        break;
      }
    }
  }
  ASSERT_GT(dwell_only.size(), 1000u);
  // The margins after SETTLED still catch samples at rest; with margin 0 nothing is left.
  TimingLagEstimateOptions options;
  options.margin_s = 0.0;
  TimingLagEstimate est =
      estimate_timing_lag(run.recording.commands, dwell_only, run.table, run.base, options);
  EXPECT_FALSE(est.ok);
  EXPECT_FALSE(est.detected);
  EXPECT_LT(est.samples_used, options.min_move_samples);
  EXPECT_EQ(est.samples_total, dwell_only.size());
  EXPECT_NE(est.message.find("while the gimbal moves"), std::string::npos) << est.message;

  // No commands at all.
  est = estimate_timing_lag({}, run.recording.samples, run.base, std::nan(""),
                            Eigen::Vector3d::Ones());
  EXPECT_FALSE(est.ok);
  EXPECT_NE(est.message.find("no gimbal commands"), std::string::npos) << est.message;

  // The full stream with the same options works.
  est = estimate_timing_lag(run.recording.commands, run.recording.samples, run.table, run.base,
                            options);
  EXPECT_TRUE(est.ok) << est.message;
  EXPECT_TRUE(est.detected) << est.message;

  // Bad options throw.
  options.max_abs_lag_s = 0.0;
  EXPECT_THROW(estimate_timing_lag(run.recording.commands, run.recording.samples, run.table,
                                   run.base, options),
               std::invalid_argument);
}

TEST(TimingLag, LargeLagConvergesAndTheBoundIsReported) {
  // 80 ms: far from the linear regime of the first Gauss-Newton step from 0, still recovered.
  std::mt19937_64 rng(21);
  SimulationOptions sim = simulation(random_device(rng), 0.08, 100.0, 9);
  sim.protocol.steps_per_phase = 8;
  const SimulatedRun run = simulate_and_fit(sim);
  const TimingLagEstimate est =
      estimate_timing_lag(run.recording.commands, run.recording.samples, run.table, run.base);
  ASSERT_TRUE(est.ok) << est.message;
  EXPECT_TRUE(est.converged) << est.message;
  EXPECT_LT(std::abs(est.lag_s - 0.08), kSingleRunK * est.std_s) << est.message;
  // A bound below the true lag: the estimate stops there and is not ok.
  TimingLagEstimateOptions options;
  options.max_abs_lag_s = 0.03;
  const TimingLagEstimate bounded = estimate_timing_lag(
      run.recording.commands, run.recording.samples, run.table, run.base, options);
  EXPECT_TRUE(bounded.at_bound) << bounded.message;
  EXPECT_FALSE(bounded.ok);
  EXPECT_FALSE(bounded.detected);
  EXPECT_NEAR(bounded.lag_s, 0.03, 1e-12);
  EXPECT_NE(bounded.message.find("bound"), std::string::npos) << bounded.message;
}

TEST(TimingLag, NoiseScaleFromResidualsWhenTheTableHasNoStd) {
  // Zero sample_sigma: unit weights, the scale estimated from the move residuals; the estimate
  // and its uncertainty match those with the known sigma.
  std::mt19937_64 rng(11);
  SimulationOptions sim = simulation(random_device(rng), 0.004, 200.0, 8);
  sim.protocol.steps_per_phase = 8;
  const SimulatedRun run = simulate_and_fit(sim);
  const TimingLagEstimate known =
      estimate_timing_lag(run.recording.commands, run.recording.samples, run.table, run.base);
  const Eigen::Vector3d sigma = Eigen::Vector3d::Constant(sample_noise_std(sim));
  const TimingLagEstimate exact =
      estimate_timing_lag(run.recording.commands, run.recording.samples, run.base, 0.0, sigma);
  const TimingLagEstimate unknown = estimate_timing_lag(
      run.recording.commands, run.recording.samples, run.base, 0.0, Eigen::Vector3d::Zero());
  ASSERT_TRUE(known.ok && exact.ok && unknown.ok) << unknown.message;
  EXPECT_TRUE(unknown.sigma_from_residuals);
  EXPECT_NEAR(unknown.lag_s, known.lag_s, 0.1 * known.std_s);
  EXPECT_NEAR(unknown.std_s, known.std_s, 0.1 * known.std_s);
  EXPECT_NEAR(unknown.sample_sigma(0), sample_noise_std(sim), 0.05 * sample_noise_std(sim));
  EXPECT_NEAR(exact.lag_s, known.lag_s, 0.1 * known.std_s);
  EXPECT_LT(std::abs(unknown.lag_s - 0.004), kSingleRunK * unknown.std_s);
}

// The calibration node keeps only what the estimator reads (MoveSampleRecorder fed by the
// assembler's release observers, messages arriving out of order within the reorder window): the
// estimate from that is the estimate from the whole recording, from a fraction of the samples.
TEST(MoveSampleRecorder, GivesTheEstimateOfTheWholeRecording) {
  std::mt19937_64 rng(77);
  for (int k = 0; k < 3; ++k) {
    SimulationOptions sim = simulation(random_device(rng), k == 0 ? 0.0 : 0.004 * k, 200.0, 50 + k);
    sim.protocol.steps_per_phase = 12;
    sim.protocol.two_way = k == 2;
    sim.protocol.closing_position = k == 1;
    const SimulatedRun run = simulate_and_fit(sim);

    AssemblerOptions options;
    options.reorder_window_s = 0.3;
    DwellAssembler assembler(options);
    MoveSampleRecorder recorder;
    assembler.set_release_observers([&recorder](const GimbalEvent& e) { recorder.add_command(e); },
                                    [&recorder](const ImuSample& s) { recorder.add_sample(s); });
    // Arrival order: commands 0.2 s late (inside the reorder window), samples in order.
    std::vector<std::pair<double, int>>
        arrivals;  // (arrival time, index: >= 0 sample, < 0 command)
    for (std::size_t i = 0; i < run.recording.samples.size(); ++i)
      arrivals.emplace_back(run.recording.samples[i].stamp_s, static_cast<int>(i));
    for (std::size_t i = 0; i < run.recording.commands.size(); ++i)
      arrivals.emplace_back(run.recording.commands[i].stamp_s + 0.2, -1 - static_cast<int>(i));
    std::stable_sort(arrivals.begin(), arrivals.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& a : arrivals) {
      if (a.second >= 0) {
        assembler.add_sample(run.recording.samples[static_cast<std::size_t>(a.second)]);
      } else {
        assembler.add_command(run.recording.commands[static_cast<std::size_t>(-1 - a.second)]);
      }
    }
    assembler.flush();
    ASSERT_EQ(assembler.table().rows.size(), run.table.rows.size());
    EXPECT_EQ(recorder.commands().size(), run.recording.commands.size());
    EXPECT_EQ(recorder.samples_dropped(), 0u);
    EXPECT_LT(recorder.samples().size(), run.recording.samples.size() / 2);

    const TimingLagEstimate whole =
        estimate_timing_lag(run.recording.commands, run.recording.samples, run.table, run.base);
    const TimingLagEstimate kept =
        estimate_timing_lag(recorder.commands(), recorder.samples(), run.table, run.base);
    ASSERT_TRUE(whole.ok) << whole.message;
    ASSERT_TRUE(kept.ok) << kept.message;
    EXPECT_EQ(kept.samples_used, whole.samples_used);
    EXPECT_EQ(kept.moves_used, whole.moves_used);
    EXPECT_NEAR(kept.lag_s, whole.lag_s, 1e-12);
    EXPECT_NEAR(kept.std_s, whole.std_s, 1e-12);
  }
}

TEST(MoveSampleRecorder, StopsAtItsCapAndCounts) {
  MoveSampleRecorder recorder(0.1, 10);
  GimbalEvent e;
  e.state = GimbalState::Settled;
  recorder.add_command(e);  // at rest in phase x
  e.state = GimbalState::Moving;
  e.stamp_s = 1.0;
  recorder.add_command(e);  // a move within the phase: keep everything until SETTLED + margin
  for (int i = 0; i < 25; ++i) {
    ImuSample s;
    s.stamp_s = 1.0 + 0.01 * i;
    recorder.add_sample(s);
  }
  EXPECT_EQ(recorder.samples().size(), 10u);
  EXPECT_EQ(recorder.samples_dropped(), 15u);
  recorder.clear();
  EXPECT_TRUE(recorder.samples().empty());
  EXPECT_TRUE(recorder.commands().empty());
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
