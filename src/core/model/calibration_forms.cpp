#include "accel_intrinsics/core/model/calibration_forms.h"

#include <Eigen/Dense>
#include <cmath>
#include <stdexcept>

namespace accel_intrinsics {
namespace core {
namespace {

void check_invertible(const Eigen::Matrix3d& S) {
  if (!S.allFinite()) throw std::invalid_argument("the matrix S has non-finite entries");
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(S);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv(2) > 1e-9 * sv(0))) throw std::invalid_argument("the matrix S is singular");
}

// A = Qa Ra with Ra upper triangular and a positive diagonal (Householder QR, signs fixed).
void qr_positive(const Eigen::Matrix3d& A, Eigen::Matrix3d* Qa, Eigen::Matrix3d* Ra) {
  const Eigen::HouseholderQR<Eigen::Matrix3d> qr(A);
  Eigen::Matrix3d Q = qr.householderQ();
  Eigen::Matrix3d R = qr.matrixQR().triangularView<Eigen::Upper>();
  for (int i = 0; i < 3; ++i) {
    if (R(i, i) < 0.0) {
      R.row(i) *= -1.0;
      Q.col(i) *= -1.0;
    }
  }
  *Qa = Q;
  *Ra = R;
}

}  // namespace

LowerTriangularForm lower_triangular_form(const Eigen::Matrix3d& S) {
  check_invertible(S);
  // S^T = Qs Rs  =>  S = Rs^T Qs^T: M = Rs^T (lower), Q = Qs^T.
  Eigen::Matrix3d Qs, Rs;
  qr_positive(S.transpose(), &Qs, &Rs);
  LowerTriangularForm out;
  out.M = Rs.transpose();
  out.Q = Qs.transpose();
  return out;
}

UpperTriangularInverseForm upper_triangular_inverse_form(const Eigen::Matrix3d& S) {
  check_invertible(S);
  // P = Qp Up  =>  Up (R - O) = Qp^T P (R - O) = Qp^T a: T K = Up, K = diag(Up), Q = Qp^T.
  const Eigen::Matrix3d P = S.inverse();
  Eigen::Matrix3d Qp, Up;
  qr_positive(P, &Qp, &Up);
  UpperTriangularInverseForm out;
  out.K = Up.diagonal().asDiagonal();
  out.T = Up * out.K.inverse();
  out.T.diagonal().setOnes();  // exactly, as the format defines it
  out.Q = Qp.transpose();
  return out;
}

DiagonalForm diagonal_form(const Eigen::Matrix3d& S) {
  if (!S.allFinite()) throw std::invalid_argument("the matrix S has non-finite entries");
  DiagonalForm out;
  for (int i = 0; i < 3; ++i) {
    const double n2 = S.row(i).squaredNorm();
    if (!(n2 > 0.0)) throw std::invalid_argument("a row of the matrix S is zero");
    out.scale(i) = S(i, i) / n2;
  }
  const Eigen::Matrix3d E = out.scale.asDiagonal() * S - Eigen::Matrix3d::Identity();
  out.worst_error_per_g = Eigen::JacobiSVD<Eigen::Matrix3d>(E).singularValues()(0);
  return out;
}

}  // namespace core
}  // namespace accel_intrinsics
