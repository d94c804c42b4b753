// The discrepancy analysis of a hand tumble (docs/design.md section 11, issue 22 item 4): which
// sensor effects the rests show without known orientations, and how much of the gap each closes.
//
// Model: each rest mean m_i = outputs_for_force(S, O, effects; g f_i) (model.h, the one model of
// every fit and the simulator) with f_i an unknown unit vector per rest (a nuisance parameter on
// the sphere), S lower-triangular (sensor frame). Weighted by the rests' standard errors, this is
// the maximum-likelihood form of |P (m - O)| = g, and it takes effect terms as the gimbal fit does.
// Without effects it gives the tumble fit's S and O to first order.
//
// Screening: every candidate the rests can show (quadratic and cubic non-linearity and offset
// drift per accelerometer; the temperature coefficients when every rest has a temperature over
// min_temperature_span_k) is refitted; its chi2 drop is tested as an F(1, dof) statistic (chi2(1)
// when the reduced chi-square is not above 1), Holm-adjusted over the candidates of the step. The
// best candidate below alpha is named, and the screening repeats (greedy forward selection, up to
// max_effects). With a noise model that has a slow part (the first long rest's, noise.h), every
// fit is generalized least squares across the rests: the residuals are whitened per
// accelerometer by the Cholesky factor of the rest means' correlation (noise.h
// dwell_correlation), so that rests erring together under a slow bias are not read as an
// effect. Not screened, and said so:
// the gimbal effects (angle offset and scale, axis tilt, backlash: there are no angles), timing
// lag (no commanded moves).
#pragma once

#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/effects.h"
#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace core {

struct TumbleAnalysisOptions {
  double local_gravity = kStandardGravity;
  double alpha = 0.025;  // family-wise per step (Holm), as the gimbal analysis
  int max_effects = 3;
  double min_temperature_span_k = 0.5;
  // The noise of the rest means: white (std / sqrt(n)) by default; with a slow part, GLS across
  // the rests (above).
  NoiseModel noise_model;
};

struct TumbleEffectTest {
  Effect effect;     // value: fitted with the model of the step plus this term
  double std = 0.0;  // its standard uncertainty there
  double delta_chi2 = 0.0;
  double statistic = 0.0;  // delta chi2, divided by the reduced chi-square when above 1
  double p_raw = 1.0;
  double p_holm = 1.0;
};

struct TumbleAnalysis {
  FitResult before;                     // no effect terms (the nuisance-direction form)
  FitResult after;                      // with the named effects (FitResult::effects, effects_std)
  std::vector<TumbleEffectTest> named;  // in the order named, tests of their step
  std::vector<std::vector<TumbleEffectTest>> steps;  // every candidate of every step
  std::vector<std::string> not_screened;
  std::string stop_reason;
  NoiseModel noise_model;  // what every fit used
};

// The fit of the model above with `effects` (their values the start), GLS when the noise model
// has a slow part (the result then holds it and the correlation; chi2 is the whitened one).
// Throws FitError.
FitResult fit_tumble_with_effects(const PositionTable& table, const std::vector<Effect>& effects,
                                  double local_gravity,
                                  const NoiseModel& noise_model = NoiseModel());

// Throws FitError when even the base fit fails (too few rests, ...).
TumbleAnalysis analyze_tumble(const PositionTable& table,
                              const TumbleAnalysisOptions& options = {});

}  // namespace core
}  // namespace accel_intrinsics
