// Fits of the rig model to a position table: joint (linear, or Ceres with effect terms) and eq4.
//
// Conventions shared by all fits
// - Each dwell mean R_s (s = u, v, w) is a measurement with standard error se_s =
//   std_s / sqrt(n) (dwell_standard_errors), weight 1 / se_s^2; the noise of u, v and w is
//   taken as independent.
// - chi2 = sum over rows and accelerometers of ((R_meas - R_model) / se)^2, dof = residuals
//   minus parameters, reduced_chi2 = chi2 / dof.
// - Covariance = (A^T W A)^-1 ((J^T W J)^-1 for the non-linear fit), multiplied by the reduced
//   chi-square when that is above 1 (with unit weights, for data without a usable std, by the
//   reduced chi-square itself: see chi2_scale). We scale with the GLOBAL reduced chi-square,
//   the one reported in FitResult, for every model: it is the only choice that also works for
//   the non-linear fit, where gimbal effects couple the three accelerometers, and it keeps
//   joint, joint+effects and eq4 comparable for the discrepancy analysis. (Per accelerometer
//   would be defensible for the linear joint fit, whose three 4-parameter problems are
//   independent; it differs only when one accelerometer misfits much worse than the others,
//   and then the analysis should name the missing effect rather than let the uncertainty of
//   that one accelerometer absorb it.)
// - Residuals reported per row are measured minus model, m/s^2.
// - Noise that is not white (docs/design.md section 12; FitOptions::noise_model with a slow part):
//   the joint fits use GENERALIZED least squares with the full covariance the noise model
//   implies between the dwell means of each accelerometer (C = D R D, noise.h
//   dwell_correlation), not merely dwell variances inflated by the slow part. Why: a slow bias
//   makes neighbouring dwells err TOGETHER. Inflating each variance keeps the estimate's spread
//   honest only if the errors were independent; here they are not, so the inflated fit still
//   misstates the covariance of S and O (a common error of a whole phase acts like an offset,
//   a smooth one like a harmonic), and its residuals stay correlated in time, which the
//   discrepancy analysis would read as drift or angle effects. GLS weights the information
//   correctly (the efficient estimate) and whitens the residuals, so the analysis' tests keep
//   their chi-square distributions. Its cost is one Cholesky factor per accelerometer (rows^3 / 3;
//   a 24-step run has 72 rows). eq4 fits each phase on its own, where cross-phase correlations
//   do not fit its independent-sets construction; it inflates each dwell's variance by its slow
//   part (variance of the mean over the dwell) instead. The tumble fit is GLS too (tumble.h):
//   its scalar residual per rest, linearized in the rest's mean, gets the covariance of the
//   means across rests. Inflated variances were tried there first and measured short: under a
//   30 s Gauss-Markov bias the offsets' RMS z was 1.5 with the true model, because the rests err
//   together (test/core/noise/correlated_noise_test.cpp).
#include "accel_intrinsics/core/fit/fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <memory>

#include "accel_intrinsics/core/fit/tumble.h"
#include "fit_internal.h"

namespace accel_intrinsics {
namespace core {

const char* model_name(FitModel model) {
  switch (model) {
    case FitModel::Joint: return "joint";
    case FitModel::Eq4: return "eq4";
    case FitModel::Tumble: return "tumble";
  }
  return "unknown";
}

FitModel parse_model(const std::string& name) {
  if (name == "joint") return FitModel::Joint;
  if (name == "eq4") return FitModel::Eq4;
  throw std::invalid_argument("unknown fit model '" + name + "' (expected joint or eq4)");
}

std::string FitResult::model_label() const {
  std::string label = model_name(model);
  for (const Effect& e : effects) label += "+" + e.label();
  return label;
}

std::vector<Eigen::Vector3d> dwell_standard_errors(const PositionTable& table, bool* unit_weights) {
  const std::size_t rows = table.rows.size();
  std::vector<Eigen::Vector3d> se(rows, Eigen::Vector3d::Zero());
  if (unit_weights) *unit_weights = false;
  for (int s = 0; s < 3; ++s) {
    std::vector<double> valid;
    std::vector<bool> ok(rows, false);
    for (std::size_t i = 0; i < rows; ++i) {
      const DwellRecord& r = table.rows[i];
      const double sd = r.std(s);
      if (r.n >= 2 && std::isfinite(sd) && sd > 0.0) {
        se[i](s) = sd / std::sqrt(static_cast<double>(r.n));
        ok[i] = true;
        valid.push_back(se[i](s));
      }
    }
    double fallback = 1.0;  // noise-free data: unit weights
    if (valid.empty() && unit_weights) *unit_weights = true;
    if (!valid.empty()) {
      const std::size_t mid = valid.size() / 2;
      std::nth_element(valid.begin(), valid.begin() + mid, valid.end());
      fallback = valid[mid];
      if (valid.size() % 2 == 0) {
        const double lower = *std::max_element(valid.begin(), valid.begin() + mid);
        fallback = 0.5 * (fallback + lower);
      }
    }
    for (std::size_t i = 0; i < rows; ++i)
      if (!ok[i]) se[i](s) = fallback;
  }
  return se;
}

std::vector<Eigen::Vector3d> dwell_standard_errors(const PositionTable& table) {
  return dwell_standard_errors(table, nullptr);
}

namespace {

// The weights of one fit: noise that is not white makes the joint fits generalized least
// squares and inflates eq4's variances (see the top).
FitWeights fit_weights(const PreparedTable& table, const FitOptions& options) {
  FitWeights w;
  w.se = table.standard_errors();
  w.unit_weights = table.unit_weights();
  if (options.noise_model.white() || w.unit_weights) return w;
  if (options.model == FitModel::Eq4) {
    for (std::size_t i = 0; i < w.se.size(); ++i) {
      const DwellRecord& row = table.row(i);
      for (int s = 0; s < 3; ++s)
        w.se[i](s) =
            std::sqrt(w.se[i](s) * w.se[i](s) + options.noise_model.slow_covariance(
                                                    s, row.t_start_s, row.t_end_s, row.t_start_s,
                                                    row.t_end_s, row.t_start_s));
    }
  } else {
    w.corr = dwell_correlation(table.table(), w.se, options.noise_model);
  }
  return w;
}

}  // namespace

FitResult fit(const PositionTable& table, const FitOptions& options) {
  return fit(PreparedTable(table), options);
}

FitResult fit(const PreparedTable& table, const FitOptions& options) {
  validate_options(options);
  if (!options.effects.empty() && options.model != FitModel::Joint) {
    validate_effects(options.effects, options.model, {});
  }
  validate_rows(table);
  // Rests of unknown orientation (a hand tumble): only |P (mean - O)| = g can take them.
  const std::size_t unknown = table.rows_with_unknown_orientation();
  if (unknown > 0) {
    if (unknown != table.size())
      throw FitError(std::to_string(unknown) + " of " + std::to_string(table.size()) +
                     " rows have an unknown orientation (phase '-' without f_x,f_y,f_z): a table "
                     "is either a tumble (all unknown) or known orientations, not both");
    if (options.model == FitModel::Eq4)
      throw FitError(
          "eq4 needs the gimbal's three phases; rests of unknown orientation are "
          "fitted by the tumble fit (model joint)");
    if (!options.effects.empty())
      throw FitError("effect terms need known orientations; a tumble fit has none");
    // Noise that is not white: GLS across the rests (tumble.h), as the joint fits (see the top).
    TumbleFitOptions tumble;
    tumble.local_gravity = options.local_gravity;
    tumble.noise_model = options.noise_model;
    return fit_tumble(table, tumble);
  }
  if (options.model == FitModel::Eq4) {
    for (std::size_t i = 0; i < table.size() && table.rows_with_direction() > 0; ++i) {
      if (table.row(i).has_direction)
        throw FitError("row " + std::to_string(i + 1) +
                       " gives its orientation as f_x,f_y,f_z: eq4 fits a sinusoid per gimbal "
                       "phase and needs the three phases; use the joint model");
    }
    validate_geometry(table, options.min_positions_per_phase);
  } else {
    validate_joint_geometry(table, options.min_positions_per_phase);
  }
  const FitWeights weights = fit_weights(table, options);
  FitResult r;
  if (options.model == FitModel::Eq4) {
    r = fit_eq4(table, weights, options);
  } else if (options.effects.empty()) {
    r = fit_joint_linear(table, weights, options);
  } else {
    validate_effects(options.effects, options.model, table.geometries());
    r = fit_joint_effects(table, weights, options);
  }
  r.noise_model = weights.unit_weights ? NoiseModel() : options.noise_model;
  r.positions = table.positions_per_phase();
  return r;
}

}  // namespace core
}  // namespace accel_intrinsics
