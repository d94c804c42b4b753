// Discrepancy analysis: where do the measurements and the digital twin disagree, which effect of
// the vocabulary (effects.h, docs/design.md section 3) is missing, and how much of the gap closes
// once it is added (docs/design.md section 2: JSON keys `effects`, `ambiguous`, `gap`, written by
// io/analysis_report.h).
//
// Workflow of analyze():
//  1. Fit the joint model (plus any known effects in AnalysisOptions::base_effects).
//  2. Digital twin: evaluate predict_outputs() with the fitted Device at the measured positions
//     and times; the gap is the normalized residual r / sigma (sigma = dwell standard error),
//     summarized as reduced chi-square and RMS and localized by phase x accelerometer, by
//     harmonic of the angle (normalized power of harmonics 0..4, each ~chi2 with 2 dof, 1 for
//     harmonic 0, under noise), by time bin and by a linear trend in time.
//  3. Screening: for every candidate effect the dwell means can reveal, the score test of "value
//     = 0" at the current fit. With A = W^1/2 J_base the weighted Jacobian of the current model
//     and b = W^1/2 dR/d(value) at value 0, b_perp = (I - A A^+) b is the part of the effect that
//     the fitted parameters cannot absorb; the statistic T = (b_perp . z)^2 / |b_perp|^2 (z the
//     normalized residual) is the likelihood-ratio delta chi2 of the linearized refit, ~chi2(1)
//     under "no effect". |b_perp|^2 / |b|^2 is the information left after projecting out the base
//     parameters; below `identifiability_floor` the candidate is absorbed (unidentifiable) and is
//     never named. False alarms across the family of candidates are controlled by the step-down
//     max-T procedure (Westfall-Young: Holm's method with the critical values calibrated by Monte
//     Carlo on the candidates' actual correlation), so that on effect-free data at most `alpha`
//     of the runs name anything; Holm's adjusted p-values from chi2(1) are reported beside them.
//  4. Greedy forward selection: the best significant candidate (among the `refit_top` strongest,
//     the one whose nonlinear refit with fit() lowers chi2 most) is added, the model is refit and
//     re-simulated, and the screening repeats over the remaining candidates until none is
//     significant (or `max_effects`).
//  5. Report: named effects with value and standard uncertainty from the final fit and the
//     family-wise p-value of the step that named them; the gap before and after; ambiguity
//     (candidates whose score directions correlate by more than `ambiguity_correlation` with a
//     named one) with the experiment that separates them; what could not be screened.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <iosfwd>
#include <limits>
#include <string>
#include <vector>

#include "accel_intrinsics/core/analysis/setup_mistakes.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/fit/preconditions.h"
#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/effects.h"
#include "accel_intrinsics/core/model/model.h"

namespace accel_intrinsics {
namespace core {

struct AnalysisOptions {
  double local_gravity = kStandardGravity;  // m/s^2, used for every fit and the twin
  // Family-wise false-alarm rate across candidates, per run. The requirement is "at most 5 % of
  // effect-free runs name anything"; a procedure calibrated at exactly 5 % would meet it only on
  // average (and fail a check on 200 runs half the time), so the default spends half of it:
  // P(more than 10 of 200 effect-free runs name anything) is then about 1 %.
  double alpha = 0.025;
  int max_effects = 4;                  // stop after naming this many
  int monte_carlo_draws = 10000;        // draws for the max-T calibration of each step
  std::uint64_t seed = 20261121;        // of the Monte Carlo calibration (reproducible)
  double ambiguity_correlation = 0.9;   // |corr| of score directions that counts as ambiguous
  double identifiability_floor = 1e-6;  // |b_perp|^2/|b|^2 below this: absorbed by the base
  int refit_top = 3;                    // significant candidates refit to pick the best
  int harmonics = 4;                    // localization: harmonics 0..harmonics of the angle
  int time_bins = 6;                    // localization: equal time bins over the run
  double detection_power = 0.9;         // for the reported detection thresholds
  // The temperature effects (offset_ and scale_temperature_coefficient) are screened only when
  // every dwell has a temperature and the dwell temperatures span at least this much (K, max -
  // min); otherwise they are listed as not screened, with the reason. 0.5 K: on-chip temperature
  // sensors resolve about 0.1 K and self-heating moves them by as much, so a smaller span is
  // mostly reading error (which biases a coefficient toward zero); and a typical MEMS offset
  // coefficient (0.1 - 1 mg/K) moves the outputs by less than 0.5 mg over it, about the noise of
  // one dwell mean.
  double min_temperature_span_k = 0.5;
  // Effects known to be present: always fitted, never screened (e.g. from an earlier analysis).
  std::vector<Effect> base_effects;
  // Candidates to screen; empty = every effect the table can reveal (default_candidates()).
  std::vector<Effect> candidates;
  // Stop as soon as the gap is consistent with noise (chi-square test at 1 %). Off by default:
  // the omnibus chi-square test spreads one effect over hundreds of degrees of freedom and is far
  // less powerful than the targeted score tests, so stopping on it would leave effects unnamed.
  bool stop_when_consistent = false;
  // The noise of the dwell means (docs/design.md section 12): white by default; with a slow part
  // (from the run's long rest, noise.h noise_model_of_run) every fit is generalized least squares
  // and every test runs on the whitened residuals, so a stationary slow bias is not read as an
  // effect.
  NoiseModel noise_model;
  // Out of sample: folds in time blocks for the cross-validated chi-square per point
  // (cross_validated_gap); an effect is named only when adding it also lowers that (the in-sample
  // test and the out-of-sample gap agree). 0 folds: no cross-validation (and no such check).
  int cv_folds = 5;
  // Unit of the outputs (docs/design.md section 6), for the setup mistakes tested first
  // (setup_mistakes.h: only m/s^2 is checked against |g|).
  std::string output_unit = "m/s^2";
};

// Throws std::invalid_argument naming the field.
void validate(const AnalysisOptions& options);

// Candidates the dwell means of `table` can reveal: quadratic and cubic non-linearity and offset
// drift per accelerometer; angle offset, angle scale and axis tilt per phase; backlash per phase
// only when that phase has a two-way sweep (rows approached from both sides). timing_lag needs
// raw streams and is never a dwell-mean candidate. The temperature coefficients per accelerometer
// when every dwell has a temperature and they span min_temperature_span_k.
std::vector<Effect> default_candidates(const PositionTable& table,
                                       double min_temperature_span_k = 0.5);

// Whole-run summary of a gap.
struct GapSummary {
  double chi2 = 0.0;
  int dof = 0;
  double reduced_chi2 = 0.0;
  double rms = 0.0;         // RMS of the unnormalized residuals, m/s^2
  double p_value = 1.0;     // P(chi2(dof) >= chi2)
  double band99_low = 0.0;  // 99 % band of the reduced chi-square under noise alone
  double band99_high = 0.0;
  bool consistent_with_noise = true;  // reduced chi2 inside the band
};

// One phase x accelerometer cell of the residuals.
struct CellGap {
  int phase = 0;          // x, y, z
  int accelerometer = 0;  // u, v, w
  int n = 0;
  double chi2 = 0.0;  // sum of normalized residuals squared
  double rms = 0.0;   // m/s^2
  // Normalized residual power at harmonic k of the angle (k = 0..harmonics): explained sum of
  // squares of z ~ a cos(k alpha) + b sin(k alpha); ~chi2(2) under noise (chi2(1) for k = 0).
  // The base fit absorbs part of harmonics 0 and 1: summed over the 9 cells, noise gives about
  // 6 at k = 0 (9 - 3 offsets), 9 at k = 1 (18 - 9 components of S) and 18 at k >= 2.
  std::vector<double> harmonic_power;
};

struct TimeBinGap {
  double t_begin_s = 0.0;
  double t_end_s = 0.0;
  int n = 0;  // residuals (dwells x 3)
  double chi2 = 0.0;
  double rms = 0.0;
};

// Cross-validated chi-square per point (docs/design.md section 12): the dwells ordered in time and
// cut into `folds` contiguous blocks; each block is predicted by the model fitted to the others,
// and its residuals judged against the noise model's covariance of that block (white: the dwell
// standard errors). Sum over blocks / number of residuals. A missing effect raises it; a term
// that only fits noise does not lower it (a drift extrapolates across blocks, a slow noise does
// not). NaN when not computed or every fold failed to fit.
struct CrossValidatedGap {
  double cv_chi2_per_point = std::numeric_limits<double>::quiet_NaN();
  int folds = 0;         // folds that were fitted
  int failed_folds = 0;  // folds whose training set could not be fitted (skipped)
  int points = 0;        // residuals predicted
};
CrossValidatedGap cross_validated_gap(const PositionTable& table, const FitOptions& options,
                                      int folds);

// The slow part of a noise model estimated from one long rest is rough: a 120 s rest cannot tell
// a 30 s Gauss-Markov bias from a random walk or from a 3 s one (its estimated correlation time
// ranged from 0.5 s to 500 s over 80 such rests), and the fit treated that guess as known. An
// underestimated correlation time lets the slow noise through to the screening as drift or angle
// effects (11 % of effect-free runs named one, against alpha 2.5 %). So the slow part is fitted
// again to the whole run's dwell means, which span many correlation times: per accelerometer, the
// restricted (REML) likelihood of the base fit's residuals (S, O and options.effects projected
// out, so the fitted terms do not eat into the noise) under C = D^2 + a K, D the dwells' white
// standard errors and K one of a set of shapes: a unit Gauss-Markov process at correlation times
// from 0.5 s to 5 times the run, a unit random walk, and the rest's own slow part. The long
// rest enters as its blocks (NoiseModel::rest_blocks) when the model carries them. The shape of
// highest likelihood is kept, or a random walk the data do not reject (slow_part_fit.h
// choose_slow_shape), with the amplitude's posterior mean and relative variance
// (best_slow_amplitude; the fit widens its covariance by the latter, noise.h
// estimated_scale_covariance). A model with no slow part comes back unchanged unless it came from
// a recorded rest (NoiseModel::slow_part_to_fit): a rest that looks white does not rule out a
// slow part the run shows. The rest offers its shape; the run sets amplitude and shape. The
// source says what was chosen.
NoiseModel slow_part_from_run(const PositionTable& table, const FitOptions& options);

struct Gap {
  GapSummary summary;
  CrossValidatedGap cv;        // filled by analyze() for the `before` and `after` gaps
  std::vector<CellGap> cells;  // 9 cells, phase-major
  std::vector<TimeBinGap> time_bins;
  std::array<double, 3> trend_z{{0, 0, 0}};  // per accelerometer: t-statistic of z vs time
};

// The digital twin of a fit: its Device (S, O and fitted effect terms).
Device device_from_fit(const FitResult& fit);
// Measured minus twin (m/s^2), one vector per row of the table.
std::vector<Eigen::Vector3d> twin_residuals(const PositionTable& table, const Device& device,
                                            double local_gravity);
// Gap of a fit: twin residuals normalized by the dwell standard errors; dof = 3 rows - 12 -
// number of fitted effects.
Gap compute_gap(const PositionTable& table, const FitResult& fit, int harmonics = 4,
                int time_bins = 6);

// One candidate at one screening step.
struct CandidateScore {
  Effect effect;  // value = one-step (linearized) estimate
  bool identifiable = true;
  double information_ratio = 0;    // |b_perp|^2 / |b|^2
  double score_chi2 = 0;           // T, ~chi2(1) under no effect
  double estimate_std = 0;         // 1 / |b_perp| (linearized, known sigma)
  double p_raw = 1;                // P(chi2(1) >= T)
  double p_holm = 1;               // Holm-adjusted over the identifiable candidates
  double p_adjusted = 1;           // step-down max-T (Monte Carlo), the family-wise p-value
  double detection_threshold = 0;  // |value| named with probability detection_power (theory)
  double delta_chi2 = 0;           // from the nonlinear refit, when one was made (else 0)
  bool refit = false;
  // Out of sample, for refit candidates: the cross-validated chi2 per point of the model at this
  // step and with the candidate added (NaN when not computed).
  double cv_before = std::numeric_limits<double>::quiet_NaN();
  double cv_after = std::numeric_limits<double>::quiet_NaN();
};

struct ScreeningStep {
  std::string model;                       // model label the step started from
  GapSummary gap;                          // of that model
  std::vector<CandidateScore> candidates;  // sorted by score, strongest first
  double critical_chi2 = 0;                // max-T critical value of the first step-down stage
  std::string chosen;                      // label of the effect added, empty if none
};

struct NamedEffect {
  Effect effect;       // value from the final fit
  double std = 0;      // standard uncertainty from the final fit
  double p_value = 1;  // family-wise (step-down max-T) p-value at the step that named it
  double p_raw = 1;    // single-test p-value of its score statistic at that step
  double score_chi2 = 0;
  double delta_chi2 = 0;  // chi2 drop of the refit that added it
  int step = 0;
  double cv_before = std::numeric_limits<double>::quiet_NaN();  // out of sample, at its step
  double cv_after = std::numeric_limits<double>::quiet_NaN();
  // The candidate whose score direction was closest to this one's at that step, and |corr|.
  std::string closest_alternative;
  double closest_correlation = 0;
};

struct Ambiguity {
  std::string named;                    // label of the named effect, or empty
  std::vector<std::string> candidates;  // labels that explain the data almost equally
  double correlation = 0;               // |corr| of their score directions after the base fit
  std::string separating_experiment;
};

// The noise-model entry `correlated_noise` of the vocabulary (effects.h noise_entry_catalog):
// named when the residuals exceed the white prediction (the final model refitted with white
// weights fails the chi-square test at alpha), the noise model explains them (the GLS gap passes
// it), and no catalog effect explains them better out of sample (whatever effects the analysis
// named are in both models). Not a physical effect: never in `effects`.
struct NoiseEntry {
  std::string name = "correlated_noise";
  bool named = false;
  std::string noise_model;          // kind() of the model used
  double white_reduced_chi2 = 0.0;  // of the final model, white weights
  double white_p_value = 1.0;
  double model_reduced_chi2 = 0.0;  // of the final model with the noise model
  double model_p_value = 1.0;
  std::string reason;
};

struct AnalysisResult {
  // Tested before any physical effect (setup_mistakes.h): when one is found the analysis stops
  // after the base fit and names no effect.
  std::vector<SetupMistake> setup_mistakes;
  FitResult before_fit;  // base model
  FitResult after_fit;   // base model + named effects
  Gap before;
  Gap after;
  std::vector<NamedEffect> effects;
  std::vector<Ambiguity> ambiguous;
  std::vector<ScreeningStep> steps;
  std::vector<CandidateScore> unidentifiable;  // candidates absorbed by the base model (step 1)
  std::vector<std::string> not_screened;       // what dwell means cannot show, and why
  std::vector<std::string> unobservable;       // e.g. local gravity: no residual shows it
  std::string stop_reason;
  double local_gravity = kStandardGravity;
  NoiseModel noise_model;  // what every fit used
  NoiseEntry correlated_noise;
};

// The whole workflow. Throws FitError when even the base model cannot be fitted.
AnalysisResult analyze(const PositionTable& table, const AnalysisOptions& options = {});

// Its documents (the analysis JSON, the text report, the residual CSV) are written by the io
// library: io/analysis_report.h, io/residuals_csv.h.

// timing_lag needs raw streams, not dwell means: see estimate_timing_lag() in
// raw_stream_analysis.h.

// Theoretical detection threshold of a single chi2(1) test with critical value `critical_chi2`:
// the non-centrality lambda at which the test rejects with probability `power` (Boost.Math
// non-central chi-square); the effect value is sqrt(lambda) * estimate_std.
double noncentrality_for_power(double critical_chi2, double power);

}  // namespace core
}  // namespace accel_intrinsics
