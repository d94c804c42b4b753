// Intrinsic parameters (docs/design.md section 1, eqs. 6, 7 of its reference [1]) and their
// GUM uncertainty.
//
// With u, v, w the rows of S:
//   |u| = sqrt(u . u)                                    (eq. 6)
//   theta_uv = arccos(u . v / (|u| |v|))                 (eq. 7)
// The angle is evaluated as atan2(|u x v|, u . v), which equals the arccos for every pair of
// non-zero vectors but stays accurate (and never NaN) near 0 and 180 degrees, where the arccos
// of a rounded cosine loses half the digits or leaves its domain.
//
// Jacobian (analytic): d|u|/du = u / |u|. For the angle, with v_perp = v - (v . u_hat) u_hat the
// part of v orthogonal to u (|v_perp| = |v| sin theta),
//   d theta / du = -v_perp / (|v_perp| |u|),   d theta / dv = -u_perp / (|u_perp| |v|).
// At theta = 0 or pi the angle is not differentiable (it behaves like |x|); there the rows are
// set to zero rather than NaN: the first-order (GUM) uncertainty of such an angle is not defined.
#include "accel_intrinsics/core/model/intrinsics.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace accel_intrinsics {
namespace core {
namespace {

using Matrix9d = Eigen::Matrix<double, 9, 9>;

// Pairs (uv, vw, wu) of accelerometer indices.
constexpr int kPairs[3][2] = {{0, 1}, {1, 2}, {2, 0}};

// Part of b orthogonal to a.
Eigen::Vector3d orthogonal_part(const Eigen::Vector3d& b, const Eigen::Vector3d& a) {
  const Eigen::Vector3d a_hat = a.normalized();
  return b - b.dot(a_hat) * a_hat;
}

// Kronecker product of two 3x3 matrices (9x9).
Matrix9d kronecker(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  Matrix9d k;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) k.block<3, 3>(3 * i, 3 * j) = a(i, j) * b;
  return k;
}

void check_finite_matrix(const Eigen::MatrixXd& m, const char* what) {
  if (!m.allFinite()) throw std::invalid_argument(std::string(what) + " has non-finite entries");
}

}  // namespace

Eigen::Matrix<double, 6, 9> intrinsics_jacobian(const Eigen::Matrix3d& S) {
  Eigen::Matrix<double, 6, 9> J = Eigen::Matrix<double, 6, 9>::Zero();
  for (int s = 0; s < 3; ++s) {
    const Eigen::Vector3d row = S.row(s).transpose();
    const double norm = row.norm();
    if (norm > 0.0) J.block<1, 3>(s, 3 * s) = (row / norm).transpose();
  }
  for (int k = 0; k < 3; ++k) {
    const int a = kPairs[k][0];
    const int b = kPairs[k][1];
    const Eigen::Vector3d va = S.row(a).transpose();
    const Eigen::Vector3d vb = S.row(b).transpose();
    const double na = va.norm();
    const double nb = vb.norm();
    if (na == 0.0 || nb == 0.0) continue;
    const Eigen::Vector3d b_perp = orthogonal_part(vb, va);
    const Eigen::Vector3d a_perp = orthogonal_part(va, vb);
    const double sb = b_perp.norm();
    const double sa = a_perp.norm();
    // sin(theta) relative to round-off: below this the angle is 0 or pi to machine precision.
    if (sb <= 1e-15 * nb || sa <= 1e-15 * na) continue;
    J.block<1, 3>(3 + k, 3 * a) = (-b_perp / (sb * na)).transpose();
    J.block<1, 3>(3 + k, 3 * b) = (-a_perp / (sa * nb)).transpose();
  }
  return J;
}

Intrinsics intrinsics_from_vectors(const Eigen::Matrix3d& S,
                                   const Eigen::Matrix<double, 9, 9>& covariance_S) {
  check_finite_matrix(S, "S");
  check_finite_matrix(covariance_S, "covariance of S");
  Intrinsics out;
  for (int s = 0; s < 3; ++s) out.responsivity(s) = S.row(s).norm();
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d va = S.row(kPairs[k][0]).transpose();
    const Eigen::Vector3d vb = S.row(kPairs[k][1]).transpose();
    out.angles_rad(k) = std::atan2(va.cross(vb).norm(), va.dot(vb));
  }
  const Eigen::Matrix<double, 6, 9> J = intrinsics_jacobian(S);
  out.covariance = J * covariance_S * J.transpose();
  out.covariance = 0.5 * (out.covariance + out.covariance.transpose()).eval();
  for (int i = 0; i < 3; ++i) {
    out.responsivity_std(i) = std::sqrt(std::max(0.0, out.covariance(i, i)));
    out.angles_std_rad(i) = std::sqrt(std::max(0.0, out.covariance(3 + i, 3 + i)));
  }
  return out;
}

Intrinsics intrinsics_from_cross_sensitivity(const Eigen::Matrix3d& P,
                                             const Eigen::Matrix<double, 9, 9>& covariance_P) {
  check_finite_matrix(P, "cross-sensitivity matrix P");
  check_finite_matrix(covariance_P, "covariance of P");
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(P);
  const Eigen::Vector3d sv = svd.singularValues();
  // sv(0) is the largest, >= 0: a zero matrix has sv(2) = sv(0) = 0 and is refused here too.
  if (sv(2) <= 1e-12 * sv(0)) {
    throw std::invalid_argument("cross-sensitivity matrix P is singular (singular values " +
                                std::to_string(sv(0)) + ", " + std::to_string(sv(1)) + ", " +
                                std::to_string(sv(2)) + ")");
  }
  const Eigen::Matrix3d S = P.inverse();
  // dS = -S dP S; row-major vec(A X B) = (A kron B^T) vec(X).
  const Matrix9d J = -kronecker(S, S.transpose());
  const Matrix9d cov_S = J * covariance_P * J.transpose();
  // G = S S^T holds the same information: |u| = sqrt(G_uu), cos theta_uv = G_uv / sqrt(G_uu
  // G_vv); intrinsics_from_vectors evaluates exactly these from the rows of S.
  return intrinsics_from_vectors(S, 0.5 * (cov_S + cov_S.transpose()));
}

}  // namespace core
}  // namespace accel_intrinsics
