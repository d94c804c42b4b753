#include "accel_intrinsics/core/fit/tumble.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <memory>
#include <sstream>

#include "accel_intrinsics/core/model/intrinsics.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/noise/slow_part_fit.h"

namespace accel_intrinsics {
namespace core {

const char* const kTumbleFrame =
    "sensor frame: u along x, v in the x-y plane (S lower-triangular); the rotation of S is not "
    "observable without known orientations";

namespace {

constexpr int kParams = 9;  // S lower-triangular (6) then O (3)
// Row-major index in S of each lower-triangular parameter.
constexpr std::array<int, 6> kLowerIndex{{0, 3, 4, 6, 7, 8}};
constexpr std::array<int, 6> kLowerRow{{0, 1, 1, 2, 2, 2}};
constexpr std::array<int, 6> kLowerCol{{0, 0, 1, 0, 1, 2}};
const char* const kParamNames[kParams] = {"S_ux", "S_vx", "S_vy", "S_wx", "S_wy", "S_wz",
                                          "O_u",  "O_v",  "O_w"};
const char* const kIntrinsicNames[9] = {"responsivity_u", "responsivity_v", "responsivity_w",
                                        "angle_uv",       "angle_vw",       "angle_wu",
                                        "offset_u",       "offset_v",       "offset_w"};

using Vector9 = Eigen::Matrix<double, kParams, 1>;
using Matrix9 = Eigen::Matrix<double, kParams, kParams>;

struct Parameters {
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();  // lower-triangular
  Eigen::Vector3d O = Eigen::Vector3d::Zero();

  Vector9 vector() const {
    Vector9 v;
    for (int k = 0; k < 6; ++k) v(k) = S(kLowerRow[k], kLowerCol[k]);
    v.tail<3>() = O;
    return v;
  }
  static Parameters from(const Vector9& v) {
    Parameters p;
    p.S.setZero();
    for (int k = 0; k < 6; ++k) p.S(kLowerRow[k], kLowerCol[k]) = v(k);
    p.O = v.tail<3>();
    return p;
  }
};

// One rest under the parameters: the specific force a = P (m - O), |a| - g and its gradient.
struct RestTerm {
  Eigen::Vector3d a;
  double residual = 0.0;  // |a| - g
  Vector9 gradient;       // d residual / d parameters
  Eigen::Vector3d c;      // P^T a_hat = d|a| / dm
};

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

std::string number(double x, int precision = 3) {
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
      if (std::abs(dir(i)) > 0.1) involved += (involved.empty() ? "" : ", ") + std::string(kParamNames[i]);
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

struct Normal {
  Matrix9 N = Matrix9::Zero();
  Vector9 b = Vector9::Zero();
  double chi2 = 0.0;
};

// The rests to fit and how their means err. White noise: each mean on its own, standard errors
// se. A noise model with a slow part (docs/design.md section 12): the means of neighbouring rests err
// together; R_s = L_s L_s^T from dwell_correlation (noise.h, the one definition of the slow
// covariance between dwells) is their correlation per accelerometer in units of se, i.e.
// Cov(m_i(s), m_j(s)) = se_i(s) se_j(s) R_s(i, j).
struct TumbleProblem {
  const PositionTable* table = nullptr;
  std::vector<Eigen::Vector3d> se;
  bool unit_weights = false;
  double g = kStandardGravity;
  bool gls = false;
  Eigen::MatrixXd R[3];
};

TumbleProblem make_problem(const PositionTable& table, double g, const NoiseModel& noise_model) {
  TumbleProblem problem;
  problem.table = &table;
  problem.se = dwell_standard_errors(table);
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

// How the rests are weighted at an estimate. White: each by the sigma of its residual
// (rest_sigma). GLS: jointly, by the lower Cholesky factor L of the residuals' covariance.
// The residual r_i = |P (m_i - O)| - g depends on the mean m_i through c_i = P^T a_hat_i (first
// order), so C(i, j) = sum_s c_i(s) c_j(s) Cov(m_i(s), m_j(s)), the white variances included.
// The gradients c_i are taken at the current estimate and recomputed every Gauss-Newton
// iteration, as the white sigmas are: they depend on P and each rest's direction, which the start
// ellipsoid already gives far better than the weights need, so the iterations barely move them;
// recomputing costs one rests x rests Cholesky per iteration and with no slow part gives exactly
// the white weights. The step halving keeps the iteration's weights so that its costs compare.
struct RestWeights {
  std::vector<double> sigma;  // white
  Eigen::MatrixXd L;          // GLS
};

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
    throw FitError("tumble: the covariance of the rests' residuals under the noise model is not "
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

// The fit's parameters, information matrix (unscaled) and the covariance scale.
struct TumbleSolution {
  Parameters p;
  Matrix9 information = Matrix9::Zero();
  double chi2 = 0.0;  // at p, with the weights at p
  double scale = 1.0;
};

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

}  // namespace

FitResult fit_tumble(const PositionTable& table, const TumbleFitOptions& options) {
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
  const TumbleProblem problem = make_problem(table, g, options.noise_model);
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

NoiseModel slow_part_from_tumble(const PositionTable& table, const NoiseModel& rest_model,
                                 double local_gravity) {
  NoiseModel model = rest_model;
  const std::size_t n = table.rows.size();
  const std::vector<DwellRecord>& blocks = rest_model.rest_blocks;
  if (!model.slow_part_to_fit() || n < kParams + 4 || blocks.size() < 4) return model;
  const TumbleProblem problem = make_problem(table, local_gravity, NoiseModel());
  if (problem.unit_weights) return model;
  const Parameters p = solve(problem).p;
  // The observations, normalized to unit white variance, each with its interval, its row of the
  // Jacobian and how each accelerometer's mean error reaches it (`load`):
  //  - every rest but the long one: the white fit's scalar residual (|a_i| - g) / sigma_i, its
  //    gradient by the nine parameters, load c_i / sigma_i (first order, as the GLS fit);
  //  - the long rest's blocks, each accelerometer apart: (mean - level) / se, the level three
  //    nuisance parameters (so only the blocks' variation about it counts), load 1 / se.
  // The rest's blocks pin the slow part's short-time shape on all three axes; the rests spread
  // over the run add how it grows over minutes, which the offsets carry.
  const double rest_start = blocks.front().t_start_s, rest_end = blocks.back().t_end_s;
  struct Observation {
    double t0, t1, value;
    Eigen::Vector3d load;
    Eigen::Matrix<double, 1, kParams + 3> gradient;
  };
  std::vector<Observation> obs;
  for (std::size_t i = 0; i < n; ++i) {
    const DwellRecord& row = table.rows[i];
    if (row.t_end_s >= rest_start && row.t_start_s <= rest_end) continue;  // the long rest
    const RestTerm t = rest_term(p, row.mean, local_gravity);
    const double sigma = rest_sigma(t, problem.se[i]);
    Observation o{row.t_start_s, row.t_end_s, t.residual / sigma, t.c / sigma, {}};
    o.gradient.setZero();
    o.gradient.head<kParams>() = t.gradient.transpose() / sigma;
    obs.push_back(o);
  }
  Eigen::Vector3d level = Eigen::Vector3d::Zero();
  for (const DwellRecord& b : blocks) level += b.mean / static_cast<double>(blocks.size());
  for (const DwellRecord& b : blocks) {
    for (int s = 0; s < 3; ++s) {
      const double se = b.std(s) / std::sqrt(static_cast<double>(b.n));
      if (!(se > 0.0)) return model;
      Observation o{b.t_start_s, b.t_end_s, (b.mean(s) - level(s)) / se,
                    Eigen::Vector3d::Zero(), {}};
      o.load(s) = 1.0 / se;
      o.gradient.setZero();
      o.gradient(kParams + s) = 1.0 / se;
      obs.push_back(o);
    }
  }
  const Eigen::Index m = static_cast<Eigen::Index>(obs.size());
  Eigen::VectorXd z(m);
  Eigen::MatrixXd X(m, kParams + 3);
  for (Eigen::Index i = 0; i < m; ++i) {
    z(i) = obs[static_cast<std::size_t>(i)].value;
    X.row(i) = obs[static_cast<std::size_t>(i)].gradient;
  }
  const Eigen::MatrixXd U = residual_complement(X);
  if (U.cols() < 4) return model;
  const Eigen::VectorXd w = U.transpose() * z;
  const RunSpan run = run_span(table);
  const double t_first = run.t_first;
  const double span = std::max(run.length(), 1.0);
  // Each accelerometer's candidate kernels, projected: U^T K U with K(i, j) = load_i(s) load_j(s)
  // Cov_unit(i, j) over the observations' intervals.
  std::vector<AxisNoiseModel> shapes[3];
  std::vector<Eigen::MatrixXd> kernels[3];
  for (int s = 0; s < 3; ++s) {
    shapes[s] = slow_part_shapes(span, model.axes[s]);
    for (const AxisNoiseModel& shape : shapes[s]) {
      NoiseModel unit;
      unit.axes[s] = shape;
      Eigen::MatrixXd K = Eigen::MatrixXd::Zero(m, m);
      for (Eigen::Index i = 0; i < m; ++i) {
        const Observation& a = obs[static_cast<std::size_t>(i)];
        if (a.load(s) == 0.0) continue;
        for (Eigen::Index j = 0; j <= i; ++j) {
          const Observation& b = obs[static_cast<std::size_t>(j)];
          if (b.load(s) == 0.0) continue;
          K(i, j) = K(j, i) =
              a.load(s) * b.load(s) * unit.slow_covariance(s, a.t0, a.t1, b.t0, b.t1, t_first);
        }
      }
      kernels[s].push_back(U.transpose() * K * U);
    }
  }
  // A rest's scalar residual mixes the three accelerometers, so their slow parts are fitted
  // together: coordinate ascent of the restricted likelihood, each
  // accelerometer's shape and amplitude with the other two held, until no choice changes.
  const Eigen::Index k = U.cols();
  AxisNoiseModel fitted[3];
  Eigen::MatrixXd held[3];
  int chosen[3] = {-1, -1, -1};
  for (int s = 0; s < 3; ++s) held[s] = Eigen::MatrixXd::Zero(k, k);
  for (int sweep = 0; sweep < 10; ++sweep) {
    bool changed = false;
    for (int s = 0; s < 3; ++s) {
      Eigen::MatrixXd B = Eigen::MatrixXd::Identity(k, k);
      for (int o = 0; o < 3; ++o)
        if (o != s) B += held[o];
      const Eigen::LLT<Eigen::MatrixXd> llt(B);
      if (llt.info() != Eigen::Success) return model;
      const Eigen::MatrixXd L = llt.matrixL();
      const SlowShapeChoice choice = choose_slow_shape(w, kernels[s], shapes[s], L);
      const int best_shape = choice.shape;
      const SlowAmplitude& best = choice.fit;
      const AxisNoiseModel next =
          best_shape >= 0 ? scaled_shape(shapes[s][static_cast<std::size_t>(best_shape)], best)
                          : AxisNoiseModel();
      if (best_shape != chosen[s] ||
          std::abs(next.gm_sigma - fitted[s].gm_sigma) > 1e-3 * std::abs(next.gm_sigma) ||
          std::abs(next.rw_density - fitted[s].rw_density) > 1e-3 * std::abs(next.rw_density))
        changed = true;
      chosen[s] = best_shape;
      fitted[s] = next;
      held[s] = Eigen::MatrixXd::Zero(k, k);
      if (best_shape >= 0)
        held[s] = best.amplitude * kernels[s][static_cast<std::size_t>(best_shape)];
    }
    if (!changed) break;
  }
  for (int s = 0; s < 3; ++s) {
    AxisNoiseModel& axis = model.axes[s];
    axis.gm_sigma = fitted[s].gm_sigma;
    axis.gm_tau_s = fitted[s].gm_tau_s;
    axis.rw_density = fitted[s].rw_density;
    axis.slow_scale_rel_var = fitted[s].slow_scale_rel_var;
  }
  model.source +=
      slow_part_note("the long rest's blocks and the tumble's rest means together", model);
  return model;
}

std::vector<Eigen::Vector3d> rest_up_directions(const FitResult& fit, const PositionTable& table) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(table.rows.size());
  for (const DwellRecord& row : table.rows) {
    const Eigen::Vector3d a = fit.S.lu().solve(row.mean - fit.O);
    out.push_back(a.normalized());
  }
  return out;
}

TumbleCoverage tumble_coverage(const FitResult& fit, const PositionTable& table, double cone_deg) {
  TumbleCoverage c;
  c.cone_deg = cone_deg;
  const std::vector<Eigen::Vector3d> ups = rest_up_directions(fit, table);
  const char* axis_names[3] = {"u", "v", "w"};
  for (int s = 0; s < 3; ++s) {
    const Eigen::Vector3d axis = fit.S.row(s).normalized();
    for (int side = 0; side < 2; ++side) {
      double best = 180.0;
      for (const Eigen::Vector3d& up : ups) {
        const double cosine = std::clamp((side == 0 ? 1.0 : -1.0) * up.dot(axis), -1.0, 1.0);
        best = std::min(best, std::acos(cosine) * 180.0 / M_PI);
      }
      c.closest_deg[s][side] = best;
      if (best > cone_deg) {
        c.missing.push_back(std::string("no rest with ") + axis_names[s] + " pointing " +
                            (side == 0 ? "up" : "down") + " within " + number(cone_deg) +
                            " deg (closest " + number(best, 3) + " deg)");
      }
    }
  }
  return c;
}

std::vector<RelativeUncertainty> relative_uncertainties(const FitResult& fit) {
  std::vector<RelativeUncertainty> out;
  const Intrinsics& in = fit.intrinsics;
  for (int k = 0; k < 3; ++k)
    out.push_back({kIntrinsicNames[k], in.responsivity_std(k) / in.responsivity(k)});
  for (int k = 0; k < 3; ++k) out.push_back({kIntrinsicNames[3 + k], in.angles_std_rad(k)});
  for (int k = 0; k < 3; ++k)
    out.push_back(
        {kIntrinsicNames[6 + k], fit.O_std(k) / (in.responsivity(k) * fit.local_gravity)});
  return out;
}

PoseSuggestion suggest_next_pose(const FitResult& fit, const PositionTable& table, int candidates) {
  if (fit.model != FitModel::Tumble)
    throw std::invalid_argument("suggest_next_pose needs a tumble fit");
  const double g = fit.local_gravity;
  Parameters p;
  p.S = fit.S;
  p.O = fit.O;
  const TumbleProblem problem = make_problem(table, g, NoiseModel());
  const std::vector<Eigen::Vector3d>& se = problem.se;
  const bool unit_weights = problem.unit_weights;
  const Normal n = accumulate(problem, p, weights_at(problem, p));
  const Matrix9 C = checked_tumble_inverse(n.N);  // unscaled
  const double scale = fit.reduced_chi2 > 1.0 || unit_weights ? fit.reduced_chi2 : 1.0;
  // The typical noise of one more rest: the median standard error per axis.
  Eigen::Vector3d typical;
  for (int s = 0; s < 3; ++s) {
    std::vector<double> v;
    for (const Eigen::Vector3d& e : se) v.push_back(e(s));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    typical(s) = v[v.size() / 2];
  }
  const Matrix9 T = intrinsic_jacobian(fit.S);
  const Vector9 scales = intrinsic_scales(fit.S, g);
  // Variances of the nine intrinsics now (unscaled), and C T^T for the updates.
  const Eigen::Matrix<double, 9, 9> CT = C * T.transpose();
  Vector9 variance;
  for (int k = 0; k < 9; ++k) variance(k) = T.row(k).dot(CT.col(k));
  auto relative = [&](const Vector9& var) {
    return (var.cwiseMax(0.0) * scale).cwiseSqrt().cwiseQuotient(scales);
  };
  const Vector9 now = relative(variance);
  int target = 0;
  now.maxCoeff(&target);
  PoseSuggestion best;
  best.target = kIntrinsicNames[target];
  best.relative_std_now = now(target);
  best.relative_std_after = now(target);
  double best_largest = now.maxCoeff();
  // Candidates on a Fibonacci sphere. One more rest with gradient j and noise sigma changes each
  // variance by -(t_k^T C j)^2 / (sigma^2 + j^T C j) (Sherman-Morrison on the information); the
  // best candidate has the smallest largest relative uncertainty afterwards.
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < candidates; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / candidates;
    const double radius = std::sqrt(std::max(0.0, 1.0 - z * z));
    const Eigen::Vector3d up(radius * std::cos(golden * i), radius * std::sin(golden * i), z);
    const Eigen::Vector3d mean = p.S * (g * up) + p.O;
    const RestTerm term = rest_term(p, mean, g);
    const double sigma = unit_weights ? 1.0 : rest_sigma(term, typical);
    const Vector9& j = term.gradient;
    const Vector9 tCj = CT.transpose() * j;
    const double denominator = sigma * sigma + j.dot(C * j);
    const Vector9 after = relative(variance - tCj.cwiseProduct(tCj) / denominator);
    const double largest = after.maxCoeff();
    if (largest < best_largest) {
      best_largest = largest;
      best.up = up;
      best.relative_std_after = after(target);
    }
  }
  best.largest_after = best_largest;
  best.words = describe_pose(best.up);
  return best;
}

std::string describe_pose(const Eigen::Vector3d& up_in) {
  const Eigen::Vector3d up = up_in.normalized();
  const char* axis[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    const double elevation = std::asin(std::clamp(up(k), -1.0, 1.0)) * 180.0 / M_PI;
    if (elevation >= 80.0) return std::string(axis[k]) + " axis pointing straight up";
    if (elevation <= -80.0) return std::string(axis[k]) + " axis pointing straight down";
  }
  // Name the axes that tilt noticeably, the steepest first.
  std::array<int, 3> order{{0, 1, 2}};
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return std::abs(up(a)) > std::abs(up(b)); });
  std::string words;
  for (int k : order) {
    const double elevation = std::asin(std::clamp(up(k), -1.0, 1.0)) * 180.0 / M_PI;
    if (std::abs(elevation) < 10.0) continue;
    if (!words.empty()) words += ", ";
    words += std::string(axis[k]) + " axis " + number(std::round(std::abs(elevation)), 3) +
             " deg " + (elevation > 0.0 ? "up" : "down");
  }
  return words.empty() ? "level" : words;
}

}  // namespace core
}  // namespace accel_intrinsics
