// Intrinsics from rests of unknown orientation: a hand tumble (docs/design.md section 11).
//
// At rest |f| = g, so each rest mean m satisfies |P (m - O)| = g with P = S^-1: the rests lie on
// an ellipsoid whose centre is O and whose shape is the Gram matrix G = S S^T. The rotation of S
// is not observable, so S is reported in the sensor's own frame: u along x, v in the x-y plane,
// i.e. S lower-triangular (6 parameters) plus O (3). |u|, |v|, |w| and the angles between them,
// the intrinsic parameters, are exactly what G holds.
//
// Fit: an algebraic ellipsoid fit gives the start, then Gauss-Newton on the weighted residuals
//   r_i = (|P (m_i - O)| - g) / sigma_i,  sigma_i^2 = sum_s (P^T a_hat_i)_s^2 se_is^2
// (se the standard error of the rest mean, a_hat the unit specific force: first-order
// propagation of the mean's noise into |a|). Covariance (J^T W J)^-1, scaled by the reduced
// chi-square when above 1, as every fit here (fit.h).
// With a noise model that has a slow part (docs/design.md section 12) the rests' means err
// together, and the fit is generalized least squares across rests: r^T C^-1 r with
//   C_ij = sum_s c_is c_js Cov(m_is, m_js),  c_i = P^T a_hat_i
// (the same first-order propagation, Cov the white variances plus the slow covariance between
// the rests, noise.h dwell_correlation); the residuals and the Jacobian are whitened by the
// Cholesky factor of C, and chi2 is the whitened one.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/constants.h"

namespace accel_intrinsics {
namespace core {

// The frame S is reported in (the result's "frame").
extern const char* const kTumbleFrame;

struct TumbleFitOptions {
  double local_gravity = kStandardGravity;
  std::size_t min_rests = 10;  // fewer: FitError naming how many more are needed
  // White (the default): each rest weighted by its std / sqrt(n). With a slow part: GLS across
  // the rests (above), and the result states the model (FitResult::noise_model). Data without a
  // usable std (unit weights) ignore it, as the gimbal fit does.
  NoiseModel noise_model;
};

// Fits the rows of `table` (all orientation_unknown). The FitResult has model Tumble, S
// lower-triangular, residuals per row as 3-vectors (mean minus its projection on the fitted
// ellipsoid, S a_hat g + O), chi2 over the scalar residuals, dof = rests - 9. Throws FitError for
// too few rests or rests that do not determine the ellipsoid, naming what to add.
FitResult fit_tumble(const PositionTable& table, const TumbleFitOptions& options = {});
// The same on a prepared table (prepared_table.h; fit() passes its own).
FitResult fit_tumble(const PreparedTable& table, const TumbleFitOptions& options = {});

// The rest's slow part fitted again to the whole tumble (docs/design.md section 12), as
// slow_part_from_run does for a gimbal run (discrepancy.h). A long rest's Allan fit sees a random
// walk poorly (a 120 s rest took it for a short Gauss-Markov part or for nothing on a third of
// the axes) while the offsets carry the walk's excursion over the whole run; the rests alone do
// not suffice either (about 20 degrees of freedom for three accelerometers). So one restricted
// likelihood takes both: the long rest's blocks (NoiseModel::rest_blocks) per accelerometer,
// their level projected out, and the white fit's scalar residuals of the other rests with the
// nine parameters projected out, with the slow covariance between all of them. Each
// accelerometer's slow part is chosen among slow_part_shapes (slow_part_fit.h); a rest's residual
// mixes the three accelerometers (through c_i = P^T a_hat_i), so the three are fitted together
// by coordinate ascent. Where the data do not reject a random walk (log-likelihood within 2 of
// the best shape) it is kept: one tumble cannot tell it from a long Gauss-Markov bias whose level
// the offsets absorb, and the walk does not assume the bias stopped wandering
// (tumble_slow_part.cpp).
// Measured over 60 simulated tumbles each (test/core/noise/correlated_noise_test.cpp), offsets' RMS
// z-score with the model from the rest alone / fitted here: Gauss-Markov 0.91 / 0.84, random
// walk 2.55 / 1.32 (1.0 is right; the walk's density comes from about ten rests per axis).
// A white model, a model without rest blocks (given, not measured), a table
// without usable stds or fewer than 13 rests come back unchanged; the source says what was
// chosen. Throws FitError as fit_tumble.
NoiseModel slow_part_from_tumble(const PositionTable& table, const NoiseModel& rest_model,
                                 double local_gravity = kStandardGravity);

// The unit specific force ("up") of each row in the sensor frame under a tumble fit.
std::vector<Eigen::Vector3d> rest_up_directions(const FitResult& fit, const PositionTable& table);

// Which of the six axis directions (u, v, w each up and down) some rest reached within the cone.
struct TumbleCoverage {
  double cone_deg = 45.0;
  // [axis][0 = up, 1 = down]: the smallest angle (deg) between a rest's up direction and +axis
  // (up) or -axis (down).
  std::array<std::array<double, 2>, 3> closest_deg{};
  std::vector<std::string> missing;  // e.g. "no rest with w pointing down within 45 deg"
  bool complete() const { return missing.empty(); }
};
TumbleCoverage tumble_coverage(const FitResult& fit, const PositionTable& table,
                               double cone_deg = 45.0);

// Relative standard uncertainty of each intrinsic parameter, comparable across kinds:
// responsivity std / responsivity, angle std in rad, offset std / (responsivity g) (a fraction of
// 1 g). Names as in the result: responsivity_u.., angle_uv.., offset_u..
struct RelativeUncertainty {
  std::string name;
  double value = 0.0;
};
std::vector<RelativeUncertainty> relative_uncertainties(const FitResult& fit);

// The pose to try next (docs/design.md section 11): the up direction (unit, sensor frame) after
// whose rest the largest relative uncertainty of the nine intrinsics would be smallest, from the
// Fisher information of the rests so far plus one more rest there (its noise the median of the
// rests').
struct PoseSuggestion {
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  std::string target;               // the parameter with the largest relative uncertainty
  double relative_std_now = 0.0;    // of the target
  double relative_std_after = 0.0;  // of the target, predicted with one more rest at `up`
  double largest_after = 0.0;       // the largest relative uncertainty then, predicted
  std::string words;                // for the person holding the device (describe_pose)
};
PoseSuggestion suggest_next_pose(const FitResult& fit, const PositionTable& table,
                                 int candidates = 600);

// "x axis straight up", "z axis 45 deg up, y axis 45 deg down", ...: which way the device's
// axes point when the specific force in its frame is along `up`.
std::string describe_pose(const Eigen::Vector3d& up);

}  // namespace core
}  // namespace accel_intrinsics
