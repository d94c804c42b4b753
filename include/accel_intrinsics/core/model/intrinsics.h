// Intrinsic parameters (docs/design.md section 1, eqs. 6, 7 of its reference [1]) and their
// uncertainty (GUM: Jacobian propagation).
#pragma once

#include <Eigen/Core>

namespace accel_intrinsics {
namespace core {

// |u|, |v|, |w| and the angles uv, vw, wu, each with its standard uncertainty.
struct Intrinsics {
  Eigen::Vector3d responsivity = Eigen::Vector3d::Zero();
  Eigen::Vector3d responsivity_std = Eigen::Vector3d::Zero();
  Eigen::Vector3d angles_rad = Eigen::Vector3d::Zero();  // uv, vw, wu
  Eigen::Vector3d angles_std_rad = Eigen::Vector3d::Zero();
  // Full covariance of (|u|, |v|, |w|, theta_uv, theta_vw, theta_wu).
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
};

// From the vectors (rows of S) and the 9x9 covariance of S in row-major order.
Intrinsics intrinsics_from_vectors(
    const Eigen::Matrix3d& S,
    const Eigen::Matrix<double, 9, 9>& covariance_S = Eigen::Matrix<double, 9, 9>::Zero());

// From an independently measured cross-sensitivity matrix P (a = P (R - O)): S = P^-1,
// G = S S^T, |u| = sqrt(G_uu), cos theta_uv = G_uv / sqrt(G_uu G_vv). The covariance of P
// (row-major) is optional. Throws std::invalid_argument when P is singular.
Intrinsics intrinsics_from_cross_sensitivity(
    const Eigen::Matrix3d& P,
    const Eigen::Matrix<double, 9, 9>& covariance_P = Eigen::Matrix<double, 9, 9>::Zero());

// Jacobian d(intrinsics)/d(S row-major), 6x9.
Eigen::Matrix<double, 6, 9> intrinsics_jacobian(const Eigen::Matrix3d& S);

}  // namespace core
}  // namespace accel_intrinsics
