// The fitted calibration R = S a + O (docs/design.md section 1) rewritten in the forms other tools
// hold (docs/design.md section 7). Pure linear algebra, shared by the exporters (io/exporters.h)
// and their tests; every form maps raw outputs R to the specific force, in the DUT frame or in a
// rotated frame Q a that the form states.
#pragma once

#include <Eigen/Core>

namespace accel_intrinsics {
namespace core {

// Lower-triangular form (kalibr's scale-misalignment model): S = M Q with M lower triangular,
// positive diagonal, and Q orthogonal, so R - O = M a' with a' = Q a (a frame whose x axis lies
// along u and whose y axis lies in the u-v plane). M M^T = S S^T. Q is a rotation when det S > 0
// (a right-handed triad) and a reflection otherwise.
struct LowerTriangularForm {
  Eigen::Matrix3d M = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d Q = Eigen::Matrix3d::Identity();
};
// Throws std::invalid_argument when S is singular or not finite.
LowerTriangularForm lower_triangular_form(const Eigen::Matrix3d& S);

// Upper-triangular inverse form (imu_tk): a' = T K (R - O) with T unit upper triangular, K
// diagonal (positive), a' = Q a, Q orthogonal. T K = Q P, P = S^-1.
struct UpperTriangularInverseForm {
  Eigen::Matrix3d T = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d Q = Eigen::Matrix3d::Identity();
};
// Throws std::invalid_argument when S is singular or not finite.
UpperTriangularInverseForm upper_triangular_inverse_form(const Eigen::Matrix3d& S);

// Diagonal form (px4, ardupilot): a ~= diag(scale) (R - O), the offsets exact, the axis
// couplings dropped. scale_i = S_ii / |s_i|^2 makes each row of diag(scale) S - I as short as it
// can be (least squares per axis). The error it leaves at a specific force a of magnitude g is
// (diag(scale) S - I) a, at most g * ||diag(scale) S - I||_2 over all orientations.
struct DiagonalForm {
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
  double worst_error_per_g = 0.0;  // ||diag(scale) S - I||_2 (spectral norm): error / |a|
};
// Throws std::invalid_argument when a row of S is zero or S is not finite.
DiagonalForm diagonal_form(const Eigen::Matrix3d& S);

}  // namespace core
}  // namespace accel_intrinsics
