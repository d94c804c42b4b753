// The quality gate: honest simulated runs pass (random devices, mountings, seeds); a run on an
// unsynchronized clock, outputs in other units, a near-degenerate triad and starved dwells each
// fail with a reason that names what is wrong.
#include "accel_intrinsics/core/fit/quality.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "../../support/random_device.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

SimulationOptions honest_stand(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  SimulationOptions sim;
  sim.truth = testing_devices::random_device(rng);
  sim.protocol.steps_per_phase = 8;
  sim.seed = seed;
  return sim;
}

bool mentions(const Quality& q, const std::string& word) {
  for (const std::string& r : q.reasons) {
    if (r.find(word) != std::string::npos) return true;
  }
  return false;
}

TEST(QualityGate, ReducedChi2UpperEndIsTheChiSquareQuantile) {
  // chi2(10) 0.9995 quantile = 31.42 (tables); per degree of freedom 3.142.
  EXPECT_NEAR(reduced_chi2_upper(10, 0.999), 3.142, 2e-3);
  EXPECT_GT(reduced_chi2_upper(10, 0.999), reduced_chi2_upper(1000, 0.999));
}

TEST(QualityGate, HonestRunsPass) {
  for (std::uint64_t seed = 1; seed <= 60; ++seed) {
    const PositionTable table = simulate_position_table(honest_stand(seed));
    for (FitModel model : {FitModel::Joint, FitModel::Eq4}) {
      CalibrateOptions options;
      options.fit.model = model;
      const CalibrationReport report = calibrate(table, nullptr, options);
      EXPECT_TRUE(report.quality.pass) << "seed " << seed << ": " << report.quality.summary();
      EXPECT_TRUE(report.quality.reasons.empty());
    }
  }
}

TEST(QualityGate, UnsynchronizedClockFailsOnChiSquare) {
  const Recording rec = simulate_recording(honest_stand(3));
  AssemblerOptions assembler_options;
  assembler_options.reorder_window_s = 20.0;
  DwellAssembler assembler(assembler_options);
  Recording shifted = rec;
  for (ImuSample& s : shifted.samples) s.stamp_s += 1.3;  // IMU clock 1.3 s ahead
  feed_in_stamp_order(shifted, &assembler);
  const CalibrationReport report = calibrate(assembler.table(), nullptr, {});
  EXPECT_FALSE(report.quality.pass);
  EXPECT_TRUE(mentions(report.quality, "reduced chi-square")) << report.quality.summary();
}

TEST(QualityGate, OutputsInOtherUnitsNeedOutputUnit) {
  PositionTable table = simulate_position_table(honest_stand(4));
  for (DwellRecord& row : table.rows) {  // cm/s^2 instead of m/s^2
    row.mean *= 100.0;
    row.std *= 100.0;
  }
  CalibrateOptions options;
  const CalibrationReport si = calibrate(table, nullptr, options);
  EXPECT_FALSE(si.quality.pass);
  EXPECT_TRUE(mentions(si.quality, "output_unit")) << si.quality.summary();
  options.quality.outputs_in_si = false;
  EXPECT_TRUE(calibrate(table, nullptr, options).quality.pass);
}

TEST(QualityGate, ImplausibleTriadFails) {
  SimulationOptions sim = honest_stand(5);
  sim.truth.S = Eigen::Matrix3d::Identity();
  sim.truth.S.row(1) = Eigen::Vector3d(0.8, 0.6, 0.0);  // 37 degrees from u
  const CalibrationReport report = calibrate(simulate_position_table(sim), nullptr, {});
  EXPECT_FALSE(report.quality.pass);
  EXPECT_TRUE(mentions(report.quality, "theta_uv")) << report.quality.summary();
  EXPECT_FALSE(mentions(report.quality, "theta_vw")) << report.quality.summary();

  SimulationOptions lopsided = honest_stand(6);
  lopsided.truth.S.row(2) *= 3.0;  // one axis three times the others, outputs in counts
  CalibrateOptions counts;
  counts.quality.outputs_in_si = false;
  const CalibrationReport r2 = calibrate(simulate_position_table(lopsided), nullptr, counts);
  EXPECT_FALSE(r2.quality.pass);
  EXPECT_TRUE(mentions(r2.quality, "differs from the mean")) << r2.quality.summary();
}

TEST(QualityGate, StarvedDwellFails) {
  PositionTable table = simulate_position_table(honest_stand(7));
  table.rows[5].n = 2;
  const CalibrationReport report = calibrate(table, nullptr, {});
  EXPECT_FALSE(report.quality.pass);
  EXPECT_TRUE(mentions(report.quality, "2 samples")) << report.quality.summary();
}

// A responsivity that is zero, negative or NaN is no responsivity at all: the gate must say so in
// every unit mode (a NaN slips past every range and spread comparison).
TEST(QualityGate, NonPositiveOrNanResponsivityIsNamed) {
  const PositionTable table = simulate_position_table(honest_stand(8));
  const CalibrationReport report = calibrate(table, nullptr, {});
  ASSERT_TRUE(report.quality.pass) << report.quality.summary();
  for (bool si : {true, false}) {
    QualityOptions options;
    options.outputs_in_si = si;
    for (double bad : {std::nan(""), 0.0, -1.0}) {
      FitResult fit = report.certificate;
      fit.intrinsics.responsivity(1) = bad;
      const Quality q = assess_quality(fit, table, options);
      EXPECT_FALSE(q.pass) << "responsivity " << bad << " si " << si;
      EXPECT_TRUE(mentions(q, "responsivity |v|")) << q.summary();
      EXPECT_TRUE(mentions(q, "is not a responsivity"))
          << "responsivity " << bad << ": " << q.summary();
    }
  }
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
