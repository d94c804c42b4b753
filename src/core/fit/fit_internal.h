// Helpers shared by the fits of src/core/fit (not installed): the linear joint solve the
// effects fit starts from, the validators, the result's finishing steps. The conventions shared
// by all fits are at the top of fit.cpp. Validators and solvers read the table through the
// PreparedTable fit() builds once (prepared_table.h), and the weights through FitWeights.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/fit/prepared_table.h"
#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace core {

constexpr int kNumLinear = 12;  // S (9, row-major) and O (3)

// fit.cpp: dwell_standard_errors (fit.h), also telling whether some accelerometer fell back to
// unit weights (no row with a usable std: noise-free or std-less data).
std::vector<Eigen::Vector3d> dwell_standard_errors(const PositionTable& table, bool* unit_weights);

// fit_common.cpp
std::string format_number(double x);
std::string row_name(const PositionTable& table, std::size_t i);
std::string linear_parameter_name(int k);
// Inverse of a symmetric positive (semi)definite normal matrix, scaled to unit diagonal first so
// the rank test is independent of parameter units. Throws FitError naming the parameters that
// span the unidentifiable direction.
Eigen::MatrixXd checked_inverse(const Eigen::MatrixXd& N, const std::vector<std::string>& names,
                                const std::string& context);
double chi2_scale(const FitResult& r, bool unit_weights);
void apply_correlation(FitResult& r, const std::shared_ptr<const DwellCorrelation>& corr);

// The weights of one fit (fit.cpp fit_weights): the prepared standard errors, for eq4 inflated by
// the slow part of a noise model that is not white, and for the joint fits under such a model the
// dwell means' correlation (generalized least squares; null when white or unit weights).
struct FitWeights {
  std::vector<Eigen::Vector3d> se;
  bool unit_weights = false;
  std::shared_ptr<const DwellCorrelation> corr;
};

// Residuals, chi2, dof, rms. `model_of_row(i)` returns the model outputs of row i.
template <typename ModelOfRow>
void fill_residuals(FitResult& r, const PreparedTable& table,
                    const std::vector<Eigen::Vector3d>& se, int num_parameters,
                    ModelOfRow&& model_of_row) {
  const std::size_t rows = table.size();
  r.residuals.resize(rows);
  r.standard_errors = se;
  r.chi2 = 0.0;
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < rows; ++i) {
    r.residuals[i] = table.row(i).mean - model_of_row(i);
    r.chi2 += r.residuals[i].cwiseQuotient(se[i]).squaredNorm();
    sum_sq += r.residuals[i].squaredNorm();
  }
  r.dof = 3 * static_cast<int>(rows) - num_parameters;
  // dof = 0 (eq4 with exactly 3 dwells per phase): the fit interpolates, there is no redundancy
  // to judge it by; reduced_chi2 is reported as 0 and the covariance left unscaled (with unit
  // weights as well, i.e. no noise information at all, the uncertainties come out zero).
  r.reduced_chi2 = r.dof > 0 ? r.chi2 / r.dof : 0.0;
  r.residual_rms = rows > 0 ? std::sqrt(sum_sq / (3.0 * rows)) : 0.0;
}

// fit_validation.cpp
void validate_options(const FitOptions& options);
void validate_rows(const PreparedTable& table);
void validate_geometry(const PreparedTable& table, int min_positions);
void validate_joint_geometry(const PreparedTable& table, int min_positions);
void validate_effects(const std::vector<Effect>& effects, FitModel model,
                      const std::vector<DwellGeometry>& geoms);

// linear_fit.cpp
struct LinearJoint {
  Eigen::Matrix3d S;
  Eigen::Vector3d O;
  Eigen::Matrix<double, 12, 12> covariance;  // unscaled (A^T W A)^-1
  // GLS only: the whitened Jacobian, 3 rows per dwell (u, v, w interleaved), 12 columns.
  Eigen::MatrixXd whitened_jacobian;

  // Accelerometer s's unknowns x = (s_x, s_y, s_z, O_s) and the inverse of their normal matrix
  // `normal` (named in the error when it is singular) into S, O and the covariance.
  void store(int s, const Eigen::Vector4d& x, const Eigen::Matrix4d& normal, const char* fit_name) {
    std::vector<std::string> names;
    for (int c = 0; c < 3; ++c) names.push_back(linear_parameter_name(3 * s + c));
    names.push_back(linear_parameter_name(9 + s));
    const Eigen::Matrix4d inv = checked_inverse(normal, names, fit_name);
    S.row(s) = x.head<3>().transpose();
    O(s) = x(3);
    const int idx[4] = {3 * s, 3 * s + 1, 3 * s + 2, 9 + s};
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 4; ++c) covariance(idx[a], idx[c]) = inv(a, c);
  }
};

LinearJoint solve_joint_linear(const PreparedTable& table, const std::vector<Eigen::Vector3d>& se,
                               double g);
FitResult fit_joint_linear(const PreparedTable& table, const FitWeights& weights,
                           const FitOptions& options);

// effects_fit.cpp (the dwell geometries from the prepared table)
FitResult fit_joint_effects(const PreparedTable& table, const FitWeights& weights,
                            const FitOptions& options);

// eq4_fit.cpp
FitResult fit_eq4(const PreparedTable& table, const FitWeights& weights, const FitOptions& options);

}  // namespace core
}  // namespace accel_intrinsics
