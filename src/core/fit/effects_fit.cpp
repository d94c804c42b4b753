// The joint fit with effect terms: Ceres on the one model (model.h predict_outputs), then
// generalized least squares for noise that is not white (conventions at the top of fit.cpp).
#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <memory>
#include <utility>

#include "accel_intrinsics/core/model/model.h"
#include "fit_internal.h"

namespace accel_intrinsics {
namespace core {

namespace {

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

void build_effects_problem(EffectsProblem& prob, const PreparedTable& table,
                           const std::vector<Eigen::Vector3d>& se, const FitOptions& options,
                           const LinearJoint& start) {
  for (int k = 0; k < 9; ++k) prob.S[k] = start.S(k / 3, k % 3);
  for (int s = 0; s < 3; ++s) prob.O[s] = start.O(s);
  prob.values.clear();
  for (const Effect& e : options.effects) prob.values.push_back(e.value);
  prob.blocks = {prob.S.data(), prob.O.data()};
  for (double& v : prob.values) prob.blocks.push_back(&v);
  auto terms = std::make_shared<const std::vector<Effect>>(options.effects);
  const std::vector<DwellGeometry>& geoms = table.geometries();
  for (std::size_t i = 0; i < table.size(); ++i) {
    prob.problem.AddResidualBlock(
        DwellMeanResidual::Create(terms, geoms[i], table.row(i).mean, se[i], options.local_gravity),
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

}  // namespace

FitResult fit_joint_effects(const PreparedTable& table, const FitWeights& weights,
                            const FitOptions& options) {
  const std::vector<Eigen::Vector3d>& se = weights.se;
  const std::shared_ptr<const DwellCorrelation>& corr = weights.corr;
  std::string label = "joint";
  for (const Effect& e : options.effects) label += "+" + e.label();
  const std::size_t k = options.effects.size();
  const int num_params = kNumLinear + static_cast<int>(k);
  if (3 * static_cast<int>(table.size()) <= num_params)
    throw FitError(label + " has " + std::to_string(num_params) + " parameters but only " +
                   std::to_string(3 * table.size()) + " dwell means");

  const LinearJoint start = solve_joint_linear(table, se, options.local_gravity);
  EffectsProblem prob;
  build_effects_problem(prob, table, se, options, start);
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
    return table.row(i).mean +
           Eigen::Vector3d(normalized(3 * i), normalized(3 * i + 1), normalized(3 * i + 2))
               .cwiseProduct(se[i]);
  });
  apply_correlation(r, corr);
  const Eigen::MatrixXd cov = cov_unscaled * chi2_scale(r, weights.unit_weights);
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

}  // namespace core
}  // namespace accel_intrinsics
