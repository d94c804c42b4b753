#include "accel_intrinsics/core/fit/tumble.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <memory>
#include <sstream>
#include <utility>

#include "accel_intrinsics/core/model/intrinsics.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "tumble_internal.h"

namespace accel_intrinsics {
namespace core {

const char* const kTumbleFrame =
    "sensor frame: u along x, v in the x-y plane (S lower-triangular); the rotation of S is not "
    "observable without known orientations";

namespace tumble_detail {

RestTerm rest_term(const Parameters& p, const Eigen::Vector3d& mean, double g) {
  RestTerm t;
  const Eigen::Matrix3d& S = p.S;
  t.a = S.triangularView<Eigen::Lower>().solve(mean - p.O);
  const double norm = t.a.norm();
  t.residual = norm - g;
  const Eigen::Vector3d a_hat = t.a / norm;
  // c = P^T a_hat = S^-T a_hat (S^T is upper-triangular).
  t.c = S.transpose().triangularView<Eigen::Upper>().solve(a_hat);
  // d|a| = a_hat^T da, da = -P dS a - P dO  =>  d|a|/dS_jk = -c_j a_k, d|a|/dO = -c.
  for (int k = 0; k < 6; ++k) t.gradient(k) = -t.c(kLowerRow[k]) * t.a(kLowerCol[k]);
  t.gradient.tail<3>() = -t.c;
  return t;
}

double rest_sigma(const RestTerm& t, const Eigen::Vector3d& se) {
  return std::sqrt(t.c.cwiseProduct(se).squaredNorm());
}

std::string number(double x, int precision) {
  std::ostringstream out;
  out << std::setprecision(precision) << x;
  return out.str();
}

// The algebraic ellipsoid through the rest means (start of the fit): x^T A x + b^T x + c = 0 in
// centred, scaled coordinates, the smallest right singular vector of the design matrix.
Parameters ellipsoid_start(const PositionTable& table, double g) {
  const std::size_t n = table.rows.size();
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const DwellRecord& r : table.rows) centre += r.mean;
  centre /= static_cast<double>(n);
  double scale = 0.0;
  for (const DwellRecord& r : table.rows) scale += (r.mean - centre).squaredNorm();
  scale = std::sqrt(scale / static_cast<double>(n));
  if (!(scale > 0.0))
    throw FitError("tumble: every rest has the same mean: the device was never turned");
  Eigen::MatrixXd D(n, 10);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x = (table.rows[i].mean - centre) / scale;
    D.row(static_cast<Eigen::Index>(i)) << x(0) * x(0), x(1) * x(1), x(2) * x(2), 2 * x(0) * x(1),
        2 * x(0) * x(2), 2 * x(1) * x(2), x(0), x(1), x(2), 1.0;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(D, Eigen::ComputeFullV);
  Eigen::VectorXd v = svd.matrixV().col(9);
  Eigen::Matrix3d A;
  A << v(0), v(3), v(4), v(3), v(1), v(5), v(4), v(5), v(2);
  if (A.trace() < 0.0) {
    A = -A;
    v = -v;
  }
  const Eigen::Vector3d b = v.segment<3>(6);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(A);
  if (!(eig.eigenvalues()(0) > 0.0))
    throw FitError(
        "tumble: the rest means do not lie on an ellipsoid (the orientations are too few or too "
        "close together): turn the device through more, well spread orientations");
  const Eigen::Vector3d centre_scaled = -0.5 * A.ldlt().solve(b);
  const double k = centre_scaled.dot(A * centre_scaled) - v(9);
  if (!(k > 0.0)) throw FitError("tumble: the algebraic ellipsoid fit is degenerate");
  // (x - x0)^T (A / k) (x - x0) = 1 in scaled units; m = centre + scale x.
  const Eigen::Matrix3d M = A / (k * scale * scale);
  Parameters p;
  p.O = centre + scale * centre_scaled;
  // P^T P = g^2 M  =>  G = S S^T = (g^2 M)^-1; S its lower Cholesky factor.
  const Eigen::Matrix3d G = (g * g * M).inverse();
  const Eigen::LLT<Eigen::Matrix3d> llt(0.5 * (G + G.transpose()));
  if (llt.info() != Eigen::Success) throw FitError("tumble: the start ellipsoid is not definite");
  p.S = llt.matrixL();
  return p;
}

// The scaled-diagonal eigen test of fit.cpp's checked_inverse, naming the parameters of the
// weakest direction in words a tumble user can act on.
Matrix9 checked_tumble_inverse(const Matrix9& N) {
  Vector9 d;
  for (int i = 0; i < kParams; ++i) {
    if (!(N(i, i) > 0.0) || !std::isfinite(N(i, i)))
      throw FitError(std::string("tumble: the rests do not constrain ") + kParamNames[i]);
    d(i) = 1.0 / std::sqrt(N(i, i));
  }
  const Matrix9 C = d.asDiagonal() * N * d.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix9> eig(C);
  const Vector9 ev = eig.eigenvalues();
  if (!(ev(0) > 1e-12 * ev(kParams - 1))) {
    const Vector9 dir = eig.eigenvectors().col(0);
    std::string involved;
    for (int i = 0; i < kParams; ++i)
      if (std::abs(dir(i)) > 0.1)
        involved += (involved.empty() ? "" : ", ") + std::string(kParamNames[i]);
    throw FitError(
        "tumble: the rests do not determine the intrinsics (their orientations leave " + involved +
        " undetermined): turn the device through more orientations, every axis up and down");
  }
  Matrix9 inv = d.asDiagonal() * eig.eigenvectors() * ev.cwiseInverse().asDiagonal() *
                eig.eigenvectors().transpose() * d.asDiagonal();
  return 0.5 * (inv + inv.transpose());
}

bool has_usable_std(const PositionTable& table) {
  for (const DwellRecord& r : table.rows)
    if (r.n >= 2 && r.std.allFinite() && r.std.maxCoeff() > 0.0) return true;
  return false;
}

TumbleProblem make_problem(const PositionTable& table, double g, const NoiseModel& noise_model) {
  return make_problem(table, dwell_standard_errors(table), g, noise_model);
}

TumbleProblem make_problem(const PositionTable& table, std::vector<Eigen::Vector3d> se, double g,
                           const NoiseModel& noise_model) {
  TumbleProblem problem;
  problem.table = &table;
  problem.se = std::move(se);
  problem.unit_weights = !has_usable_std(table);
  problem.g = g;
  if (noise_model.white() || problem.unit_weights) return problem;
  const std::shared_ptr<const DwellCorrelation> corr =
      dwell_correlation(table, problem.se, noise_model);
  if (!corr) return problem;
  problem.gls = true;
  for (int s = 0; s < 3; ++s) problem.R[s] = corr->L[s] * corr->L[s].transpose();
  return problem;
}

RestWeights weights_at(const TumbleProblem& problem, const Parameters& p) {
  const PositionTable& table = *problem.table;
  const std::size_t n = table.rows.size();
  RestWeights w;
  if (!problem.gls) {
    w.sigma.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const RestTerm t = rest_term(p, table.rows[i].mean, problem.g);
      w.sigma[i] = problem.unit_weights ? 1.0 : rest_sigma(t, problem.se[i]);
    }
    return w;
  }
  const Eigen::Index m = static_cast<Eigen::Index>(n);
  Eigen::MatrixXd u(m, 3);  // c_i(s) se_i(s)
  for (Eigen::Index i = 0; i < m; ++i) {
    const std::size_t row = static_cast<std::size_t>(i);
    const RestTerm t = rest_term(p, table.rows[row].mean, problem.g);
    u.row(i) = t.c.cwiseProduct(problem.se[row]).transpose();
  }
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(m, m);
  for (int s = 0; s < 3; ++s)
    C.noalias() += u.col(s).asDiagonal() * problem.R[s] * u.col(s).asDiagonal();
  const Eigen::LLT<Eigen::MatrixXd> llt(C);
  if (llt.info() != Eigen::Success)
    throw FitError(
        "tumble: the covariance of the rests' residuals under the noise model is not "
        "positive definite");
  w.L = llt.matrixL();
  return w;
}

// Normal equations of the residuals, weighted each on its own (white) or whitened by L^-1 (GLS).
Normal accumulate(const TumbleProblem& problem, const Parameters& p, const RestWeights& weights) {
  const PositionTable& table = *problem.table;
  Normal out;
  if (!problem.gls) {
    for (std::size_t i = 0; i < table.rows.size(); ++i) {
      const RestTerm t = rest_term(p, table.rows[i].mean, problem.g);
      const double sigma = weights.sigma[i];
      const double w = 1.0 / (sigma * sigma);
      out.N.noalias() += w * t.gradient * t.gradient.transpose();
      out.b.noalias() += w * t.gradient * t.residual;
      out.chi2 += w * t.residual * t.residual;
    }
    return out;
  }
  const Eigen::Index m = static_cast<Eigen::Index>(table.rows.size());
  Eigen::VectorXd r(m);
  Eigen::Matrix<double, Eigen::Dynamic, kParams> J(m, kParams);
  for (Eigen::Index i = 0; i < m; ++i) {
    const RestTerm t = rest_term(p, table.rows[static_cast<std::size_t>(i)].mean, problem.g);
    r(i) = t.residual;
    J.row(i) = t.gradient.transpose();
  }
  weights.L.triangularView<Eigen::Lower>().solveInPlace(r);
  weights.L.triangularView<Eigen::Lower>().solveInPlace(J);
  out.N.noalias() = J.transpose() * J;
  out.b.noalias() = J.transpose() * r;
  out.chi2 = r.squaredNorm();
  return out;
}

// Positive diagonal: the sign of each column of S is a reflection of the frame, not observable.
Parameters canonical(Parameters p) {
  for (int k = 0; k < 3; ++k) {
    if (p.S(k, k) < 0.0) p.S.col(k) = -p.S.col(k);
  }
  return p;
}

// Jacobian of the nine intrinsics (responsivities, angles, offsets) by the nine parameters.
Matrix9 intrinsic_jacobian(const Eigen::Matrix3d& S) {
  const Eigen::Matrix<double, 6, 9> J = intrinsics_jacobian(S);  // by S row-major
  Matrix9 T = Matrix9::Zero();
  for (int k = 0; k < 6; ++k) T.block<6, 1>(0, k) = J.col(kLowerIndex[k]);
  T.bottomRightCorner<3, 3>().setIdentity();
  return T;
}

Vector9 intrinsic_scales(const Eigen::Matrix3d& S, double g) {
  Vector9 s;
  for (int k = 0; k < 3; ++k) s(k) = S.row(k).norm();
  for (int k = 3; k < 6; ++k) s(k) = 1.0;  // radians
  for (int k = 0; k < 3; ++k) s(6 + k) = S.row(k).norm() * g;
  return s;
}

TumbleSolution solve(const TumbleProblem& problem) {
  const PositionTable& table = *problem.table;
  Parameters p = ellipsoid_start(table, problem.g);
  // Gauss-Newton with step halving; the weights follow the current estimate (they depend on P).
  for (int iteration = 0; iteration < 100; ++iteration) {
    const RestWeights weights = weights_at(problem, p);
    const Normal n = accumulate(problem, p, weights);
    const Eigen::LDLT<Matrix9> ldlt(n.N);
    const Vector9 step = -ldlt.solve(n.b);
    if (!step.allFinite()) break;
    double t = 1.0;
    Parameters next = p;
    bool improved = false;
    for (int halving = 0; halving < 30; ++halving) {
      next = Parameters::from(p.vector() + t * step);
      const double cost = accumulate(problem, next, weights).chi2;
      if (std::isfinite(cost) && cost <= n.chi2 * (1.0 + 1e-12)) {
        improved = true;
        break;
      }
      t *= 0.5;
    }
    if (!improved) break;
    p = next;
    // Converged when the step is far below the parameters' own uncertainty.
    const Vector9 diag = n.N.diagonal();
    double largest = 0.0;
    for (int k = 0; k < kParams; ++k)
      largest = std::max(largest, std::abs(t * step(k)) * std::sqrt(std::max(diag(k), 0.0)));
    if (largest < 1e-10) break;
  }
  p = canonical(p);
  TumbleSolution out;
  out.p = p;
  const Normal n = accumulate(problem, p, weights_at(problem, p));
  out.information = n.N;
  out.chi2 = n.chi2;
  const int dof = static_cast<int>(table.rows.size()) - kParams;
  const double reduced = dof > 0 ? n.chi2 / dof : 0.0;
  out.scale = problem.unit_weights ? reduced : std::max(1.0, reduced);
  return out;
}

}  // namespace tumble_detail

using namespace tumble_detail;

FitResult fit_tumble(const PositionTable& table, const TumbleFitOptions& options) {
  return fit_tumble(PreparedTable(table), options);
}

FitResult fit_tumble(const PreparedTable& prepared, const TumbleFitOptions& options) {
  const PositionTable& table = prepared.table();
  const std::size_t n = table.rows.size();
  if (n < options.min_rests) {
    throw FitError("tumble: " + std::to_string(n) + " rests, at least " +
                   std::to_string(options.min_rests) + " needed (" +
                   std::to_string(options.min_rests - n) +
                   " more): hold the device still in more orientations, every axis up and down");
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!table.rows[i].orientation_unknown)
      throw FitError("tumble: row " + std::to_string(i + 1) +
                     " has a known orientation; a tumble fit takes rests of unknown orientation "
                     "only (phase '-' without f_x,f_y,f_z)");
  }
  const double g = options.local_gravity;
  const TumbleProblem problem =
      make_problem(table, prepared.standard_errors(), g, options.noise_model);
  const TumbleSolution sol = solve(problem);
  const Matrix9 cov = checked_tumble_inverse(sol.information) * sol.scale;

  FitResult r;
  r.model = FitModel::Tumble;
  r.local_gravity = g;
  r.S = sol.p.S;
  r.O = sol.p.O;
  r.standard_errors = problem.se;
  if (problem.gls) r.noise_model = options.noise_model;
  r.residuals.resize(n);
  double sum_sq = 0.0;
  r.chi2 = problem.gls ? sol.chi2 : 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const RestTerm t = rest_term(sol.p, table.rows[i].mean, g);
    if (!problem.gls) {
      const double sigma = problem.unit_weights ? 1.0 : rest_sigma(t, r.standard_errors[i]);
      r.chi2 += (t.residual / sigma) * (t.residual / sigma);
    }
    // Mean minus its projection on the fitted ellipsoid: S (a - g a_hat) = S a_hat (|a| - g).
    r.residuals[i] = r.S * (t.a.normalized() * t.residual);
    sum_sq += r.residuals[i].squaredNorm();
  }
  r.dof = static_cast<int>(n) - kParams;
  r.reduced_chi2 = r.dof > 0 ? r.chi2 / r.dof : 0.0;
  r.residual_rms = std::sqrt(sum_sq / (3.0 * static_cast<double>(n)));
  Eigen::Matrix<double, 12, 12> full = Eigen::Matrix<double, 12, 12>::Zero();
  for (int a = 0; a < kParams; ++a) {
    const int ia = a < 6 ? kLowerIndex[a] : 9 + (a - 6);
    for (int b = 0; b < kParams; ++b) {
      const int ib = b < 6 ? kLowerIndex[b] : 9 + (b - 6);
      full(ia, ib) = cov(a, b);
    }
  }
  finish_result(r, full);
  for (int p = 0; p < 3; ++p) {
    r.offset_per_phase.col(p) = r.O;
    r.offset_per_phase_std.col(p) = r.O_std;
  }
  r.positions = {{0, 0, 0}};
  return r;
}

}  // namespace core
}  // namespace accel_intrinsics
