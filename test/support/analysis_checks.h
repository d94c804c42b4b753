// Shared by the tests that hide effects in simulated runs and check what core::analyze() names
// (discrepancy, closing position, temperature): lookups in an AnalysisResult, the detection
// threshold of a candidate, a one-line description for SCOPED_TRACE, and the per-trial bands of
// issue 15 item 6 (every band a quantile, Bonferroni over the trials, so that a correct analysis
// fails a whole test by chance in fewer than 1e-3 runs whatever the seeds).
#pragma once

#include <gtest/gtest.h>

#include <sstream>
#include <string>

#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "statistical_bounds.h"

namespace accel_intrinsics {
namespace analysis_checks {

inline const core::NamedEffect* find_named(const core::AnalysisResult& a, core::EffectKind kind,
                                           int target) {
  for (const core::NamedEffect& e : a.effects) {
    if (e.effect.kind == kind && e.effect.target == target) return &e;
  }
  return nullptr;
}

inline const core::CandidateScore* find_candidate(const core::ScreeningStep& step,
                                                  core::EffectKind kind, int target) {
  for (const core::CandidateScore& c : step.candidates) {
    if (c.effect.kind == kind && c.effect.target == target) return &c;
  }
  return nullptr;
}

// Whether one ambiguity group holds both labels; its separating experiment in `experiment`.
inline bool ambiguous_pair(const core::AnalysisResult& a, const std::string& x,
                           const std::string& y, std::string* experiment = nullptr) {
  for (const core::Ambiguity& amb : a.ambiguous) {
    bool has_x = false, has_y = false;
    for (const std::string& c : amb.candidates) {
      has_x = has_x || c == x;
      has_y = has_y || c == y;
    }
    if (has_x && has_y) {
      if (experiment) *experiment = amb.separating_experiment;
      return true;
    }
  }
  return false;
}

inline std::string describe(const core::AnalysisResult& a) {
  std::ostringstream os;
  os << "named:";
  for (const core::NamedEffect& e : a.effects) {
    os << ' ' << e.effect.label() << '=' << e.effect.value << "+-" << e.std << " (closest "
       << e.closest_alternative << ", |corr| " << e.closest_correlation << ')';
  }
  os << "; chi2_r " << a.before.summary.reduced_chi2 << " -> " << a.after.summary.reduced_chi2
     << " (" << a.stop_reason << "); ambiguous groups " << a.ambiguous.size() << "; not screened "
     << a.not_screened.size();
  return os.str();
}

// The detection threshold of kind[target] for this device, protocol and noise: screened on the
// same simulation without the effect. 0 when it was not a candidate (a failure is recorded);
// a candidate the design cannot identify records a failure too.
inline double detection_threshold(const core::SimulationOptions& so, core::EffectKind kind,
                                  int target) {
  const core::AnalysisResult clean = core::analyze(core::simulate_position_table(so));
  const core::CandidateScore* c = find_candidate(clean.steps.front(), kind, target);
  EXPECT_NE(c, nullptr) << core::effect_info(kind).name << " was not screened";
  if (c == nullptr) return 0.0;
  EXPECT_TRUE(c->identifiable) << core::effect_info(kind).name;
  return c->detection_threshold;
}

// Bands for `trials` trials making `checks_per_trial` two-sided checks each, 1e-3 in all.
struct TrialBands {
  double k = 0.0;     // |estimate - truth| <= k std
  double tail = 0.0;  // per check
};
inline TrialBands trial_bands(int trials, int checks_per_trial) {
  TrialBands b;
  b.tail = 1e-3 / static_cast<double>(checks_per_trial * trials);
  b.k = statistical_bounds::normal_k(b.tail);
  return b;
}

// The gap after the fit: chi2 ~ chi2(dof) under noise alone, one-sided tail `tail` on each side.
inline void expect_chi2_in_band(const core::GapSummary& g, double tail) {
  const auto band = statistical_bounds::chi2_band(g.dof, tail);
  EXPECT_GE(g.chi2, band.first) << "dof " << g.dof;
  EXPECT_LE(g.chi2, band.second) << "dof " << g.dof;
}

}  // namespace analysis_checks
}  // namespace accel_intrinsics
