// The joint fit without effect terms: closed-form weighted (or generalized) least squares per
// accelerometer (conventions at the top of fit.cpp).
#include <Eigen/Dense>
#include <memory>

#include "accel_intrinsics/core/model/model.h"
#include "fit_internal.h"

namespace accel_intrinsics {
namespace core {

// Per accelerometer s: unknowns (s_x, s_y, s_z, O_s), one equation per row,
//   R_s = (g f(phase, alpha))^T s + O_s,  weight 1 / se_s^2.
// Normal equations accumulated row by row: O(N) time, O(1) memory.
LinearJoint solve_joint_linear(const PreparedTable& table, const std::vector<Eigen::Vector3d>& se,
                               double g) {
  std::array<Eigen::Matrix4d, 3> N;
  std::array<Eigen::Vector4d, 3> b;
  for (int s = 0; s < 3; ++s) {
    N[s].setZero();
    b[s].setZero();
  }
  for (std::size_t i = 0; i < table.size(); ++i) {
    const DwellRecord& row = table.row(i);
    const Eigen::Vector3d f = table.direction(i) * g;
    const Eigen::Vector4d h(f(0), f(1), f(2), 1.0);
    const Eigen::Matrix4d hh = h * h.transpose();
    for (int s = 0; s < 3; ++s) {
      const double w = 1.0 / (se[i](s) * se[i](s));
      N[s].noalias() += w * hh;
      b[s].noalias() += (w * row.mean(s)) * h;
    }
  }
  LinearJoint out;
  out.covariance.setZero();
  for (int s = 0; s < 3; ++s) {
    // Solve with the pivoted LDLT rather than multiply by the inverse: exact data stay exact.
    out.store(s, N[s].ldlt().solve(b[s]), N[s], "joint fit");
  }
  return out;
}

// The same by generalized least squares: per accelerometer the rows h / se and the means / se
// whitened by L_s^-1 (DwellCorrelation), then ordinary least squares.
LinearJoint solve_joint_gls(const PreparedTable& table, const std::vector<Eigen::Vector3d>& se,
                            double g, const DwellCorrelation& corr) {
  const Eigen::Index n = static_cast<Eigen::Index>(table.size());
  LinearJoint out;
  out.covariance.setZero();
  out.whitened_jacobian = Eigen::MatrixXd::Zero(3 * n, kNumLinear);
  for (int s = 0; s < 3; ++s) {
    Eigen::MatrixXd A(n, 4);
    Eigen::VectorXd y(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const std::size_t k = static_cast<std::size_t>(i);
      const DwellRecord& row = table.row(k);
      const Eigen::Vector3d f = table.direction(k) * g;
      const double inv = 1.0 / se[k](s);
      A.row(i) << f(0) * inv, f(1) * inv, f(2) * inv, inv;
      y(i) = row.mean(s) * inv;
    }
    corr.L[s].triangularView<Eigen::Lower>().solveInPlace(A);
    corr.L[s].triangularView<Eigen::Lower>().solveInPlace(y);
    out.store(s, A.colPivHouseholderQr().solve(y), A.transpose() * A,
              "joint fit (generalized least squares)");
    const int columns[4] = {3 * s, 3 * s + 1, 3 * s + 2, 9 + s};
    for (Eigen::Index i = 0; i < n; ++i)
      for (int c = 0; c < 4; ++c) out.whitened_jacobian(3 * i + s, columns[c]) = A(i, c);
  }
  return out;
}

FitResult fit_joint_linear(const PreparedTable& table, const FitWeights& weights,
                           const FitOptions& options) {
  const std::vector<Eigen::Vector3d>& se = weights.se;
  const std::shared_ptr<const DwellCorrelation>& corr = weights.corr;
  const LinearJoint lin = corr ? solve_joint_gls(table, se, options.local_gravity, *corr)
                               : solve_joint_linear(table, se, options.local_gravity);
  FitResult r;
  r.model = FitModel::Joint;
  r.local_gravity = options.local_gravity;
  r.S = lin.S;
  r.O = lin.O;
  const double g = options.local_gravity;
  fill_residuals(r, table, se, kNumLinear, [&](std::size_t i) -> Eigen::Vector3d {
    return lin.S * (table.direction(i) * g) + lin.O;
  });
  apply_correlation(r, corr);
  Eigen::Matrix<double, 12, 12> covariance = lin.covariance;
  if (corr && has_estimated_scale(options.noise_model))
    covariance = estimated_scale_covariance(options.noise_model, *corr, lin.whitened_jacobian,
                                            lin.covariance);
  finish_result(r, covariance * chi2_scale(r, weights.unit_weights));
  for (int p = 0; p < 3; ++p) {
    r.offset_per_phase.col(p) = r.O;
    r.offset_per_phase_std.col(p) = r.O_std;
  }
  return r;
}

}  // namespace core
}  // namespace accel_intrinsics
