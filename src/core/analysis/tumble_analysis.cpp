#include "accel_intrinsics/core/analysis/tumble_analysis.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/fisher_f.hpp>
#include <cmath>
#include <memory>

#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/fit/tumble.h"
#include "accel_intrinsics/core/model/model.h"

namespace accel_intrinsics {
namespace core {
namespace {

constexpr std::array<int, 6> kLowerIndex{{0, 3, 4, 6, 7, 8}};

// Residual of one rest mean: (outputs_for_force(S, O, effects; g f) - m) / se, f a unit vector.
// Parameter blocks: S lower-triangular (6), O (3), f (3, on the sphere), one block per effect.
class RestMeanResidual {
 public:
  static constexpr int kStride = 8;

  RestMeanResidual(std::shared_ptr<const std::vector<Effect>> terms, const DwellGeometry& geom,
                   const Eigen::Vector3d& mean, const Eigen::Vector3d& se, double g)
      : terms_(std::move(terms)), geom_(geom), mean_(mean), inverse_se_(se.cwiseInverse()), g_(g) {}

  template <typename T>
  bool operator()(T const* const* p, T* residuals) const {
    T S[9];
    for (int k = 0; k < 9; ++k) S[k] = T(0.0);
    for (int k = 0; k < 6; ++k) S[kLowerIndex[k]] = p[0][k];
    std::vector<T> values(terms_->size());
    for (std::size_t i = 0; i < terms_->size(); ++i) values[i] = p[3 + i][0];
    const Eigen::Matrix<T, 3, 1> f(T(g_) * p[2][0], T(g_) * p[2][1], T(g_) * p[2][2]);
    const Eigen::Matrix<T, 3, 1> R = outputs_for_force(S, p[1], *terms_, values.data(), f, geom_);
    for (int s = 0; s < 3; ++s) residuals[s] = (R(s) - T(mean_(s))) * T(inverse_se_(s));
    return true;
  }

 private:
  std::shared_ptr<const std::vector<Effect>> terms_;
  DwellGeometry geom_;
  Eigen::Vector3d mean_, inverse_se_;
  double g_;
};

// All rests at once, whitened across rests (generalized least squares under a slow bias,
// docs/design.md section 12): every rest's normalized residuals (RestMeanResidual, interleaved 3 i
// + s), then per accelerometer s the vector (z_0s, z_1s, ...) times L_s^-1 by forward substitution,
// L_s the Cholesky factor of the rest means' correlation (noise.h DwellCorrelation). One residual
// block, since the whitening couples every rest. Parameter blocks: S lower (6), O (3), the n
// directions (3 each), then one per effect.
class WhitenedRestMeans {
 public:
  static constexpr int kStride = RestMeanResidual::kStride;

  WhitenedRestMeans(std::vector<RestMeanResidual> rests,
                    std::shared_ptr<const DwellCorrelation> corr, std::size_t effects)
      : rests_(std::move(rests)), corr_(std::move(corr)), effects_(effects) {}

  template <typename T>
  bool operator()(T const* const* p, T* residuals) const {
    const std::size_t n = rests_.size();
    std::vector<T const*> blocks(3 + effects_);
    blocks[0] = p[0];
    blocks[1] = p[1];
    for (std::size_t j = 0; j < effects_; ++j) blocks[3 + j] = p[2 + n + j];
    for (std::size_t i = 0; i < n; ++i) {
      blocks[2] = p[2 + i];
      if (!rests_[i](blocks.data(), residuals + 3 * i)) return false;
    }
    for (int s = 0; s < 3; ++s) {
      const Eigen::MatrixXd& L = corr_->L[s];
      for (Eigen::Index i = 0; i < static_cast<Eigen::Index>(n); ++i) {
        T x = residuals[3 * i + s];
        for (Eigen::Index j = 0; j < i; ++j) x -= L(i, j) * residuals[3 * j + s];
        residuals[3 * i + s] = x / L(i, i);
      }
    }
    return true;
  }

 private:
  std::vector<RestMeanResidual> rests_;
  std::shared_ptr<const DwellCorrelation> corr_;
  std::size_t effects_;
};

// The normalized residuals back from whitened ones: z_s = L_s w_s per accelerometer.
std::vector<double> unwhitened(const DwellCorrelation& corr, const std::vector<double>& w) {
  const Eigen::Index n = static_cast<Eigen::Index>(corr.rows);
  std::vector<double> z(w.size());
  for (int s = 0; s < 3; ++s) {
    Eigen::VectorXd part(n);
    for (Eigen::Index i = 0; i < n; ++i) part(i) = w[static_cast<std::size_t>(3 * i + s)];
    const Eigen::VectorXd colored = corr.L[s].triangularView<Eigen::Lower>() * part;
    for (Eigen::Index i = 0; i < n; ++i) z[static_cast<std::size_t>(3 * i + s)] = colored(i);
  }
  return z;
}

bool has_usable_std(const PositionTable& table) {
  for (const DwellRecord& r : table.rows)
    if (r.n >= 2 && r.std.allFinite() && r.std.maxCoeff() > 0.0) return true;
  return false;
}

double p_value(double statistic, double reduced_chi2, int dof) {
  if (!(statistic > 0.0)) return 1.0;
  if (reduced_chi2 > 1.0 && dof > 0) {
    const boost::math::fisher_f f(1.0, static_cast<double>(dof));
    return boost::math::cdf(boost::math::complement(f, statistic));
  }
  const boost::math::chi_squared chi2(1.0);
  return boost::math::cdf(boost::math::complement(chi2, statistic));
}

// The residual blocks of fit_tumble_with_effects: one per rest (white), or one for all rests,
// whitened across them (GLS, `corr` set). Directions on the sphere.
void add_rests(ceres::Problem& problem, const std::vector<RestMeanResidual>& rests,
               const std::shared_ptr<const DwellCorrelation>& corr, double* lower, double* offsets,
               std::vector<std::array<double, 3>>& directions, std::vector<double>& values) {
  const std::size_t n = rests.size();
  const std::size_t k = values.size();
  if (!corr) {
    for (std::size_t i = 0; i < n; ++i) {
      auto* cost =
          new ceres::DynamicAutoDiffCostFunction<RestMeanResidual, RestMeanResidual::kStride>(
              new RestMeanResidual(rests[i]));
      cost->AddParameterBlock(6);
      cost->AddParameterBlock(3);
      cost->AddParameterBlock(3);
      for (std::size_t j = 0; j < k; ++j) cost->AddParameterBlock(1);
      cost->SetNumResiduals(3);
      std::vector<double*> blocks{lower, offsets, directions[i].data()};
      for (std::size_t j = 0; j < k; ++j) blocks.push_back(&values[j]);
      problem.AddResidualBlock(cost, nullptr, blocks);
      problem.SetManifold(directions[i].data(), new ceres::SphereManifold<3>());
    }
    return;
  }
  auto* cost =
      new ceres::DynamicAutoDiffCostFunction<WhitenedRestMeans, WhitenedRestMeans::kStride>(
          new WhitenedRestMeans(rests, corr, k));
  cost->AddParameterBlock(6);
  cost->AddParameterBlock(3);
  for (std::size_t i = 0; i < n; ++i) cost->AddParameterBlock(3);
  for (std::size_t j = 0; j < k; ++j) cost->AddParameterBlock(1);
  cost->SetNumResiduals(3 * static_cast<int>(n));
  std::vector<double*> blocks{lower, offsets};
  for (std::size_t i = 0; i < n; ++i) blocks.push_back(directions[i].data());
  for (std::size_t j = 0; j < k; ++j) blocks.push_back(&values[j]);
  problem.AddResidualBlock(cost, nullptr, blocks);
  for (std::size_t i = 0; i < n; ++i)
    problem.SetManifold(directions[i].data(), new ceres::SphereManifold<3>());
}

}  // namespace

FitResult fit_tumble_with_effects(const PositionTable& table, const std::vector<Effect>& effects,
                                  double g, const NoiseModel& noise_model) {
  TumbleFitOptions base_options;
  base_options.local_gravity = g;
  base_options.noise_model = noise_model;
  const FitResult start = fit_tumble(table, base_options);
  const std::size_t n = table.rows.size();
  const std::size_t k = effects.size();
  const std::vector<Eigen::Vector3d> se = dwell_standard_errors(table);
  const bool unit_weights = !has_usable_std(table);
  // Null when white (or without a usable std, as the tumble fit).
  const std::shared_ptr<const DwellCorrelation> corr =
      unit_weights ? nullptr : dwell_correlation(table, se, noise_model);
  const double t0 = effective_time_origin(table);
  const double t_ref = reference_temperature_c(table);

  std::array<double, 6> lower;
  for (int j = 0; j < 6; ++j) lower[j] = start.S(kLowerIndex[j] / 3, kLowerIndex[j] % 3);
  std::array<double, 3> offsets{{start.O(0), start.O(1), start.O(2)}};
  std::vector<std::array<double, 3>> directions(n);
  const std::vector<Eigen::Vector3d> ups = rest_up_directions(start, table);
  for (std::size_t i = 0; i < n; ++i) directions[i] = {ups[i](0), ups[i](1), ups[i](2)};
  std::vector<double> values(k);
  for (std::size_t j = 0; j < k; ++j) values[j] = effects[j].value;

  auto terms = std::make_shared<const std::vector<Effect>>(effects);
  std::vector<RestMeanResidual> rests;
  rests.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const DwellGeometry geom = dwell_inputs(table.rows[i], t0, +1, t_ref);
    const Eigen::Vector3d weight = unit_weights ? Eigen::Vector3d::Ones() : se[i];
    rests.emplace_back(terms, geom, table.rows[i].mean, weight, g);
  }
  ceres::Problem problem;
  add_rests(problem, rests, corr, lower.data(), offsets.data(), directions, values);
  ceres::Solver::Options solver;
  // One residual block under GLS: nothing for the Schur complement to eliminate.
  solver.linear_solver_type = corr ? ceres::DENSE_QR : ceres::DENSE_SCHUR;
  solver.max_num_iterations = 200;
  solver.function_tolerance = 1e-14;
  solver.gradient_tolerance = 1e-14;
  solver.parameter_tolerance = 1e-12;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  if (!summary.IsSolutionUsable())
    throw FitError("tumble with effects: the solver failed: " + summary.BriefReport());

  // Covariance of (S lower, O, effects) with the directions profiled out: Ceres' Jacobian is in
  // each block's tangent space (2 columns for a direction on the sphere); the global block of the
  // inverse normal matrix is the answer.
  // The columns in an order of our own: S lower, O, the effects, then the directions.
  ceres::Problem::EvaluateOptions evaluate;
  evaluate.parameter_blocks = {lower.data(), offsets.data()};
  for (std::size_t j = 0; j < k; ++j) evaluate.parameter_blocks.push_back(&values[j]);
  for (std::size_t i = 0; i < n; ++i) evaluate.parameter_blocks.push_back(directions[i].data());
  ceres::CRSMatrix crs;
  double cost = 0.0;
  std::vector<double> residuals;
  problem.Evaluate(evaluate, &cost, &residuals, nullptr, &crs);
  const int globals = 9 + static_cast<int>(k);
  const int cols = globals + 2 * static_cast<int>(n);
  if (crs.num_cols != cols)
    throw FitError("tumble with effects: unexpected Jacobian layout (" +
                   std::to_string(crs.num_cols) + " columns, expected " + std::to_string(cols) +
                   ")");
  Eigen::MatrixXd Jt = Eigen::MatrixXd::Zero(crs.num_rows, cols);
  for (int r = 0; r < crs.num_rows; ++r)
    for (int idx = crs.rows[r]; idx < crs.rows[r + 1]; ++idx)
      Jt(r, crs.cols[idx]) = crs.values[idx];
  const Eigen::MatrixXd N = Jt.transpose() * Jt;
  const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(N);
  if (cod.rank() < cols)
    throw FitError("tumble with effects: the rests do not determine the parameters together");
  const Eigen::MatrixXd inverse = cod.pseudoInverse();

  FitResult r;
  r.model = FitModel::Tumble;
  r.local_gravity = g;
  r.S.setZero();
  for (int j = 0; j < 6; ++j) r.S(kLowerIndex[j] / 3, kLowerIndex[j] % 3) = lower[j];
  r.O = Eigen::Vector3d(offsets[0], offsets[1], offsets[2]);
  r.chi2 = 2.0 * cost;
  r.dof = static_cast<int>(3 * n) - cols;
  r.reduced_chi2 = r.dof > 0 ? r.chi2 / r.dof : 0.0;
  const double scale = unit_weights ? r.reduced_chi2 : std::max(1.0, r.reduced_chi2);
  Eigen::Matrix<double, 12, 12> full = Eigen::Matrix<double, 12, 12>::Zero();
  auto global_index = [](int a) { return a < 6 ? kLowerIndex[a] : 9 + (a - 6); };
  for (int a = 0; a < 9; ++a)
    for (int b = 0; b < 9; ++b) full(global_index(a), global_index(b)) = inverse(a, b) * scale;
  finish_result(r, full);
  r.effects = effects;
  r.effects_std.resize(k);
  for (std::size_t j = 0; j < k; ++j) {
    r.effects[j].value = values[j];
    r.effects_std[j] = std::sqrt(std::max(0.0, inverse(9 + j, 9 + j) * scale));
  }
  r.standard_errors = se;
  if (corr) {
    r.noise_model = noise_model;
    r.correlation = corr;  // chi2 is the whitened one
    residuals = unwhitened(*corr, residuals);
  }
  r.residuals.resize(n);
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d weight = unit_weights ? Eigen::Vector3d::Ones() : se[i];
    r.residuals[i] = -Eigen::Map<const Eigen::Vector3d>(&residuals[3 * i]).cwiseProduct(weight);
    sum_sq += r.residuals[i].squaredNorm();
  }
  r.residual_rms = n > 0 ? std::sqrt(sum_sq / (3.0 * n)) : 0.0;
  for (int p = 0; p < 3; ++p) {
    r.offset_per_phase.col(p) = r.O;
    r.offset_per_phase_std.col(p) = r.O_std;
  }
  r.positions = {{0, 0, 0}};
  r.solver_message = summary.BriefReport();
  return r;
}

TumbleAnalysis analyze_tumble(const PositionTable& table, const TumbleAnalysisOptions& options) {
  TumbleAnalysis out;
  // Noise that is not white: every fit is GLS across the rests, as the tumble fit (tumble.h), so
  // the tests judge the gap against the noise the rests have, correlations included.
  const NoiseModel& noise = options.noise_model;
  std::vector<Effect> candidates;
  for (const char* name : {"quadratic_nonlinearity", "cubic_nonlinearity", "offset_drift"})
    for (const char* target : {"u", "v", "w"}) candidates.push_back(make_effect(name, target));
  const TemperatureCoverage temperature =
      temperature_coverage(table, options.min_temperature_span_k);
  if (temperature.screenable) {
    for (const char* name : {"offset_temperature_coefficient", "scale_temperature_coefficient"})
      for (const char* target : {"u", "v", "w"}) candidates.push_back(make_effect(name, target));
  } else {
    out.not_screened.push_back("offset_temperature_coefficient, scale_temperature_coefficient: " +
                               temperature.reason);
  }
  out.not_screened.push_back(
      "angle_offset, angle_scale, axis_tilt, backlash: gimbal effects; a hand tumble has no "
      "gimbal angles to err");
  out.not_screened.push_back("timing_lag: needs commanded moves (a gimbal run's raw streams)");

  std::vector<Effect> named;
  out.before = fit_tumble_with_effects(table, named, options.local_gravity, noise);
  out.after = out.before;
  for (int step = 0; step < options.max_effects; ++step) {
    std::vector<TumbleEffectTest> tests;
    for (const Effect& candidate : candidates) {
      bool taken = false;
      for (const Effect& e : named)
        taken |= e.kind == candidate.kind && e.target == candidate.target;
      if (taken) continue;
      std::vector<Effect> trial = named;
      trial.push_back(candidate);
      TumbleEffectTest t;
      t.effect = candidate;
      try {
        const FitResult refit = fit_tumble_with_effects(table, trial, options.local_gravity, noise);
        t.effect.value = refit.effects.back().value;
        t.std = refit.effects_std.back();
        t.delta_chi2 = std::max(0.0, out.after.chi2 - refit.chi2);
        t.statistic = refit.reduced_chi2 > 1.0 ? t.delta_chi2 / refit.reduced_chi2 : t.delta_chi2;
        t.p_raw = p_value(t.statistic, refit.reduced_chi2, refit.dof);
      } catch (const FitError&) {
        t.p_raw = 1.0;  // not identifiable with the rests at hand
      }
      tests.push_back(t);
    }
    if (tests.empty()) break;
    // Holm: the j-th smallest p times (m - j), running maximum.
    std::sort(tests.begin(), tests.end(), [](const TumbleEffectTest& a, const TumbleEffectTest& b) {
      return a.p_raw < b.p_raw;
    });
    double running = 0.0;
    for (std::size_t j = 0; j < tests.size(); ++j) {
      running = std::max(running, std::min(1.0, (tests.size() - j) * tests[j].p_raw));
      tests[j].p_holm = running;
    }
    out.steps.push_back(tests);
    if (tests.front().p_holm > options.alpha) {
      out.stop_reason = "no remaining candidate is significant at alpha " +
                        std::to_string(options.alpha) + " (Holm)";
      break;
    }
    named.push_back(tests.front().effect);
    out.named.push_back(tests.front());
    out.after = fit_tumble_with_effects(table, named, options.local_gravity, noise);
  }
  if (out.stop_reason.empty()) out.stop_reason = "max_effects reached";
  out.noise_model = options.noise_model;
  out.before.noise_model = options.noise_model;
  out.after.noise_model = options.noise_model;
  return out;
}

}  // namespace core
}  // namespace accel_intrinsics
