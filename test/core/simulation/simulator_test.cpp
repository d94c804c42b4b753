#include "accel_intrinsics/core/simulation/simulator.h"

#include <gtest/gtest.h>

#include <cmath>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"

namespace core = accel_intrinsics::core;

namespace {
core::SimulationOptions options() {
  core::SimulationOptions sim;
  sim.truth.S << 1.02, 0.01, -0.015, 0.004, 0.985, 0.012, -0.02, 0.006, 1.01;
  sim.truth.O << 0.05, -0.12, 0.2;
  sim.protocol.steps_per_phase = 8;
  sim.protocol.dwell_s = 1.0;
  sim.rate_hz = 400;
  sim.noise_density = 1e-3;
  return sim;
}
}  // namespace

TEST(Simulator, IsReproducibleBySeed) {
  auto sim = options();
  const auto a = core::simulate_position_table(sim);
  const auto b = core::simulate_position_table(sim);
  sim.seed = 2;
  const auto c = core::simulate_position_table(sim);
  ASSERT_EQ(a.rows.size(), 24u);
  EXPECT_EQ(a.rows[5].mean, b.rows[5].mean);
  EXPECT_NE(a.rows[5].mean, c.rows[5].mean);
}

TEST(Simulator, RecordingThroughTheAssemblerAgreesWithTheDirectTable) {
  // The raw streams, assigned to dwells, must reproduce the model means within noise and the
  // same sample counts as the direct table (same timeline, same model).
  const auto sim = options();
  const auto rec = core::simulate_recording(sim);
  core::DwellAssembler assembler;
  core::feed_in_stamp_order(rec, &assembler);
  const auto direct = core::simulate_position_table(sim);
  const auto& rows = assembler.table().rows;
  ASSERT_EQ(rows.size(), direct.rows.size());
  const double sigma = core::sample_noise_std(sim);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].n, direct.rows[i].n) << i;
    EXPECT_EQ(rows[i].step, direct.rows[i].step);
    const double se = sigma / std::sqrt(static_cast<double>(rows[i].n));
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(rows[i].mean(k), direct.rows[i].mean(k), 8 * se) << "row " << i << " axis " << k;
      EXPECT_NEAR(rows[i].std(k), sigma, 0.25 * sigma);
    }
  }
}

TEST(Simulator, DirectTableNoiseMatchesItsStatedDistribution) {
  auto sim = options();
  sim.protocol.steps_per_phase = 200;
  sim.truth.O.setZero();
  const auto noisy = core::simulate_position_table(sim);
  sim.noise_density = 0.0;
  const auto clean = core::simulate_position_table(sim);
  const double sigma = core::sample_noise_std(options());
  double z2 = 0.0, std_sum = 0.0;
  int count = 0;
  for (std::size_t i = 0; i < noisy.rows.size(); ++i) {
    const double se = sigma / std::sqrt(static_cast<double>(noisy.rows[i].n));
    for (int k = 0; k < 3; ++k) {
      z2 += std::pow((noisy.rows[i].mean(k) - clean.rows[i].mean(k)) / se, 2);
      std_sum += noisy.rows[i].std(k);
      ++count;
    }
    EXPECT_EQ(clean.rows[i].std, Eigen::Vector3d::Zero());
  }
  // 1800 standard normals: the mean square is 1 within about 4 * sqrt(2/1800).
  EXPECT_NEAR(z2 / count, 1.0, 0.14);
  EXPECT_NEAR(std_sum / count, sigma, 0.01 * sigma);
}

TEST(Simulator, TimingLagDelaysStamps) {
  auto sim = options();
  sim.truth.effects = {core::make_effect("timing_lag", "all", 0.02)};
  const auto rec = core::simulate_recording(sim);
  EXPECT_NEAR(rec.samples[10].stamp_s, 10.0 / sim.rate_hz + 0.02, 1e-12);
  EXPECT_DOUBLE_EQ(rec.commands[0].stamp_s, 0.0);
}

TEST(Simulator, RejectsInvalidOptionsNamingTheField) {
  auto sim = options();
  sim.rate_hz = -1;
  try {
    core::simulate_position_table(sim);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("rate_hz"), std::string::npos);
  }
  sim = options();
  sim.truth.S.row(2) = sim.truth.S.row(0);
  EXPECT_THROW(core::simulate_position_table(sim), std::invalid_argument);
}
