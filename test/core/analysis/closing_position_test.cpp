// The closing position (ProtocolOptions::closing_position, issue 5): step N at 2 pi after the
// up-sweep of each phase. The discrepancy analysis must keep offset drift and angle-scale errors
// apart on such runs, and the position at 2 pi must carry the extra information about an
// angle-scale error that motivates it (it would carry none if the angle were wrapped to 0).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <string>

#include "../../support/analysis_checks.h"
#include "../../support/random_device.h"
#include "../../support/statistical_bounds.h"
#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

using analysis_checks::describe;
using analysis_checks::detection_threshold;
using analysis_checks::find_candidate;
using testing_devices::random_device;

SimulationOptions closing_simulation(std::uint64_t seed, std::uint32_t steps = 24,
                                     bool two_way = false) {
  std::mt19937_64 rng(seed);
  SimulationOptions so;
  so.truth = random_device(rng);
  std::uniform_real_distribution<double> density(150e-6, 400e-6);
  so.noise_density = density(rng) * kStandardGravity;
  so.protocol.steps_per_phase = steps;
  so.protocol.closing_position = true;
  so.protocol.two_way = two_way;
  so.seed = seed * 7 + 3;
  return so;
}

bool named_kind(const AnalysisResult& a, EffectKind kind) {
  return std::any_of(a.effects.begin(), a.effects.end(),
                     [&](const NamedEffect& e) { return e.effect.kind == kind; });
}

// Whether some ambiguity group holds both an offset_drift and an angle_scale candidate.
bool drift_and_scale_ambiguous(const AnalysisResult& a) {
  for (const Ambiguity& amb : a.ambiguous) {
    auto has = [&](const char* prefix) {
      return std::any_of(amb.candidates.begin(), amb.candidates.end(),
                         [&](const std::string& c) { return c.rfind(prefix, 0) == 0; });
    };
    if (has("offset_drift[") && has("angle_scale[")) return true;
  }
  return false;
}

// Hides `kind` at 3, 5 and 10 times its detection threshold on closing-position runs (every
// target once, both signs) and checks it is named as itself, never as the other of the pair.
// The recovery band and the upper chi-square bound are quantiles at 1e-3 / 12 (two checks in
// each of the 3 trials of the 2 tests; issue 15: together they fail by chance in fewer than 1e-3
// runs, where 3 std and the 99 % band would in about 4 %).
void expect_named_not_confused(EffectKind kind, EffectKind other, std::uint64_t seed0) {
  const double multiples[] = {3.0, 5.0, 10.0};
  const double tail = 1e-3 / 12.0;
  const double k = statistical_bounds::normal_k(tail);
  for (int trial = 0; trial < 3; ++trial) {
    SimulationOptions so = closing_simulation(seed0 + static_cast<std::uint64_t>(trial));
    const int target = trial;
    const double threshold = detection_threshold(so, kind, target);
    ASSERT_GT(threshold, 0.0);
    const Effect hidden{kind, target, (trial % 2 == 0 ? 1.0 : -1.0) * multiples[trial] * threshold};
    so.truth.effects = {hidden};
    const PositionTable table = simulate_position_table(so);
    ASSERT_EQ(table.rows.size(), 3u * 25u);
    const AnalysisResult a = analyze(table);
    SCOPED_TRACE(hidden.label() + " = " + std::to_string(hidden.value) + ": " + describe(a));
    ASSERT_FALSE(a.effects.empty());
    const NamedEffect& first = a.effects.front();
    EXPECT_EQ(first.effect.label(), hidden.label());
    EXPECT_LE(std::abs(first.effect.value - hidden.value), k * first.std);
    EXPECT_FALSE(named_kind(a, other));
    EXPECT_FALSE(drift_and_scale_ambiguous(a));
    EXPECT_LE(a.after.summary.chi2,
              statistical_bounds::chi2_band(a.after.summary.dof, tail).second);
  }
}

TEST(ClosingPosition, HiddenDriftIsNamedAsDriftNotAngleScale) {
  expect_named_not_confused(EffectKind::OffsetDrift, EffectKind::AngleScale, 5100);
}

TEST(ClosingPosition, HiddenAngleScaleIsNamedAsAngleScaleNotDrift) {
  expect_named_not_confused(EffectKind::AngleScale, EffectKind::OffsetDrift, 5200);
}

TEST(ClosingPosition, IsWorthMoreForAngleScaleThanAnotherStep) {
  // Same number of dwells and the same run time: N = 12 plus the closing position against
  // N = 13 without it. The position at 2 pi, where an angle-scale error is largest (eps 2 pi),
  // must pin the scale down better than one more step of the sweep does (measured: standard
  // uncertainty 0.89..0.93 times), and help it more than the angle offset, which reads there as
  // at 0 deg. A closing angle wrapped to 0 would carry no scale information (ratio above 1).
  for (std::uint64_t seed : {61u, 62u}) {
    SimulationOptions closing = closing_simulation(seed, 12);
    SimulationOptions more = closing;
    more.protocol.steps_per_phase = 13;
    more.protocol.closing_position = false;
    const PositionTable closing_table = simulate_position_table(closing);
    const PositionTable more_table = simulate_position_table(more);
    ASSERT_EQ(closing_table.rows.size(), more_table.rows.size());
    EXPECT_NEAR(closing_table.rows.back().t_end_s, more_table.rows.back().t_end_s, 1e-9);
    AnalysisOptions options;
    options.monte_carlo_draws = 200;  // only the screening's estimate_std is compared
    options.max_effects = 0;
    const ScreeningStep with = analyze(closing_table, options).steps.front();
    const ScreeningStep without = analyze(more_table, options).steps.front();
    for (int p = 0; p < 3; ++p) {
      const CandidateScore* s1 = find_candidate(with, EffectKind::AngleScale, p);
      const CandidateScore* s0 = find_candidate(without, EffectKind::AngleScale, p);
      const CandidateScore* o1 = find_candidate(with, EffectKind::AngleOffset, p);
      const CandidateScore* o0 = find_candidate(without, EffectKind::AngleOffset, p);
      ASSERT_TRUE(s1 && s0 && o1 && o0);
      const double scale_ratio = s1->estimate_std / s0->estimate_std;
      const double offset_ratio = o1->estimate_std / o0->estimate_std;
      EXPECT_LT(scale_ratio, 0.95) << "seed " << seed << " phase " << p;
      EXPECT_LT(scale_ratio, offset_ratio - 0.03) << "seed " << seed << " phase " << p;
    }
  }
}

TEST(ClosingPosition, WithTwoWaySweepBacklashIsStillSeparatedFromAngleOffset) {
  // 0..N-1, N at 2 pi, then N-1..0 from above: the inferred directions of approach must still
  // make backlash flip sign, so a hidden backlash is named as backlash.
  SimulationOptions so = closing_simulation(4343, 24, true);
  const double t = detection_threshold(so, EffectKind::Backlash, 2);
  ASSERT_GT(t, 0.0);
  so.truth.effects = {Effect{EffectKind::Backlash, 2, 6.0 * t}};
  const PositionTable table = simulate_position_table(so);
  ASSERT_EQ(table.rows.size(), 3u * 49u);
  const AnalysisResult a = analyze(table);
  SCOPED_TRACE(describe(a));
  ASSERT_FALSE(a.effects.empty());
  EXPECT_EQ(a.effects.front().effect.label(), "backlash[z]");
  for (const NamedEffect& e : a.effects) EXPECT_NE(e.effect.label(), "angle_offset[z]");
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
