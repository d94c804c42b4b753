// Detection power of a hidden effect, computed independently of the discrepancy analysis
// (issue 15 item 2): shared by test/core/analysis/detection_theory_test.cpp and
// bench/detection_bench.cpp, deliberately NOT in the core library and calling nothing of
// src/core/analysis/discrepancy.cpp or fit.cpp.
//
// Linear model of the dwell means with KNOWN noise (the simulator's sigma per accelerometer,
// standard error sigma_s / sqrt(n) per dwell), whitened (every row divided by its standard error):
//   base model (joint, docs/design.md section 1): accelerometer s, rows (g f^T, 1) in its own
//   outputs; effect term (docs/design.md section 3): the column b = dR/d(value) at value 0, written
//   out here from the table of section 3 (not from core::predict_outputs).
// The part of b the base model cannot absorb is b_perp = (I - A (A^T A)^-1 A^T) b; the score
// statistic of the effect is T ~ chi2_1(lambda) with non-centrality lambda = value^2 |b_perp|^2
// (exact for terms linear in their value, first order otherwise). A family of candidates tested at
// family-wise level alpha by max-T has the critical value c = the (1 - alpha) quantile of
// max_k y_k^2, y ~ N(0, C), C the correlation of the b_perp directions (Monte Carlo here, with its
// own draws). The probability of naming the effect is then P(chi2_1(lambda) > c) (Boost.Math
// non_central_chi_squared), and the threshold at power p is the value with lambda solving it.
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/distributions/non_central_chi_squared.hpp>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/model/effects.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "written_runs.h"

namespace accel_intrinsics {
namespace detection_theory {

// Where a dwell was taken and how many samples it holds.
struct Dwell {
  core::Phase phase = core::Phase::X;
  double angle_rad = 0.0;
  double mid_time_s = 0.0;  // since t0 (first gimbal command)
  int approach = +1;
  double n = 1.0;
};

// From a position table (time origin t0) and the approach of each row (+1 when all one-way).
inline std::vector<Dwell> dwells_of(const core::PositionTable& table,
                                    const std::vector<int>& approach = {}) {
  std::vector<Dwell> out;
  const double t0 = std::isnan(table.time_origin_s) ? 0.0 : table.time_origin_s;
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    const core::DwellRecord& r = table.rows[i];
    Dwell d;
    d.phase = r.phase;
    d.angle_rad = r.angle_rad;
    d.mid_time_s = 0.5 * (r.t_start_s + r.t_end_s) - t0;
    d.approach = approach.empty() ? +1 : approach[i];
    d.n = static_cast<double>(r.n);
    out.push_back(d);
  }
  return out;
}

// Eq. (4) unit specific force (written_runs.h) and its derivative with respect to the angle.
using written_runs::unit_force;
inline Eigen::Vector3d unit_force_dalpha(core::Phase p, double a) {
  switch (p) {
    case core::Phase::X: return Eigen::Vector3d(0.0, std::cos(a), -std::sin(a));
    case core::Phase::Y: return Eigen::Vector3d(std::cos(a), 0.0, -std::sin(a));
    default: return Eigen::Vector3d(std::cos(a), -std::sin(a), 0.0);
  }
}

struct Problem {
  Eigen::Matrix3d S;      // truth (the linearization point)
  Eigen::Vector3d sigma;  // per-sample noise standard deviation of u, v, w
  double g = 9.80665;
  std::vector<Dwell> dwells;
};

// Whitened residual index: 3 * dwell + accelerometer.
inline double standard_error(const Problem& pr, std::size_t i, int s) {
  return pr.sigma(s) / std::sqrt(pr.dwells[i].n);
}

// Whitened base design matrix (3 N x 12).
inline Eigen::MatrixXd base_design(const Problem& pr) {
  const std::size_t n = pr.dwells.size();
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(3 * n, 12);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d f = pr.g * unit_force(pr.dwells[i].phase, pr.dwells[i].angle_rad);
    for (int s = 0; s < 3; ++s) {
      const double w = 1.0 / standard_error(pr, i, s);
      A.block<1, 3>(3 * i + s, 3 * s) = w * f.transpose();
      A(3 * i + s, 9 + s) = w;
    }
  }
  return A;
}

// Whitened column dR/d(value) of an effect at value 0 (docs/design.md section 3).
inline Eigen::VectorXd effect_column(const Problem& pr, const core::Effect& e) {
  using core::EffectKind;
  const std::size_t n = pr.dwells.size();
  Eigen::VectorXd b = Eigen::VectorXd::Zero(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const Dwell& d = pr.dwells[i];
    const Eigen::Vector3d f = pr.g * unit_force(d.phase, d.angle_rad);
    const Eigen::Vector3d df = pr.g * unit_force_dalpha(d.phase, d.angle_rad);
    const bool in_phase = core::index(d.phase) == e.target;
    Eigen::Vector3d dR = Eigen::Vector3d::Zero();
    switch (e.kind) {
      case EffectKind::QuadraticNonlinearity: {  // K2 L^2 / |s|
        const Eigen::Vector3d s = pr.S.row(e.target).transpose();
        dR(e.target) = std::pow(s.dot(f), 2) / s.norm();
        break;
      }
      case EffectKind::CubicNonlinearity: {  // K3 L^3 / |s|^2
        const Eigen::Vector3d s = pr.S.row(e.target).transpose();
        dR(e.target) = std::pow(s.dot(f), 3) / s.squaredNorm();
        break;
      }
      case EffectKind::OffsetDrift: dR(e.target) = d.mid_time_s; break;  // d (t - t0)
      case EffectKind::AngleOffset:                                      // alpha + delta
        if (in_phase) dR = pr.S * df;
        break;
      case EffectKind::AngleScale:  // alpha (1 + eps)
        if (in_phase) dR = pr.S * df * d.angle_rad;
        break;
      case EffectKind::AxisTilt: {  // f cos tau + g sin tau e_p
        if (in_phase) dR = pr.g * pr.S.col(e.target);
        break;
      }
      case EffectKind::Backlash:  // +-b/2 by approach
        if (in_phase) dR = 0.5 * d.approach * pr.S * df;
        break;
      default: throw std::invalid_argument("detection_theory: no column for " + e.name());
    }
    for (int s = 0; s < 3; ++s) b(3 * i + s) = dR(s) / standard_error(pr, i, s);
  }
  return b;
}

// b minus its projection on the columns of A.
inline Eigen::VectorXd project_out(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  const Eigen::VectorXd coef = (A.transpose() * A).ldlt().solve(A.transpose() * b);
  return b - A * coef;
}

// The candidates the analysis screens on a gimbal table: per accelerometer quadratic, cubic,
// drift; per phase angle offset, angle scale, axis tilt; backlash per phase when two-way.
inline std::vector<core::Effect> candidate_family(bool two_way) {
  using core::EffectKind;
  std::vector<core::Effect> family;
  for (int t = 0; t < 3; ++t) {
    family.push_back({EffectKind::QuadraticNonlinearity, t, 0.0});
    family.push_back({EffectKind::CubicNonlinearity, t, 0.0});
    family.push_back({EffectKind::OffsetDrift, t, 0.0});
    family.push_back({EffectKind::AngleOffset, t, 0.0});
    family.push_back({EffectKind::AngleScale, t, 0.0});
    family.push_back({EffectKind::AxisTilt, t, 0.0});
    if (two_way) family.push_back({EffectKind::Backlash, t, 0.0});
  }
  return family;
}

struct Theory {
  double sigma_value = 0.0;        // 1 / |b_perp|: standard uncertainty of the effect's value
  double information_ratio = 0.0;  // |b_perp|^2 / |b|^2
  double critical_chi2 = 0.0;      // family-wise max-T critical value
  int family_size = 0;             // identifiable candidates in the family
};

// The effect's linearized uncertainty and the family-wise critical value at level alpha
// (candidates with information ratio below `floor` are absorbed by the base model and left out).
inline Theory theory_for(const Problem& pr, const core::Effect& effect,
                         const std::vector<core::Effect>& family, double alpha, int draws = 40000,
                         std::uint64_t seed = 424242, double floor = 1e-6) {
  const Eigen::MatrixXd A = base_design(pr);
  Theory t;
  const Eigen::VectorXd b = effect_column(pr, effect);
  const Eigen::VectorXd bp = project_out(A, b);
  t.sigma_value = 1.0 / bp.norm();
  t.information_ratio = bp.squaredNorm() / b.squaredNorm();
  std::vector<Eigen::VectorXd> dirs;
  for (const core::Effect& c : family) {
    const Eigen::VectorXd bc = effect_column(pr, c);
    const Eigen::VectorXd pc = project_out(A, bc);
    if (!(pc.squaredNorm() >= floor * bc.squaredNorm()) || bc.squaredNorm() == 0.0) continue;
    dirs.push_back(pc / pc.norm());
  }
  const int m = static_cast<int>(dirs.size());
  t.family_size = m;
  Eigen::MatrixXd C(m, m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) C(i, j) = dirs[i].dot(dirs[j]);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(C);
  const Eigen::MatrixXd L =
      eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<double> maxima(draws);
  Eigen::VectorXd xi(m);
  for (int d = 0; d < draws; ++d) {
    for (int i = 0; i < m; ++i) xi(i) = normal(rng);
    maxima[d] = (L * xi).cwiseAbs2().maxCoeff();
  }
  const std::size_t q = static_cast<std::size_t>(std::floor((1.0 - alpha) * draws));
  std::nth_element(maxima.begin(), maxima.begin() + static_cast<long>(q), maxima.end());
  t.critical_chi2 = maxima[q];
  return t;
}

// P(chi2_1(lambda) > c).
inline double power(double lambda, double critical_chi2) {
  if (lambda <= 0.0) {
    const boost::math::chi_squared_distribution<double> central(1.0);
    return boost::math::cdf(boost::math::complement(central, critical_chi2));
  }
  const boost::math::non_central_chi_squared_distribution<double> dist(1.0, lambda);
  return boost::math::cdf(boost::math::complement(dist, critical_chi2));
}

// The non-centrality at which power(lambda, c) = p (bisection; power rises with lambda).
inline double lambda_for_power(double critical_chi2, double p) {
  double lo = 0.0, hi = 1.0;
  while (power(hi, critical_chi2) < p) hi *= 2.0;
  for (int k = 0; k < 200 && hi - lo > 1e-12 * hi; ++k) {
    const double mid = 0.5 * (lo + hi);
    (power(mid, critical_chi2) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// The effect value named with probability p.
inline double threshold(const Theory& t, double p) {
  return std::sqrt(lambda_for_power(t.critical_chi2, p)) * t.sigma_value;
}

// Probability of naming an effect of value `value`.
inline double naming_probability(const Theory& t, double value) {
  return power(std::pow(value / t.sigma_value, 2), t.critical_chi2);
}

}  // namespace detection_theory
}  // namespace accel_intrinsics
