// The eq. (4) fit of docs/design.md: three independent sets per accelerometer, one per gimbal phase
// (conventions at the top of fit.cpp).
#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <string>

#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "fit_internal.h"

namespace accel_intrinsics {
namespace core {

namespace {

// The two vector components phase p determines (the axes other than p), in increasing order.
std::array<int, 2> phase_components(Phase p) {
  switch (p) {
    case Phase::X: return {{1, 2}};
    case Phase::Y: return {{0, 2}};
    case Phase::Z:
    default: return {{0, 1}};
  }
}

}  // namespace

// Seed eq. (4): for accelerometer s and phase p, R = a g f_c1(alpha) + b g f_c2(alpha) + O_sp,
// (f from in_plane_direction, so a, b are the components c1, c2 of the vector). 9 independent
// 3-parameter weighted fits. Component j of vector s is estimated in the two phases p != j and
// the estimates combined by inverse-variance weight; O_s = mean over phases of O_sp (eq. 5).
// Per accelerometer, theta = (a, b, O) of phases x, y, z (9 values, block-diagonal covariance
// Sigma), and (s_x, s_y, s_z, O_s) = M theta with a 4x9 weight matrix M, so cov = M Sigma M^T
// carries the within-phase correlation of a, b and O exactly.
FitResult fit_eq4(const PreparedTable& table, const FitWeights& weights,
                  const FitOptions& options) {
  const std::vector<Eigen::Vector3d>& se = weights.se;
  const double g = options.local_gravity;
  std::array<std::array<Eigen::Matrix3d, 3>, 3> N;  // [accelerometer][phase]
  std::array<std::array<Eigen::Vector3d, 3>, 3> b;
  for (auto& a : N)
    for (auto& m : a) m.setZero();
  for (auto& a : b)
    for (auto& v : a) v.setZero();
  // Every row is a gimbal dwell (fit() checked): its direction is in_plane_direction(phase, angle).
  auto design_row = [g, &table](std::size_t i) {
    const Eigen::Vector3d f = table.direction(i) * g;
    const std::array<int, 2> c = phase_components(table.row(i).phase);
    return Eigen::Vector3d(f(c[0]), f(c[1]), 1.0);
  };
  for (std::size_t i = 0; i < table.size(); ++i) {
    const DwellRecord& row = table.row(i);
    const int p = index(row.phase);
    const Eigen::Vector3d h = design_row(i);
    const Eigen::Matrix3d hh = h * h.transpose();
    for (int s = 0; s < 3; ++s) {
      const double w = 1.0 / (se[i](s) * se[i](s));
      N[s][p].noalias() += w * hh;
      b[s][p].noalias() += (w * row.mean(s)) * h;
    }
  }
  std::array<std::array<Eigen::Vector3d, 3>, 3> theta;
  std::array<std::array<Eigen::Matrix3d, 3>, 3> cov_set;  // unscaled
  for (int s = 0; s < 3; ++s) {
    for (Phase ph : kPhases) {
      const int p = index(ph);
      const std::array<int, 2> c = phase_components(ph);
      const std::string suffix = std::string(accelerometer_name(s)) + " in phase " + phase_name(ph);
      const std::vector<std::string> names = {std::string("s_") + "xyz"[c[0]] + " of " + suffix,
                                              std::string("s_") + "xyz"[c[1]] + " of " + suffix,
                                              "O of " + suffix};
      cov_set[s][p] = checked_inverse(N[s][p], names, "eq4 fit");
      theta[s][p] = N[s][p].ldlt().solve(b[s][p]);
    }
  }

  FitResult r;
  r.model = FitModel::Eq4;
  r.local_gravity = g;
  fill_residuals(r, table, se, 27, [&](std::size_t i) -> Eigen::Vector3d {
    const Eigen::Vector3d h = design_row(i);
    Eigen::Vector3d m;
    for (int s = 0; s < 3; ++s) m(s) = h.dot(theta[s][index(table.row(i).phase)]);
    return m;
  });
  const double scale = chi2_scale(r, weights.unit_weights);

  Eigen::Matrix<double, 12, 12> cov = Eigen::Matrix<double, 12, 12>::Zero();
  for (int s = 0; s < 3; ++s) {
    // Inverse-variance weights from the unscaled covariance (a common scale cancels, and with
    // unit weights on an exact fit the scaled one may be zero).
    Eigen::Matrix<double, 9, 9> Sigma = Eigen::Matrix<double, 9, 9>::Zero();
    Eigen::Matrix<double, 9, 1> th;
    for (int p = 0; p < 3; ++p) {
      Sigma.block<3, 3>(3 * p, 3 * p) = cov_set[s][p];
      th.segment<3>(3 * p) = theta[s][p];
    }
    Eigen::Matrix<double, 4, 9> M = Eigen::Matrix<double, 4, 9>::Zero();
    for (int j = 0; j < 3; ++j) {
      double total = 0.0;
      for (Phase ph : kPhases) {
        const std::array<int, 2> c = phase_components(ph);
        if (c[0] != j && c[1] != j) continue;
        const int pos = 3 * index(ph) + (c[0] == j ? 0 : 1);
        M(j, pos) = 1.0 / Sigma(pos, pos);
        total += M(j, pos);
      }
      M.row(j) /= total;
    }
    for (int p = 0; p < 3; ++p) M(3, 3 * p + 2) = 1.0 / 3.0;
    const Eigen::Vector4d est = M * th;
    Sigma *= scale;
    const Eigen::Matrix4d c4 = M * Sigma * M.transpose();
    r.S.row(s) = est.head<3>().transpose();
    r.O(s) = est(3);
    const int idx[4] = {3 * s, 3 * s + 1, 3 * s + 2, 9 + s};
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 4; ++c) cov(idx[a], idx[c]) = c4(a, c);
    for (int p = 0; p < 3; ++p) {
      r.offset_per_phase(s, p) = theta[s][p](2);
      r.offset_per_phase_std(s, p) = std::sqrt(Sigma(3 * p + 2, 3 * p + 2));
    }
  }
  finish_result(r, cov);
  return r;
}

}  // namespace core
}  // namespace accel_intrinsics
