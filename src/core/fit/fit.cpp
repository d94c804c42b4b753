// Fits of the rig model to a position table: joint (linear, or Ceres with effect terms) and eq4.
//
// Conventions shared by all fits
// - Each dwell mean R_s (s = u, v, w) is a measurement with standard error se_s =
//   std_s / sqrt(n) (dwell_standard_errors), weight 1 / se_s^2; the noise of u, v and w is
//   taken as independent.
// - chi2 = sum over rows and accelerometers of ((R_meas - R_model) / se)^2, dof = residuals
//   minus parameters, reduced_chi2 = chi2 / dof.
// - Covariance = (A^T W A)^-1 ((J^T W J)^-1 for the non-linear fit), multiplied by the reduced
//   chi-square when that is above 1 (with unit weights, for data without a usable std, by the
//   reduced chi-square itself: see chi2_scale). We scale with the GLOBAL reduced chi-square,
//   the one reported in FitResult, for every model: it is the only choice that also works for
//   the non-linear fit, where gimbal effects couple the three accelerometers, and it keeps
//   joint, joint+effects and eq4 comparable for the discrepancy analysis. (Per accelerometer
//   would be defensible for the linear joint fit, whose three 4-parameter problems are
//   independent; it differs only when one accelerometer misfits much worse than the others,
//   and then the analysis should name the missing effect rather than let the uncertainty of
//   that one accelerometer absorb it.)
// - Residuals reported per row are measured minus model, m/s^2.
// - Noise that is not white (docs/design.md section 12; FitOptions::noise_model with a slow part):
//   the joint fits use GENERALIZED least squares with the full covariance the noise model
//   implies between the dwell means of each accelerometer (C = D R D, noise.h
//   dwell_correlation), not merely dwell variances inflated by the slow part. Why: a slow bias
//   makes neighbouring dwells err TOGETHER. Inflating each variance keeps the estimate's spread
//   honest only if the errors were independent; here they are not, so the inflated fit still
//   misstates the covariance of S and O (a common error of a whole phase acts like an offset,
//   a smooth one like a harmonic), and its residuals stay correlated in time, which the
//   discrepancy analysis would read as drift or angle effects. GLS weights the information
//   correctly (the efficient estimate) and whitens the residuals, so the analysis' tests keep
//   their chi-square distributions. Its cost is one Cholesky factor per accelerometer (rows^3 / 3;
//   a 24-step run has 72 rows). eq4 fits each phase on its own, where cross-phase correlations
//   do not fit its independent-sets construction; it inflates each dwell's variance by its slow
//   part (variance of the mean over the dwell) instead. The tumble fit is GLS too (tumble.h):
//   its scalar residual per rest, linearized in the rest's mean, gets the covariance of the
//   means across rests. Inflated variances were tried there first and measured short: under a
//   30 s Gauss-Markov bias the offsets' RMS z was 1.5 with the true model, because the rests err
//   together (test/core/noise/correlated_noise_test.cpp).
#include "accel_intrinsics/core/fit/fit.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <memory>
#include <set>
#include <sstream>
#include <utility>

#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/core/fit/tumble.h"

namespace accel_intrinsics {
namespace core {

const char* model_name(FitModel model) {
  switch (model) {
    case FitModel::Joint: return "joint";
    case FitModel::Eq4: return "eq4";
    case FitModel::Tumble: return "tumble";
  }
  return "unknown";
}

FitModel parse_model(const std::string& name) {
  if (name == "joint") return FitModel::Joint;
  if (name == "eq4") return FitModel::Eq4;
  throw std::invalid_argument("unknown fit model '" + name + "' (expected joint or eq4)");
}

std::string FitResult::model_label() const {
  std::string label = model_name(model);
  for (const Effect& e : effects) label += "+" + e.label();
  return label;
}

namespace {

// dwell_standard_errors, also telling whether any accelerometer fell back to unit weights
// (no row with a usable std: noise-free or std-less data).
std::vector<Eigen::Vector3d> standard_errors(const PositionTable& table, bool* unit_weights) {
  const std::size_t rows = table.rows.size();
  std::vector<Eigen::Vector3d> se(rows, Eigen::Vector3d::Zero());
  if (unit_weights) *unit_weights = false;
  for (int s = 0; s < 3; ++s) {
    std::vector<double> valid;
    std::vector<bool> ok(rows, false);
    for (std::size_t i = 0; i < rows; ++i) {
      const DwellRecord& r = table.rows[i];
      const double sd = r.std(s);
      if (r.n >= 2 && std::isfinite(sd) && sd > 0.0) {
        se[i](s) = sd / std::sqrt(static_cast<double>(r.n));
        ok[i] = true;
        valid.push_back(se[i](s));
      }
    }
    double fallback = 1.0;  // noise-free data: unit weights
    if (valid.empty() && unit_weights) *unit_weights = true;
    if (!valid.empty()) {
      const std::size_t mid = valid.size() / 2;
      std::nth_element(valid.begin(), valid.begin() + mid, valid.end());
      fallback = valid[mid];
      if (valid.size() % 2 == 0) {
        const double lower = *std::max_element(valid.begin(), valid.begin() + mid);
        fallback = 0.5 * (fallback + lower);
      }
    }
    for (std::size_t i = 0; i < rows; ++i)
      if (!ok[i]) se[i](s) = fallback;
  }
  return se;
}

}  // namespace

std::vector<Eigen::Vector3d> dwell_standard_errors(const PositionTable& table) {
  return standard_errors(table, nullptr);
}

namespace {

constexpr int kNumLinear = 12;  // S (9, row-major) and O (3)

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

// Kronecker product of two 3x3 matrices: row-major vec(A X B) = kron(A, B^T) vec(X).
Eigen::Matrix<double, 9, 9> kronecker(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  Eigen::Matrix<double, 9, 9> k;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) k.block<3, 3>(3 * i, 3 * j) = a(i, j) * b;
  return k;
}

// ---- validation --------------------------------------------------------------------------

void validate_options(const FitOptions& options) {
  if (!std::isfinite(options.local_gravity) || options.local_gravity <= 0.0)
    throw FitError("local_gravity must be a positive finite number of m/s^2, got " +
                   format_number(options.local_gravity));
  if (options.min_positions_per_phase < 3)
    throw FitError("min_positions_per_phase is " + std::to_string(options.min_positions_per_phase) +
                   "; every model needs at least 3 dwells per phase");
}

void validate_rows(const PositionTable& table) {
  static const char* const kMean[3] = {"mean_u", "mean_v", "mean_w"};
  static const char* const kStd[3] = {"std_u", "std_v", "std_w"};
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    const DwellRecord& r = table.rows[i];
    auto fail = [&](const std::string& field, const std::string& what) {
      throw FitError(row_name(table, i) + ": " + field + " " + what);
    };
    if (!std::isfinite(r.angle_rad)) fail("angle_rad", "is " + format_number(r.angle_rad));
    if (!std::isfinite(r.t_start_s)) fail("t_start", "is " + format_number(r.t_start_s));
    if (!std::isfinite(r.t_end_s)) fail("t_end", "is " + format_number(r.t_end_s));
    if (r.n == 0) fail("n", "is 0 (a dwell without samples)");
    for (int s = 0; s < 3; ++s) {
      if (!std::isfinite(r.mean(s))) fail(kMean[s], "is " + format_number(r.mean(s)));
      if (!std::isfinite(r.std(s))) fail(kStd[s], "is " + format_number(r.std(s)));
      if (r.std(s) < 0.0) fail(kStd[s], "is negative (" + format_number(r.std(s)) + ")");
    }
  }
}

// Every phase needs min_positions dwells at >= 3 distinct angles: R = a g sin + b g cos + c has
// three unknowns per phase, and (sin a, cos a, 1) of points on one circle has rank 3 exactly
// when at least three of them are distinct.
void validate_geometry(const PositionTable& table, int min_positions) {
  const std::array<int, 3> counts = positions_per_phase(table);
  for (Phase p : kPhases) {
    const int count = counts[index(p)];
    if (count < min_positions)
      throw FitError("phase " + std::string(phase_name(p)) + " has " + std::to_string(count) +
                     " dwells, needs at least " + std::to_string(min_positions));
  }
  for (Phase p : kPhases) {
    Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
    std::vector<double> angles;
    for (const DwellRecord& r : table.rows) {
      if (r.phase != p) continue;
      const Eigen::Vector3d h(std::sin(r.angle_rad), std::cos(r.angle_rad), 1.0);
      M += h * h.transpose();
      double a = std::fmod(r.angle_rad, 2.0 * kPi);
      if (a < 0.0) a += 2.0 * kPi;
      angles.push_back(a);
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(M);
    const Eigen::Vector3d ev = eig.eigenvalues();
    if (ev(0) > 1e-10 * ev(2)) continue;
    std::sort(angles.begin(), angles.end());
    int distinct = angles.empty() ? 0 : 1;
    for (std::size_t k = 1; k < angles.size(); ++k)
      if (angles[k] - angles[k - 1] > 1e-9) ++distinct;
    if (distinct > 1 && angles.back() - angles.front() > 2.0 * kPi - 1e-9) --distinct;
    throw FitError("phase " + std::string(phase_name(p)) + " has a degenerate geometry: its " +
                   std::to_string(angles.size()) + " dwells lie at " + std::to_string(distinct) +
                   " distinct angle(s) (or span too small an arc); at least 3 distinct angles "
                   "are needed to determine the vector components");
  }
}

// The joint fit takes any set of orientations that determines S and O (docs/design.md section 6):
// the gimbal phases present keep the per-phase checks (they are what the rows claim to be),
// and the whole set must give (f_x, f_y, f_z, 1) full rank, well conditioned. A complete gimbal
// run (three phases, no direction rows) is checked as before.
void validate_joint_geometry(const PositionTable& table, int min_positions) {
  const std::array<int, 3> counts = positions_per_phase(table);
  const bool three_phases = counts[0] > 0 && counts[1] > 0 && counts[2] > 0;
  if (three_phases && rows_with_direction(table) == 0) {
    validate_geometry(table, min_positions);
    return;
  }
  if (table.rows.empty()) throw FitError("the position table has no dwells");
  for (Phase p : kPhases) {
    const int count = counts[index(p)];
    if (count > 0 && count < min_positions)
      throw FitError("phase " + std::string(phase_name(p)) + " has " + std::to_string(count) +
                     " dwells, needs at least " + std::to_string(min_positions));
  }
  Eigen::Matrix4d M = Eigen::Matrix4d::Zero();
  for (const DwellRecord& r : table.rows) {
    const Eigen::Vector3d f = specific_force_direction(r);
    const Eigen::Vector4d h(f(0), f(1), f(2), 1.0);
    M += h * h.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(M / static_cast<double>(table.rows.size()));
  const Eigen::Vector4d ev = eig.eigenvalues();
  // Conditioning: 1e-6 leaves the weakest combination determined to about 1000x the noise of the
  // others; below it the fit is dominated by round-off and by how well the orientations are known.
  if (ev(0) > 1e-6 * ev(3)) return;
  Eigen::Vector4d c = eig.eigenvectors().col(0);
  c /= c.cwiseAbs().maxCoeff();
  std::ostringstream m;
  m.precision(3);
  m << "the orientations do not determine S and O (" << table.rows.size()
    << " dwells): every one satisfies " << c(0) << " f_x + " << c(1) << " f_y + " << c(2)
    << " f_z + " << c(3)
    << " = 0 (f: unit specific force), so the same combination of the vector components and "
       "offsets is unobservable; add orientations off that plane";
  throw FitError(m.str());
}

void validate_effects(const std::vector<Effect>& effects, FitModel model,
                      const std::vector<DwellGeometry>& geoms) {
  if (effects.empty()) return;
  std::string names;
  for (const Effect& e : effects) names += (names.empty() ? "" : ", ") + e.name();
  if (model != FitModel::Joint)
    throw FitError(std::string("effects need the joint model: ") + model_name(model) +
                   " cannot fit " + names);
  std::set<std::pair<int, int>> seen;
  for (const Effect& e : effects) {
    const EffectInfo& info = effect_info(e.kind);
    if (e.kind == EffectKind::TimingLag)
      throw FitError(
          "timing_lag cannot be fitted from dwell means: it shifts the IMU stamps against the "
          "gimbal, and within a settled dwell the outputs do not depend on that shift; only the "
          "raw sample streams (samples taken while moving) reveal it");
    if (info.target_kind == TargetKind::All)
      throw FitError(std::string(info.name) +
                     " targets all accelerometers and phases at once, which the dwell means "
                     "cannot separate from S and O");
    if (e.target < 0 || e.target > 2)
      throw FitError(std::string(info.name) + " has target index " + std::to_string(e.target) +
                     "; expected 0..2 (" +
                     (info.target_kind == TargetKind::Accelerometer ? "u, v, w" : "x, y, z") + ")");
    if (!std::isfinite(e.value))
      throw FitError("starting value of " + e.label() + " is " + format_number(e.value));
    if (!seen.insert({static_cast<int>(e.kind), e.target}).second)
      throw FitError(e.label() + " is listed twice; each effect term can be fitted once");
    if (e.kind == EffectKind::Backlash) {
      bool up = false, down = false;
      for (const DwellGeometry& g : geoms) {
        if (index(g.phase) != e.target) continue;
        up = up || g.approach > 0;
        down = down || g.approach < 0;
      }
      if (!(up && down))
        throw FitError(e.label() + " needs a two-way sweep: every dwell of phase " +
                       e.target_name() +
                       " was approached from the same direction, so backlash cannot be told "
                       "from angle_offset[" +
                       e.target_name() + "]");
    }
    if (info.precondition == Precondition::TemperatureVaries) {
      std::size_t missing = 0;
      double lo = 0.0, hi = 0.0;
      bool first = true;
      for (const DwellGeometry& g : geoms) {
        if (!g.has_temperature) {
          ++missing;
          continue;
        }
        lo = first ? g.temperature_offset_k : std::min(lo, g.temperature_offset_k);
        hi = first ? g.temperature_offset_k : std::max(hi, g.temperature_offset_k);
        first = false;
      }
      if (missing > 0)
        throw FitError(e.label() + " needs the temperature of every dwell: " +
                       std::to_string(missing) + " of " + std::to_string(geoms.size()) +
                       " rows have none (record imu/temperature, or fill the position table's "
                       "temperature_c column)");
      if (!(hi > lo))
        throw FitError(e.label() +
                       " needs dwell temperatures that differ: every row has the same "
                       "temperature, so the coefficient cannot be told from the offset");
    }
    if (e.kind == EffectKind::OffsetDrift) {
      double lo = 0.0, hi = 0.0;
      for (std::size_t i = 0; i < geoms.size(); ++i) {
        lo = i == 0 ? geoms[i].time_s : std::min(lo, geoms[i].time_s);
        hi = i == 0 ? geoms[i].time_s : std::max(hi, geoms[i].time_s);
      }
      if (!(hi > lo))
        throw FitError(e.label() +
                       " needs dwell times: every row has the same mid-dwell time, so a drift "
                       "cannot be told from the offset");
    }
  }
}

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

}  // namespace

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

namespace {

// Residuals, chi2, dof, rms. `model_of_row(i)` returns the model outputs of row i.
template <typename ModelOfRow>
void fill_residuals(FitResult& r, const PositionTable& table,
                    const std::vector<Eigen::Vector3d>& se, int num_parameters,
                    ModelOfRow&& model_of_row) {
  const std::size_t rows = table.rows.size();
  r.residuals.resize(rows);
  r.standard_errors = se;
  r.chi2 = 0.0;
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < rows; ++i) {
    r.residuals[i] = table.rows[i].mean - model_of_row(i);
    r.chi2 += r.residuals[i].cwiseQuotient(se[i]).squaredNorm();
    sum_sq += r.residuals[i].squaredNorm();
  }
  r.dof = 3 * static_cast<int>(rows) - num_parameters;
  // dof = 0 (eq4 with exactly 3 dwells per phase): the fit interpolates, there is no redundancy
  // to judge it by; reduced_chi2 is reported as 0 and the covariance left unscaled (with unit
  // weights as well, i.e. no noise information at all, the uncertainties come out zero).
  r.reduced_chi2 = r.dof > 0 ? r.chi2 / r.dof : 0.0;
  r.residual_rms = rows > 0 ? std::sqrt(sum_sq / (3.0 * rows)) : 0.0;
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

// ---- joint, linear -----------------------------------------------------------------------

struct LinearJoint {
  Eigen::Matrix3d S;
  Eigen::Vector3d O;
  Eigen::Matrix<double, 12, 12> covariance;  // unscaled (A^T W A)^-1
  // GLS only: the whitened Jacobian, 3 rows per dwell (u, v, w interleaved), 12 columns.
  Eigen::MatrixXd whitened_jacobian;

  // Accelerometer s's unknowns x = (s_x, s_y, s_z, O_s) and the inverse of their normal matrix
  // `normal` (named in the error when it is singular) into S, O and the covariance.
  void store(int s, const Eigen::Vector4d& x, const Eigen::Matrix4d& normal, const char* fit_name) {
    std::vector<std::string> names;
    for (int c = 0; c < 3; ++c) names.push_back(linear_parameter_name(3 * s + c));
    names.push_back(linear_parameter_name(9 + s));
    const Eigen::Matrix4d inv = checked_inverse(normal, names, fit_name);
    S.row(s) = x.head<3>().transpose();
    O(s) = x(3);
    const int idx[4] = {3 * s, 3 * s + 1, 3 * s + 2, 9 + s};
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 4; ++c) covariance(idx[a], idx[c]) = inv(a, c);
  }
};

// Per accelerometer s: unknowns (s_x, s_y, s_z, O_s), one equation per row,
//   R_s = (g f(phase, alpha))^T s + O_s,  weight 1 / se_s^2.
// Normal equations accumulated row by row: O(N) time, O(1) memory.
LinearJoint solve_joint_linear(const PositionTable& table, const std::vector<Eigen::Vector3d>& se,
                               double g) {
  std::array<Eigen::Matrix4d, 3> N;
  std::array<Eigen::Vector4d, 3> b;
  for (int s = 0; s < 3; ++s) {
    N[s].setZero();
    b[s].setZero();
  }
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    const DwellRecord& row = table.rows[i];
    const Eigen::Vector3d f = specific_force_direction(row) * g;
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
LinearJoint solve_joint_gls(const PositionTable& table, const std::vector<Eigen::Vector3d>& se,
                            double g, const DwellCorrelation& corr) {
  const Eigen::Index n = static_cast<Eigen::Index>(table.rows.size());
  LinearJoint out;
  out.covariance.setZero();
  out.whitened_jacobian = Eigen::MatrixXd::Zero(3 * n, kNumLinear);
  for (int s = 0; s < 3; ++s) {
    Eigen::MatrixXd A(n, 4);
    Eigen::VectorXd y(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const DwellRecord& row = table.rows[static_cast<std::size_t>(i)];
      const Eigen::Vector3d f = specific_force_direction(row) * g;
      const double inv = 1.0 / se[static_cast<std::size_t>(i)](s);
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

FitResult fit_joint_linear(const PositionTable& table, const std::vector<Eigen::Vector3d>& se,
                           bool unit_weights, const FitOptions& options,
                           const std::shared_ptr<const DwellCorrelation>& corr) {
  const LinearJoint lin = corr ? solve_joint_gls(table, se, options.local_gravity, *corr)
                               : solve_joint_linear(table, se, options.local_gravity);
  FitResult r;
  r.model = FitModel::Joint;
  r.local_gravity = options.local_gravity;
  r.S = lin.S;
  r.O = lin.O;
  const double g = options.local_gravity;
  fill_residuals(r, table, se, kNumLinear, [&](std::size_t i) -> Eigen::Vector3d {
    const DwellRecord& row = table.rows[i];
    return lin.S * (specific_force_direction(row) * g) + lin.O;
  });
  apply_correlation(r, corr);
  Eigen::Matrix<double, 12, 12> covariance = lin.covariance;
  if (corr && has_estimated_scale(options.noise_model))
    covariance = estimated_scale_covariance(options.noise_model, *corr, lin.whitened_jacobian,
                                            lin.covariance);
  finish_result(r, covariance * chi2_scale(r, unit_weights));
  for (int p = 0; p < 3; ++p) {
    r.offset_per_phase.col(p) = r.O;
    r.offset_per_phase_std.col(p) = r.O_std;
  }
  return r;
}

// ---- joint with effect terms (Ceres) -------------------------------------------------------

// Normalized residual of one dwell mean under the rig model with effect terms.
//
// The dwell mean of accelerometer s is modeled as R_s = predict_outputs(S, O, effects; geometry)
// (model.h: the same template the simulator evaluates) plus Gaussian noise of standard error
// se_s, independent between rows and accelerometers. The negative log-likelihood is then
//   0.5 * sum_rows sum_s ((predict_s - R_meas_s) / se_s)^2,
// which is exactly Ceres' cost 0.5 * sum r^2 with the residual
//   r_s = (predict_s(S, O, values) - R_meas_s) / se_s.
// Parameter blocks: S (9, row-major), O (3), then one block of size 1 per effect value.
class DwellMeanResidual {
 public:
  static constexpr int kStride = 16;  // one autodiff pass for S, O and up to 4 effect values

  DwellMeanResidual(std::shared_ptr<const std::vector<Effect>> terms, const DwellGeometry& geom,
                    const Eigen::Vector3d& measured, const Eigen::Vector3d& standard_error,
                    double g)
      : terms_(std::move(terms)),
        geom_(geom),
        measured_(measured),
        inverse_se_(standard_error.cwiseInverse()),
        g_(g) {}

  template <typename T>
  bool operator()(T const* const* parameters, T* residuals) const {
    const std::size_t k = terms_->size();
    std::vector<T> values(k);
    for (std::size_t i = 0; i < k; ++i) values[i] = parameters[2 + i][0];
    const Eigen::Matrix<T, 3, 1> model =
        predict_outputs(parameters[0], parameters[1], *terms_, values.data(), geom_, g_);
    for (int s = 0; s < 3; ++s) residuals[s] = (model(s) - T(measured_(s))) * T(inverse_se_(s));
    return true;
  }

  static ceres::CostFunction* Create(std::shared_ptr<const std::vector<Effect>> terms,
                                     const DwellGeometry& geom, const Eigen::Vector3d& measured,
                                     const Eigen::Vector3d& standard_error, double g) {
    const std::size_t k = terms->size();
    auto* cost = new ceres::DynamicAutoDiffCostFunction<DwellMeanResidual, kStride>(
        new DwellMeanResidual(std::move(terms), geom, measured, standard_error, g));
    cost->AddParameterBlock(9);
    cost->AddParameterBlock(3);
    for (std::size_t i = 0; i < k; ++i) cost->AddParameterBlock(1);
    cost->SetNumResiduals(3);
    return cost;
  }

 private:
  std::shared_ptr<const std::vector<Effect>> terms_;
  DwellGeometry geom_;
  Eigen::Vector3d measured_;
  Eigen::Vector3d inverse_se_;
  double g_;
};

struct EffectsProblem {
  std::array<double, 9> S{};
  std::array<double, 3> O{};
  std::vector<double> values;
  ceres::Problem problem;
  std::vector<double*> blocks;  // S, O, values...
};

void build_effects_problem(EffectsProblem& prob, const PositionTable& table,
                           const std::vector<Eigen::Vector3d>& se,
                           const std::vector<DwellGeometry>& geoms, const FitOptions& options,
                           const LinearJoint& start) {
  for (int k = 0; k < 9; ++k) prob.S[k] = start.S(k / 3, k % 3);
  for (int s = 0; s < 3; ++s) prob.O[s] = start.O(s);
  prob.values.clear();
  for (const Effect& e : options.effects) prob.values.push_back(e.value);
  prob.blocks = {prob.S.data(), prob.O.data()};
  for (double& v : prob.values) prob.blocks.push_back(&v);
  auto terms = std::make_shared<const std::vector<Effect>>(options.effects);
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    prob.problem.AddResidualBlock(DwellMeanResidual::Create(terms, geoms[i], table.rows[i].mean,
                                                            se[i], options.local_gravity),
                                  nullptr, prob.blocks);
  }
}

ceres::Solver::Summary solve_effects_problem(EffectsProblem& prob) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = 200;
  so.function_tolerance = 1e-15;
  so.gradient_tolerance = 1e-16;
  so.parameter_tolerance = 1e-14;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &prob.problem, &summary);
  return summary;
}

// Normalized residuals z and their Jacobian (dense, rows 3 row + s) at the problem's current
// parameter values.
bool evaluate_effects_problem(EffectsProblem& prob, Eigen::VectorXd* z, Eigen::MatrixXd* J,
                              int num_params) {
  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = prob.blocks;
  eo.num_threads = 1;
  double cost = 0.0;
  std::vector<double> normalized;
  ceres::CRSMatrix jac;
  if (!prob.problem.Evaluate(eo, &cost, &normalized, nullptr, J ? &jac : nullptr)) return false;
  *z = Eigen::Map<const Eigen::VectorXd>(normalized.data(),
                                         static_cast<Eigen::Index>(normalized.size()));
  if (J) {
    J->setZero(jac.num_rows, num_params);
    for (int row = 0; row < jac.num_rows; ++row)
      for (int idx = jac.rows[row]; idx < jac.rows[row + 1]; ++idx)
        (*J)(row, jac.cols[idx]) = jac.values[idx];
  }
  return true;
}

std::vector<double*> parameter_pointers(EffectsProblem& prob) {
  std::vector<double*> out;
  for (int k = 0; k < 9; ++k) out.push_back(&prob.S[k]);
  for (int k = 0; k < 3; ++k) out.push_back(&prob.O[k]);
  for (double& v : prob.values) out.push_back(&v);
  return out;
}

// Generalized least squares with effect terms: minimizes |L^-1 z(theta)|^2 by Levenberg-Marquardt
// from the white (Ceres) solution, with the Jacobian of the one model that Ceres evaluates.
// The models are mildly non-linear and the start is close, so a few steps converge.
void refine_gls(EffectsProblem& prob, const DwellCorrelation& corr, int num_params,
                const std::string& label) {
  const std::vector<double*> params = parameter_pointers(prob);
  auto get = [&]() {
    Eigen::VectorXd x(num_params);
    for (int k = 0; k < num_params; ++k) x(k) = *params[k];
    return x;
  };
  auto set = [&](const Eigen::VectorXd& x) {
    for (int k = 0; k < num_params; ++k) *params[k] = x(k);
  };
  Eigen::VectorXd z;
  Eigen::MatrixXd J;
  if (!evaluate_effects_problem(prob, &z, &J, num_params))
    throw FitError("evaluating " + label + " failed");
  corr.whiten(z);
  corr.whiten_columns(J);
  double cost = z.squaredNorm();
  double mu = 1e-6;
  for (int iteration = 0; iteration < 100; ++iteration) {
    const Eigen::MatrixXd N = J.transpose() * J;
    const Eigen::VectorXd grad = J.transpose() * z;
    const Eigen::VectorXd x = get();
    bool improved = false;
    for (int tries = 0; tries < 20 && !improved; ++tries) {
      Eigen::MatrixXd damped = N;
      damped.diagonal() += mu * N.diagonal().cwiseMax(1e-300);
      const Eigen::VectorXd step = -damped.ldlt().solve(grad);
      if (!step.allFinite()) {
        mu *= 10.0;
        continue;
      }
      set(x + step);
      Eigen::VectorXd z_new;
      Eigen::MatrixXd J_new;
      if (evaluate_effects_problem(prob, &z_new, &J_new, num_params)) {
        corr.whiten(z_new);
        const double new_cost = z_new.squaredNorm();
        if (new_cost <= cost) {
          corr.whiten_columns(J_new);
          const double drop = cost - new_cost;
          z = z_new;
          J = J_new;
          cost = new_cost;
          mu = std::max(1e-12, mu / 10.0);
          improved = true;
          const double rel_step =
              step.cwiseAbs().cwiseQuotient(x.cwiseAbs().cwiseMax(1e-12)).maxCoeff();
          if (drop <= 1e-14 * std::max(1.0, cost) || rel_step < 1e-13) return;
          break;
        }
      }
      set(x);
      mu *= 10.0;
    }
    if (!improved) return;  // no step lowers the cost: at the minimum (to round-off)
  }
}

FitResult fit_joint_effects(const PositionTable& table, const std::vector<Eigen::Vector3d>& se,
                            bool unit_weights, const std::vector<DwellGeometry>& geoms,
                            const FitOptions& options,
                            const std::shared_ptr<const DwellCorrelation>& corr) {
  std::string label = "joint";
  for (const Effect& e : options.effects) label += "+" + e.label();
  const std::size_t k = options.effects.size();
  const int num_params = kNumLinear + static_cast<int>(k);
  if (3 * static_cast<int>(table.rows.size()) <= num_params)
    throw FitError(label + " has " + std::to_string(num_params) + " parameters but only " +
                   std::to_string(3 * table.rows.size()) + " dwell means");

  const LinearJoint start = solve_joint_linear(table, se, options.local_gravity);
  EffectsProblem prob;
  build_effects_problem(prob, table, se, geoms, options, start);
  const ceres::Solver::Summary summary = solve_effects_problem(prob);

  FitResult r;
  r.model = FitModel::Joint;
  r.local_gravity = options.local_gravity;
  r.effects = options.effects;
  if (!summary.IsSolutionUsable())
    throw FitError("the Ceres solve of " + label + " failed: " + summary.message);
  r.solver_message = summary.BriefReport();
  if (corr) {
    refine_gls(prob, *corr, num_params, label);
    r.solver_message += " (then generalized least squares, Levenberg-Marquardt)";
  }

  for (int j = 0; j < 9; ++j) r.S(j / 3, j % 3) = prob.S[j];
  for (int s = 0; s < 3; ++s) r.O(s) = prob.O[s];
  for (std::size_t i = 0; i < k; ++i) r.effects[i].value = prob.values[i];

  // J^T W J from the Jacobian of the normalized residuals at the solution (whitened for GLS).
  Eigen::VectorXd normalized;
  Eigen::MatrixXd J;
  if (!evaluate_effects_problem(prob, &normalized, &J, num_params))
    throw FitError("evaluating the Jacobian of " + label + " failed");
  if (corr) corr->whiten_columns(J);
  const Eigen::MatrixXd JtJ = J.transpose() * J;
  std::vector<std::string> names;
  for (int j = 0; j < kNumLinear; ++j) names.push_back(linear_parameter_name(j));
  for (const Effect& e : options.effects) names.push_back(e.label());
  Eigen::MatrixXd cov_unscaled = checked_inverse(JtJ, names, label);
  if (corr && has_estimated_scale(options.noise_model))
    cov_unscaled = estimated_scale_covariance(options.noise_model, *corr, J, cov_unscaled);

  // Residuals as measured minus model: the normalized Ceres residual times -se.
  fill_residuals(r, table, se, num_params, [&](std::size_t i) -> Eigen::Vector3d {
    return table.rows[i].mean +
           Eigen::Vector3d(normalized(3 * i), normalized(3 * i + 1), normalized(3 * i + 2))
               .cwiseProduct(se[i]);
  });
  apply_correlation(r, corr);
  const Eigen::MatrixXd cov = cov_unscaled * chi2_scale(r, unit_weights);
  finish_result(r, cov.topLeftCorner<kNumLinear, kNumLinear>());
  r.effects_std.resize(k);
  for (std::size_t i = 0; i < k; ++i)
    r.effects_std[i] = std::sqrt(std::max(0.0, cov(kNumLinear + i, kNumLinear + i)));
  for (int p = 0; p < 3; ++p) {
    r.offset_per_phase.col(p) = r.O;
    r.offset_per_phase_std.col(p) = r.O_std;
  }
  return r;
}

// ---- eq4 ---------------------------------------------------------------------------------

// The two vector components phase p determines (the axes other than p), in increasing order.
std::array<int, 2> phase_components(Phase p) {
  switch (p) {
    case Phase::X: return {{1, 2}};
    case Phase::Y: return {{0, 2}};
    case Phase::Z:
    default: return {{0, 1}};
  }
}

// Seed eq. (4): for accelerometer s and phase p, R = a g f_c1(alpha) + b g f_c2(alpha) + O_sp,
// (f from in_plane_direction, so a, b are the components c1, c2 of the vector). 9 independent
// 3-parameter weighted fits. Component j of vector s is estimated in the two phases p != j and
// the estimates combined by inverse-variance weight; O_s = mean over phases of O_sp (eq. 5).
// Per accelerometer, theta = (a, b, O) of phases x, y, z (9 values, block-diagonal covariance
// Sigma), and (s_x, s_y, s_z, O_s) = M theta with a 4x9 weight matrix M, so cov = M Sigma M^T
// carries the within-phase correlation of a, b and O exactly.
FitResult fit_eq4(const PositionTable& table, const std::vector<Eigen::Vector3d>& se,
                  bool unit_weights, const FitOptions& options) {
  const double g = options.local_gravity;
  std::array<std::array<Eigen::Matrix3d, 3>, 3> N;  // [accelerometer][phase]
  std::array<std::array<Eigen::Vector3d, 3>, 3> b;
  for (auto& a : N)
    for (auto& m : a) m.setZero();
  for (auto& a : b)
    for (auto& v : a) v.setZero();
  auto design_row = [g](const DwellRecord& row) {
    const Eigen::Vector3d f = in_plane_direction(row.phase, row.angle_rad) * g;
    const std::array<int, 2> c = phase_components(row.phase);
    return Eigen::Vector3d(f(c[0]), f(c[1]), 1.0);
  };
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    const DwellRecord& row = table.rows[i];
    const int p = index(row.phase);
    const Eigen::Vector3d h = design_row(row);
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
    const DwellRecord& row = table.rows[i];
    const Eigen::Vector3d h = design_row(row);
    Eigen::Vector3d m;
    for (int s = 0; s < 3; ++s) m(s) = h.dot(theta[s][index(row.phase)]);
    return m;
  });
  const double scale = chi2_scale(r, unit_weights);

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

}  // namespace

FitResult fit(const PositionTable& table, const FitOptions& options) {
  validate_options(options);
  if (!options.effects.empty() && options.model != FitModel::Joint) {
    validate_effects(options.effects, options.model, {});
  }
  validate_rows(table);
  // Rests of unknown orientation (a hand tumble): only |P (mean - O)| = g can take them.
  const std::size_t unknown = rows_with_unknown_orientation(table);
  if (unknown > 0) {
    if (unknown != table.rows.size())
      throw FitError(std::to_string(unknown) + " of " + std::to_string(table.rows.size()) +
                     " rows have an unknown orientation (phase '-' without f_x,f_y,f_z): a table "
                     "is either a tumble (all unknown) or known orientations, not both");
    if (options.model == FitModel::Eq4)
      throw FitError("eq4 needs the gimbal's three phases; rests of unknown orientation are "
                     "fitted by the tumble fit (model joint)");
    if (!options.effects.empty())
      throw FitError("effect terms need known orientations; a tumble fit has none");
    // Noise that is not white: GLS across the rests (tumble.h), as the joint fits (see the top).
    TumbleFitOptions tumble;
    tumble.local_gravity = options.local_gravity;
    tumble.noise_model = options.noise_model;
    return fit_tumble(table, tumble);
  }
  if (options.model == FitModel::Eq4) {
    for (std::size_t i = 0; i < table.rows.size(); ++i) {
      if (table.rows[i].has_direction)
        throw FitError("row " + std::to_string(i + 1) +
                       " gives its orientation as f_x,f_y,f_z: eq4 fits a sinusoid per gimbal "
                       "phase and needs the three phases; use the joint model");
    }
    validate_geometry(table, options.min_positions_per_phase);
  } else {
    validate_joint_geometry(table, options.min_positions_per_phase);
  }
  bool unit_weights = false;
  std::vector<Eigen::Vector3d> se = standard_errors(table, &unit_weights);
  // Noise that is not white: GLS for the joint fits, inflated variances for eq4 (see the top).
  std::shared_ptr<const DwellCorrelation> corr;
  if (!options.noise_model.white() && !unit_weights) {
    if (options.model == FitModel::Eq4) {
      for (std::size_t i = 0; i < se.size(); ++i) {
        const DwellRecord& row = table.rows[i];
        for (int s = 0; s < 3; ++s)
          se[i](s) = std::sqrt(se[i](s) * se[i](s) +
                               options.noise_model.slow_covariance(s, row.t_start_s, row.t_end_s,
                                                                   row.t_start_s, row.t_end_s,
                                                                   row.t_start_s));
      }
    } else {
      corr = dwell_correlation(table, se, options.noise_model);
    }
  }
  FitResult r;
  if (options.model == FitModel::Eq4) {
    r = fit_eq4(table, se, unit_weights, options);
  } else if (options.effects.empty()) {
    r = fit_joint_linear(table, se, unit_weights, options, corr);
  } else {
    const std::vector<DwellGeometry> geoms = dwell_geometries(table);
    if (geoms.size() != table.rows.size())
      throw FitError("dwell_geometries returned " + std::to_string(geoms.size()) + " entries for " +
                     std::to_string(table.rows.size()) + " rows");
    validate_effects(options.effects, options.model, geoms);
    r = fit_joint_effects(table, se, unit_weights, geoms, options, corr);
  }
  r.noise_model = unit_weights ? NoiseModel() : options.noise_model;
  r.positions = positions_per_phase(table);
  return r;
}

}  // namespace core
}  // namespace accel_intrinsics
