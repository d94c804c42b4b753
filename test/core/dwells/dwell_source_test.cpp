// The dwell-source seam (core/dwell_source.h): a gimbal run's stream with its commands through
// the commanded source, and the same samples without any command through the detected source,
// give the same dwells, the detected ones within the rest detector's trimming; and the detected
// source's rows are the rest detector's own rests, also when it cut a disturbance out of one.
#include "accel_intrinsics/core/dwells/dwell_source.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

// A gimbal run whose rests are its dwells: no settle time after a move (the move ends at
// SETTLED), no still remount between phases (the orientation changes at once).
SimulationOptions still_only_in_dwells() {
  SimulationOptions sim;
  sim.protocol.steps_per_phase = 4;
  sim.protocol.move_s = 1.0;
  sim.protocol.settle_s = 0.0;
  sim.protocol.phase_change_s = 0.0;
  sim.protocol.dwell_s = 4.0;
  sim.rate_hz = 100.0;
  sim.seed = 11;
  return sim;
}

// Feeds commands (when `with_commands`) and samples in stamp order, then finishes.
CompletedRows run_source(DwellSource* source, const Recording& rec, bool with_commands) {
  CompletedRows rows;
  const auto keep = [&rows](const CompletedRows& r) {
    rows.insert(rows.end(), r.begin(), r.end());
  };
  std::size_t c = 0;
  for (const ImuSample& s : rec.samples) {
    while (with_commands && c < rec.commands.size() && rec.commands[c].stamp_s <= s.stamp_s) {
      keep(source->add_command(rec.commands[c++]));
    }
    keep(source->add_sample(s));
  }
  while (with_commands && c < rec.commands.size()) keep(source->add_command(rec.commands[c++]));
  keep(source->finish());
  return rows;
}

void expect_same_rows(const CompletedRows& a, const std::vector<DwellRecord>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].n, b[i].n) << i;
    EXPECT_EQ(a[i].t_start_s, b[i].t_start_s) << i;
    EXPECT_EQ(a[i].t_end_s, b[i].t_end_s) << i;
    EXPECT_EQ(a[i].step, b[i].step) << i;
    EXPECT_TRUE(a[i].orientation_unknown) << i;
    for (int k = 0; k < 3; ++k) {
      // The same samples summed in another order.
      EXPECT_NEAR(a[i].mean(k), b[i].mean(k), 1e-12 * (1.0 + std::abs(b[i].mean(k)))) << i;
      EXPECT_NEAR(a[i].std(k), b[i].std(k), 1e-9 * b[i].std(k)) << i;
    }
  }
}

TEST(DwellSource, DetectedRestsGiveTheCommandedDwellsWithinTheTrimming) {
  const SimulationOptions sim = still_only_in_dwells();
  const Recording rec = simulate_recording(sim);
  DwellAssembler commanded_assembler, detected_assembler;
  CommandedDwellSource commanded(&commanded_assembler);
  RestDetectionOptions rest_options;
  DetectedDwellSource detected(&detected_assembler, rest_options);
  const CompletedRows by_command = run_source(&commanded, rec, true);
  const CompletedRows by_rest = run_source(&detected, rec, false);
  EXPECT_STREQ(commanded.name(), "commanded");
  EXPECT_STREQ(detected.name(), "detected");
  ASSERT_EQ(by_command.size(), 12u);
  ASSERT_EQ(by_rest.size(), by_command.size());
  EXPECT_EQ(detected.commands_ignored(), 0u);
  const double sigma = sample_noise_std(sim);
  // Trimmed at both ends, and the still blocks need not line up with the commands.
  const double slack_s = rest_options.trim_s + 2.0 * rest_options.block_s;
  for (std::size_t i = 0; i < by_rest.size(); ++i) {
    const DwellRecord& d = by_rest[i];
    const DwellRecord& c = by_command[i];
    EXPECT_FALSE(c.orientation_unknown);
    EXPECT_TRUE(d.orientation_unknown);
    EXPECT_EQ(d.step, i);  // rests are numbered in time order
    EXPECT_GE(d.t_start_s, c.t_start_s) << i;
    EXPECT_LE(d.t_start_s, c.t_start_s + slack_s) << i;
    EXPECT_LE(d.t_end_s, c.t_end_s) << i;
    EXPECT_GE(d.t_end_s, c.t_end_s - slack_s) << i;
    EXPECT_LT(d.n, c.n) << i;
    EXPECT_GE(static_cast<double>(d.n), c.n - 2.0 * slack_s * sim.rate_hz) << i;
    for (int k = 0; k < 3; ++k) {
      // The detected samples are a subset of the dwell's: their means differ by noise only.
      EXPECT_NEAR(d.mean(k), c.mean(k), 5.0 * sigma / std::sqrt(static_cast<double>(d.n)))
          << i << " " << k;
      EXPECT_NEAR(d.std(k), c.std(k), 0.2 * sigma) << i << " " << k;
    }
  }
}

TEST(DwellSource, DetectedRowsAreTheRestDetectorsRestsAndCommandsAreIgnored) {
  const Recording rec = simulate_recording(still_only_in_dwells());
  const RestDetection streamed = [&] {
    // The streaming detector on the same samples, as the source runs it.
    RestDetector detector;
    for (const ImuSample& s : rec.samples) detector.add(s.stamp_s, s.outputs);
    detector.finish();
    RestDetection out;
    out.rests = detector.take_rests();
    return out;
  }();
  DwellAssembler assembler;
  DetectedDwellSource source(&assembler, RestDetectionOptions());
  const CompletedRows rows = run_source(&source, rec, /*with_commands=*/true);
  EXPECT_EQ(source.commands_ignored(), rec.commands.size());
  expect_same_rows(rows, streamed.rests);
}

TEST(DwellSource, DisturbanceCutOutOfARestIsLeftOutOfItsRow) {
  // Three rests; a 0.3 s jolt in the middle of the second, which the detector cuts out and joins
  // the two sides of: the source's row must leave the jolt's samples out in the same way.
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.01);
  const Eigen::Vector3d ups[] = {Eigen::Vector3d(0, 0, 9.8), Eigen::Vector3d(0, 9.8, 0),
                                 Eigen::Vector3d(9.8, 0, 0)};
  Recording rec;
  double t = 0.0;
  for (int r = 0; r < 3; ++r) {
    for (int i = 0; i < 600; ++i, t += 0.01) {  // 6 s at rest
      ImuSample s;
      s.stamp_s = t;
      s.outputs = ups[r] + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      if (r == 1 && i >= 300 && i < 330) s.outputs += Eigen::Vector3d(0.5, -0.8, 0.6) * std::sin(i);
      rec.samples.push_back(s);
    }
    for (int i = 0; i < 100; ++i, t += 0.01) {  // 1 s turning to the next
      ImuSample s;
      s.stamp_s = t;
      s.outputs = ups[r] * std::cos(0.0157 * i) + ups[(r + 1) % 3] * std::sin(0.0157 * i) +
                  Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      rec.samples.push_back(s);
    }
  }
  RestDetector detector;
  for (const ImuSample& s : rec.samples) detector.add(s.stamp_s, s.outputs);
  detector.finish();
  const std::vector<DwellRecord> rests = detector.take_rests();
  bool cut = false;
  for (const RejectedSpan& r : detector.rejected()) {
    cut = cut || r.reason.find("disturbance inside a rest") != std::string::npos;
  }
  ASSERT_TRUE(cut) << "the jolt was not cut out: the test does not test the cut";
  DwellAssembler assembler;
  DetectedDwellSource source(&assembler, RestDetectionOptions());
  expect_same_rows(run_source(&source, rec, false), rests);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
