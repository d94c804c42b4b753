// The slow part of the noise refitted to a hand tumble's rests and the long rest's blocks
// (tumble.h slow_part_from_tumble; the likelihood machinery is noise/slow_part_fit.h).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <vector>

#include "accel_intrinsics/core/fit/tumble.h"
#include "accel_intrinsics/core/noise/slow_part_fit.h"
#include "tumble_internal.h"

namespace accel_intrinsics {
namespace core {

using namespace tumble_detail;

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
      Observation o{
          b.t_start_s, b.t_end_s, (b.mean(s) - level(s)) / se, Eigen::Vector3d::Zero(), {}};
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

}  // namespace core
}  // namespace accel_intrinsics
