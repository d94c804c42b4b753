// Fits of the rig model to a position table (docs/design.md section 1, "Models to fit").
//   joint (default): one vector and one offset per accelerometer from all 9N dwell means,
//                    weighted by the dwell standard errors; closed-form linear least squares,
//                    or Ceres when effect terms are added.
//   eq4:             eq. (4) as written: per accelerometer and phase R = s_a g sin a +
//                    s_b g cos a + O_up; each vector component is estimated twice and the two
//                    combined by inverse-variance weight; O_u = mean of O_up (seed eq. 5).
#pragma once

#include <Eigen/Core>
#include <array>
#include <stdexcept>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/prepared_table.h"
#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/effects.h"
#include "accel_intrinsics/core/model/intrinsics.h"
#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace core {

// Tumble: rests of unknown orientation (hand tumble, docs/design.md section 11), |P (mean - O)| =
// g; chosen by the input (tumble.h), never by --model.
enum class FitModel { Joint, Eq4, Tumble };
const char* model_name(FitModel model);
// "joint" or "eq4"; throws std::invalid_argument otherwise.
FitModel parse_model(const std::string& name);

struct FitOptions {
  FitModel model = FitModel::Joint;
  double local_gravity = kStandardGravity;  // m/s^2
  // Effect terms to fit together with S and O (joint model only). Each Effect's value is the
  // starting guess; the fitted values come back in FitResult::effects.
  std::vector<Effect> effects;
  int min_positions_per_phase = 3;
  // The noise of the dwell means (docs/design.md section 12). White (default): weights 1 / se^2
  // with se = std / sqrt(n), as always. With a slow part (estimated from the run's long rest,
  // noise.h), the joint fit (a tumble's too) is generalized least squares with the covariance
  // the model implies between the dwell means (fit.cpp says why); eq4 inflates each dwell's
  // variance by its slow part instead.
  NoiseModel noise_model;
};

// Throws FitError with a message that names the phase, the row or the field.
class FitError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct FitResult {
  FitModel model = FitModel::Joint;
  double local_gravity = kStandardGravity;

  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();  // rows u, v, w
  Eigen::Vector3d O = Eigen::Vector3d::Zero();
  Eigen::Vector3d O_std = Eigen::Vector3d::Zero();
  // Covariance of (S row-major, O): 12x12, scaled by reduced_chi2 when above 1 (see fit.cpp).
  // eq4 fills it completely too: S from the inverse-variance combination, O from eq. (5).
  Eigen::Matrix<double, 12, 12> covariance = Eigen::Matrix<double, 12, 12>::Zero();

  // O_up: row = accelerometer u/v/w, column = phase x/y/z. For joint, each entry is O_u.
  Eigen::Matrix3d offset_per_phase = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d offset_per_phase_std = Eigen::Matrix3d::Zero();

  Intrinsics intrinsics;
  Eigen::Matrix3d cross_sensitivity = Eigen::Matrix3d::Identity();  // P = S^-1
  Eigen::Matrix3d cross_sensitivity_std = Eigen::Matrix3d::Zero();

  // Fitted effect terms (value = estimate) and their standard uncertainties.
  std::vector<Effect> effects;
  std::vector<double> effects_std;

  double chi2 = 0.0;          // sum of squared normalized residuals
  int dof = 0;                // residuals minus parameters
  double reduced_chi2 = 0.0;  // chi2 / dof
  double residual_rms = 0.0;  // RMS of the unnormalized residuals, m/s^2
  std::array<int, 3> positions{{0, 0, 0}};

  // Per row of the table: measured minus model (m/s^2), and the standard error used as weight.
  std::vector<Eigen::Vector3d> residuals;
  std::vector<Eigen::Vector3d> standard_errors;

  // The noise model the fit used (white: kind() == "white"), and for generalized least squares
  // the Cholesky factors of the dwell means' correlation (null when white or eq4): the analysis
  // whitens residuals and Jacobians with it. chi2 is then r^T C^-1 r.
  NoiseModel noise_model;
  std::shared_ptr<const DwellCorrelation> correlation;

  // Ceres' brief report for fits with effect terms (empty for the closed-form fits).
  std::string solver_message;

  // Human-readable model description, e.g. "joint" or "joint+quadratic_nonlinearity[u]".
  std::string model_label() const;
};

// Validates the table and fits; throws FitError naming the row, the phase or what is
// unobservable. eq4: finite values, the three gimbal phases with min_positions_per_phase dwells
// at three distinct angles each. joint: the same for a complete gimbal run; otherwise any set of
// orientations (gimbal phases present with min_positions_per_phase dwells, rows with
// f_x,f_y,f_z) whose unit specific forces determine S and O (docs/design.md section 6).
FitResult fit(const PositionTable& table, const FitOptions& options = {});
// The same on a table prepared once (prepared_table.h): fit(table) prepares it and calls this;
// a caller that fits one table with several options prepares it once.
FitResult fit(const PreparedTable& table, const FitOptions& options = {});

// Standard error of each dwell mean (std / sqrt(n)); rows with n < 2 or zero std get the median
// of the other rows of the same accelerometer (all zero: unit weights, noise-free data). With
// unit weights the fit takes the scale of its covariance from the residuals (s^2 = chi2 / dof),
// so an exact fit reports uncertainties at the round-off level.
std::vector<Eigen::Vector3d> dwell_standard_errors(const PositionTable& table);

// Fills what follows from r.S and the (already chi2-scaled) 12x12 covariance of (S row-major, O):
// covariance, O_std, intrinsics, cross_sensitivity and its std. Throws FitError when S is
// singular. Every fit ends with it (the tumble fit of tumble.h too).
void finish_result(FitResult& r, const Eigen::Matrix<double, 12, 12>& covariance);

}  // namespace core
}  // namespace accel_intrinsics
