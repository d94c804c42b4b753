// Helpers shared by the fits: names in messages, the checked inverse, the result's covariance,
// residuals and chi-square (conventions at the top of fit.cpp).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

#include "accel_intrinsics/core/model/model.h"
#include "fit_internal.h"

namespace accel_intrinsics {
namespace core {

std::string format_number(double x) {
  std::ostringstream out;
  out.precision(6);
  out << x;
  return out.str();
}

std::string row_name(const PositionTable& table, std::size_t i) {
  const DwellRecord& r = table.rows[i];
  return "row " + std::to_string(i + 1) + " (phase " + phase_name(r.phase) + ", step " +
         std::to_string(r.step) + ")";
}

std::string linear_parameter_name(int k) {
  if (k < 9) return std::string("S[") + accelerometer_name(k / 3) + "_" + "xyz"[k % 3] + "]";
  return std::string("O[") + accelerometer_name(k - 9) + "]";
}

namespace {

// Kronecker product of two 3x3 matrices: row-major vec(A X B) = kron(A, B^T) vec(X).
Eigen::Matrix<double, 9, 9> kronecker(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  Eigen::Matrix<double, 9, 9> k;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) k.block<3, 3>(3 * i, 3 * j) = a(i, j) * b;
  return k;
}

}  // namespace

// ---- linear algebra helpers --------------------------------------------------------------

// Inverse of a symmetric positive (semi)definite normal matrix, scaled to unit diagonal first so
// the rank test is independent of parameter units. Throws FitError naming the parameters that
// span the unidentifiable direction.
Eigen::MatrixXd checked_inverse(const Eigen::MatrixXd& N, const std::vector<std::string>& names,
                                const std::string& context) {
  const Eigen::Index n = N.rows();
  Eigen::VectorXd d(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!(N(i, i) > 0.0) || !std::isfinite(N(i, i)))
      throw FitError(context + ": the data do not constrain " + names[i]);
    d(i) = 1.0 / std::sqrt(N(i, i));
  }
  const Eigen::MatrixXd C = d.asDiagonal() * N * d.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(C);
  const Eigen::VectorXd ev = eig.eigenvalues();
  // Relative threshold: below this the direction is determined only by round-off.
  if (!(ev(0) > 1e-13 * ev(n - 1))) {
    const Eigen::VectorXd dir = eig.eigenvectors().col(0);
    std::vector<std::pair<double, Eigen::Index>> weight;
    for (Eigen::Index i = 0; i < n; ++i) weight.push_back({std::abs(dir(i)), i});
    std::sort(weight.rbegin(), weight.rend());
    std::string involved;
    for (const auto& w : weight) {
      if (w.first < 1e-3 * weight.front().first) break;  // round-off level: not involved
      involved += (involved.empty() ? "" : ", ") + names[w.second];
    }
    throw FitError(context +
                   ": parameters not identifiable together (rank-deficient normal "
                   "matrix): " +
                   involved);
  }
  const Eigen::MatrixXd Cinv =
      eig.eigenvectors() * ev.cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
  Eigen::MatrixXd inv = d.asDiagonal() * Cinv * d.asDiagonal();
  return 0.5 * (inv + inv.transpose());
}

void finish_result(FitResult& r, const Eigen::Matrix<double, 12, 12>& covariance) {
  r.covariance = 0.5 * (covariance + covariance.transpose());
  for (int s = 0; s < 3; ++s) r.O_std(s) = std::sqrt(std::max(0.0, r.covariance(9 + s, 9 + s)));
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(r.S);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!r.S.allFinite() || !(sv(2) > 1e-12 * sv(0)))
    throw FitError(
        "the fitted vectors u, v, w are linearly dependent (S singular, singular "
        "values " +
        format_number(sv(0)) + ", " + format_number(sv(1)) + ", " + format_number(sv(2)) +
        "): the cross-sensitivity matrix is undefined");
  const Eigen::Matrix<double, 9, 9> cov_S = r.covariance.topLeftCorner<9, 9>();
  r.intrinsics = intrinsics_from_vectors(r.S, cov_S);
  r.cross_sensitivity = r.S.inverse();
  // dP = -P dS P  =>  vec(dP) = -kron(P, P^T) vec(dS) (row-major).
  const Eigen::Matrix<double, 9, 9> J =
      -kronecker(r.cross_sensitivity, r.cross_sensitivity.transpose());
  const Eigen::Matrix<double, 9, 9> cov_P = J * cov_S * J.transpose();
  for (int k = 0; k < 9; ++k)
    r.cross_sensitivity_std(k / 3, k % 3) = std::sqrt(std::max(0.0, cov_P(k, k)));
}

// Factor applied to (A^T W A)^-1. With standard errors from the dwell statistics the weights
// carry an absolute scale and the covariance is only inflated, by the reduced chi-square when
// above 1. With unit weights (no usable std: noise-free or std-less data) the weights are
// relative only and the residuals alone set the scale (unknown-variance least squares,
// s^2 = chi2 / dof), so an exact fit reports an uncertainty at the round-off level, not 1 m/s^2.
double chi2_scale(const FitResult& r, bool unit_weights) {
  if (r.correlation) return std::max(1.0, r.reduced_chi2);
  if (unit_weights) return r.dof > 0 ? r.reduced_chi2 : 0.0;
  return std::max(1.0, r.reduced_chi2);
}

// With a correlation (GLS): chi2 = |L^-1 z|^2 of the normalized residuals z = r / se.
void apply_correlation(FitResult& r, const std::shared_ptr<const DwellCorrelation>& corr) {
  r.correlation = corr;
  if (!corr) return;
  Eigen::VectorXd z(3 * static_cast<Eigen::Index>(r.residuals.size()));
  for (std::size_t i = 0; i < r.residuals.size(); ++i)
    for (int s = 0; s < 3; ++s)
      z(3 * static_cast<Eigen::Index>(i) + s) = r.residuals[i](s) / r.standard_errors[i](s);
  corr->whiten(z);
  r.chi2 = z.squaredNorm();
  r.reduced_chi2 = r.dof > 0 ? r.chi2 / r.dof : 0.0;
}

}  // namespace core
}  // namespace accel_intrinsics
