#include "accel_intrinsics/core/analysis/discrepancy.h"

#include <ceres/jet.h>

#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/non_central_chi_squared.hpp>
#include <cmath>
#include <iomanip>
#include <limits>
#include <numeric>
#include <optional>
#include <ostream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/fit/preconditions.h"
#include "discrepancy_internal.h"

namespace accel_intrinsics {
namespace core {

namespace analysis_detail {

bool same_term(const Effect& a, const Effect& b) {
  return a.kind == b.kind && a.target == b.target;
}

bool contains_term(const std::vector<Effect>& list, const Effect& e) {
  return std::any_of(list.begin(), list.end(), [&](const Effect& x) { return same_term(x, e); });
}

}  // namespace analysis_detail

using namespace analysis_detail;

namespace {

// The vocabulary's noise-model entry (discrepancy.h NoiseEntry).
NoiseEntry correlated_noise_entry(const PositionTable& table, const FitResult& final_fit,
                                  const AnalysisOptions& options, const Gap& model_gap) {
  NoiseEntry e;
  e.noise_model = options.noise_model.kind();
  FitOptions white;
  white.model = FitModel::Joint;
  white.local_gravity = options.local_gravity;
  white.effects = final_fit.effects;
  GapSummary white_gap = model_gap.summary;
  if (!options.noise_model.white()) {
    try {
      white_gap = compute_gap(table, fit(table, white), 0, 1).summary;
    } catch (const std::exception& ex) {
      e.reason = std::string("the white refit failed: ") + ex.what();
      return e;
    }
  }
  e.white_reduced_chi2 = white_gap.reduced_chi2;
  e.white_p_value = white_gap.p_value;
  e.model_reduced_chi2 = model_gap.summary.reduced_chi2;
  e.model_p_value = model_gap.summary.p_value;
  const bool exceeds_white = white_gap.p_value < options.alpha;
  if (options.noise_model.white()) {
    e.reason = exceeds_white
                   ? "the residuals exceed the white-noise prediction, but the run has no noise "
                     "model (no long rest: protocol initial_rest_s, or a dwell 10 times the "
                     "median) to tell correlated noise from a missing effect"
                   : "no noise model, and the residuals are consistent with white noise";
    return e;
  }
  const bool explained = model_gap.summary.p_value >= options.alpha;
  e.named = exceeds_white && explained;
  if (e.named) {
    e.reason = "the residuals exceed the white-noise prediction and the noise model (" +
               e.noise_model +
               ") explains them; no catalog effect explains them better out of sample";
  } else if (!exceeds_white) {
    e.reason = "the residuals are consistent with white noise";
  } else {
    e.reason = "the residuals exceed even the noise model (" + e.noise_model +
               "): something else is missing";
  }
  return e;
}

}  // namespace

void validate(const AnalysisOptions& options) {
  auto fail = [](const std::string& m) { throw std::invalid_argument("analysis: " + m); };
  if (!std::isfinite(options.local_gravity) || options.local_gravity <= 0.0)
    fail("local_gravity must be positive");
  if (!(options.alpha > 0.0 && options.alpha < 1.0)) fail("alpha must be in (0, 1)");
  if (options.max_effects < 0) fail("max_effects must be >= 0");
  if (!(options.min_temperature_span_k >= 0.0) || !std::isfinite(options.min_temperature_span_k))
    fail("min_temperature_span_k must be a non-negative number of K");
  if (options.monte_carlo_draws < 100) fail("monte_carlo_draws must be >= 100");
  if (!(options.ambiguity_correlation > 0.0 && options.ambiguity_correlation <= 1.0)) {
    fail("ambiguity_correlation must be in (0, 1]");
  }
  if (!(options.identifiability_floor >= 0.0 && options.identifiability_floor < 1.0)) {
    fail("identifiability_floor must be in [0, 1)");
  }
  if (options.refit_top < 1) fail("refit_top must be >= 1");
  if (options.harmonics < 0 || options.harmonics > 32) fail("harmonics must be in [0, 32]");
  if (options.time_bins < 1) fail("time_bins must be >= 1");
  if (options.cv_folds < 0 || options.cv_folds == 1) fail("cv_folds must be 0 (none) or >= 2");
  if (!(options.detection_power > 0.0 && options.detection_power < 1.0))
    fail("detection_power must be in (0, 1)");
}

AnalysisResult analyze(const PositionTable& table, const AnalysisOptions& options) {
  validate(options);
  AnalysisResult result;
  result.local_gravity = options.local_gravity;
  if (stop_analysis_on_setup_mistakes(table, options, &result)) return result;
  // The table prepared once for the many fits below (fit/prepared_table.h).
  const PreparedTable prepared(table);
  const std::vector<DwellGeometry>& geoms = prepared.geometries();
  const RunConditions run = run_conditions(table, geoms, options.min_temperature_span_k);

  // Candidate family.
  std::vector<Effect> candidates = options.candidates.empty()
                                       ? default_candidates(table, options.min_temperature_span_k)
                                       : options.candidates;
  {
    std::vector<Effect> kept;
    for (const Effect& c : candidates) {
      // Effects that need raw streams: reported below, whatever their target.
      if (effect_info(c.kind).precondition == Precondition::RawStreams) continue;
      if (c.target < 0 || c.target > 2) {
        throw std::invalid_argument("analysis: candidate " + c.name() + " has target index " +
                                    std::to_string(c.target) + "; expected 0..2");
      }
      if (!screenable(c, run)) continue;
      if (contains_term(options.base_effects, c) || contains_term(kept, c)) continue;
      kept.push_back(c);
    }
    candidates = kept;
  }
  // What the dwell means of this run cannot show, per effect and target, from the catalog.
  for (const EffectInfo& info : effect_catalog()) {
    for (int target : effect_targets(info.kind)) {
      const Effect effect{info.kind, target, 0.0};
      if (!screenable(effect, run))
        result.not_screened.push_back(effect.label() + ": " + not_screened_note(effect, run));
    }
  }
  std::ostringstream gnote;
  gnote << std::setprecision(8)
        << "local_gravity: a wrong g scales all three responsivities together and "
        << "leaves no residual; an independent g (gravimeter, or normal_gravity(latitude, height)) "
           "is the "
        << "only cure. This analysis used g = " << options.local_gravity << " m/s^2";
  result.unobservable.push_back(gnote.str());

  // 1. Base fit.
  FitOptions fo;
  fo.model = FitModel::Joint;
  fo.local_gravity = options.local_gravity;
  fo.effects = options.base_effects;
  fo.noise_model = options.noise_model;
  // The rest's slow part, scaled up to the run's residuals when it falls short (see the header).
  fo.noise_model = slow_part_from_run(table, fo);
  result.noise_model = fo.noise_model;
  FitResult current = fit(prepared, fo);
  result.before_fit = current;
  result.before = compute_gap(table, current, options.harmonics, options.time_bins);
  const bool cross_validate = options.cv_folds >= 2;
  if (cross_validate) result.before.cv = cross_validated_gap(table, fo, options.cv_folds);
  double cv_current = result.before.cv.cv_chi2_per_point;
  std::vector<Effect> model_terms = options.base_effects;

  result.stop_reason = "max_effects reached";
  for (int step = 0; step < options.max_effects + 1; ++step) {
    std::vector<Effect> remaining;
    for (const Effect& c : candidates) {
      if (!contains_term(model_terms, c)) remaining.push_back(c);
    }
    Screening sc = screen(table, geoms, current, model_terms, remaining, options, step);
    sc.step.gap = compute_gap(table, current, 0, 1).summary;
    if (step == 0) {
      for (const CandidateScore& cs : sc.step.candidates) {
        if (!cs.identifiable) result.unidentifiable.push_back(cs);
      }
    }
    if (step == options.max_effects) {
      result.steps.push_back(sc.step);
      break;
    }
    if (options.stop_when_consistent && sc.step.gap.consistent_with_noise) {
      result.stop_reason = "gap consistent with noise";
      result.steps.push_back(sc.step);
      break;
    }
    // Significant candidates, strongest first.
    std::vector<int> significant;
    for (std::size_t k = 0; k < sc.step.candidates.size(); ++k) {
      const CandidateScore& cs = sc.step.candidates[k];
      if (cs.identifiable && cs.p_adjusted <= options.alpha)
        significant.push_back(static_cast<int>(k));
    }
    if (significant.empty()) {
      bool any = std::any_of(sc.step.candidates.begin(), sc.step.candidates.end(),
                             [](const CandidateScore& c) { return c.identifiable; });
      result.stop_reason = any ? "no candidate significant at the family-wise level"
                               : "no identifiable candidate left";
      result.steps.push_back(sc.step);
      break;
    }
    // Refit the strongest few and keep the one that lowers chi2 most among those the
    // out-of-sample gap confirms (its cross-validated chi2 per point drops when it is added).
    int best = -1;
    double best_delta = -std::numeric_limits<double>::infinity();
    FitResult best_fit;
    int refits = 0;
    for (int i = 0; i < std::min<int>(options.refit_top, static_cast<int>(significant.size()));
         ++i) {
      CandidateScore& cs = sc.step.candidates[significant[i]];
      FitOptions o = fo;
      o.effects = model_terms;
      for (Effect& t : o.effects) {
        for (const Effect& f : current.effects) {
          if (same_term(t, f)) t.value = f.value;
        }
      }
      o.effects.push_back(cs.effect);  // one-step estimate as the starting value
      try {
        FitResult f = fit(prepared, o);
        if (!std::isfinite(f.chi2)) continue;
        cs.refit = true;
        ++refits;
        cs.delta_chi2 = current.chi2 - f.chi2;
        if (cross_validate) {
          FitOptions cv_options = o;
          cv_options.effects = f.effects;  // fitted values as the folds' starting values
          cs.cv_before = cv_current;
          cs.cv_after = cross_validated_gap(table, cv_options, options.cv_folds).cv_chi2_per_point;
          // Not confirmed out of sample: the term fits the noise of the dwells it saw.
          if (std::isfinite(cv_current) && !(cs.cv_after < cv_current)) continue;
        }
        if (cs.delta_chi2 > best_delta) {
          best_delta = cs.delta_chi2;
          best = significant[i];
          best_fit = f;
        }
      } catch (const std::exception&) {
        // A refit that fails is not a candidate for naming at this step.
      }
    }
    if (best < 0) {
      result.stop_reason =
          refits > 0 ? "the out-of-sample gap does not confirm the significant candidates (their "
                       "cross-validated chi-square per point does not drop)"
                     : "refits of the significant candidates failed";
      result.steps.push_back(sc.step);
      break;
    }
    const CandidateScore& chosen = sc.step.candidates[best];
    sc.step.chosen = chosen.effect.label();

    NamedEffect named;
    named.effect = chosen.effect;
    named.p_value = chosen.p_adjusted;
    named.p_raw = chosen.p_raw;
    named.score_chi2 = chosen.score_chi2;
    named.delta_chi2 = chosen.delta_chi2;
    named.step = step + 1;
    named.cv_before = chosen.cv_before;
    named.cv_after = chosen.cv_after;

    // Ambiguity: candidates whose score direction nearly coincides with the chosen one.
    const int row = sc.identifiable_index[best];
    Ambiguity amb;
    amb.named = chosen.effect.label();
    amb.candidates.push_back(chosen.effect.label());
    for (std::size_t k = 0; k < sc.step.candidates.size(); ++k) {
      const int other = sc.identifiable_index[k];
      if (other < 0 || other == row) continue;
      const double corr = ambiguity_threshold_corr(sc, row, other);
      if (corr > named.closest_correlation) {
        named.closest_correlation = corr;
        named.closest_alternative = sc.step.candidates[k].effect.label();
      }
      if (corr > options.ambiguity_correlation) {
        amb.candidates.push_back(sc.step.candidates[k].effect.label());
        if (corr > amb.correlation) {
          amb.correlation = corr;
          amb.separating_experiment =
              separating_experiment(chosen.effect, sc.step.candidates[k].effect);
        }
      }
    }
    result.effects.push_back(named);
    if (amb.candidates.size() > 1) result.ambiguous.push_back(amb);
    // An effect the run cannot screen may look exactly like the one named (backlash on a one-way
    // phase is an angle offset): report the pair, with the experiment that separates them.
    for (const EffectInfo& info : effect_catalog()) {
      if (!info.has_look_alike || info.same_as_when_unmet != chosen.effect.kind) continue;
      const Effect look_alike{info.kind, chosen.effect.target, 0.0};
      if (screenable(look_alike, run) || !look_alike_possible(look_alike, run)) continue;
      Ambiguity same;
      same.named = chosen.effect.label();
      same.candidates = {chosen.effect.label(), look_alike.label()};
      same.correlation = 1.0;
      same.separating_experiment = separating_experiment(chosen.effect, look_alike);
      result.ambiguous.push_back(same);
    }

    Effect added = chosen.effect;
    for (const Effect& f : best_fit.effects) {
      if (same_term(f, added)) added.value = f.value;
    }
    model_terms.push_back(added);
    current = best_fit;
    cv_current = chosen.cv_after;
    result.steps.push_back(sc.step);
  }

  result.after_fit = current;
  result.after = compute_gap(table, current, options.harmonics, options.time_bins);
  if (cross_validate) {
    FitOptions final_options = fo;
    final_options.effects = current.effects;
    result.after.cv = cross_validated_gap(table, final_options, options.cv_folds);
  }
  {
    AnalysisOptions used = options;
    used.noise_model = fo.noise_model;
    result.correlated_noise = correlated_noise_entry(table, current, used, result.after);
  }
  for (NamedEffect& ne : result.effects) {
    for (std::size_t i = 0; i < current.effects.size(); ++i) {
      if (same_term(current.effects[i], ne.effect)) {
        ne.effect.value = current.effects[i].value;
        ne.std = i < current.effects_std.size() ? current.effects_std[i] : 0.0;
      }
    }
  }
  return result;
}

}  // namespace core
}  // namespace accel_intrinsics
