// The slow part of the noise refitted to a gimbal run's dwell means (slow_part_fit.h
// slow_part_from_residuals; the fit and its Jacobian come from discrepancy.h slow_part_from_run).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "accel_intrinsics/core/noise/slow_part_fit.h"

namespace accel_intrinsics {
namespace core {

NoiseModel slow_part_from_residuals(const PositionTable& table, NoiseModel model,
                                    const std::vector<Eigen::Vector3d>& residuals,
                                    const std::vector<Eigen::Vector3d>& se,
                                    const Eigen::MatrixXd& J) {
  const std::size_t rows = table.rows.size();
  const int p = static_cast<int>(J.cols());
  const RunSpan run = run_span(table);
  const double t_first = run.t_first;
  const double span = std::max(run.length(), 1.0);
  // The observations of the likelihood: every dwell mean, but the long rest, when the model
  // carries its blocks, stands as its blocks (each against the fit's prediction for the rest's
  // position): they show how the slow part grows over the rest's seconds to minutes, which the
  // 2 s dwells, whose level the fit absorbs, barely see. Measured (seeds 900..959, random walk):
  // the offsets' RMS z-score 1.26 without the blocks, 0.91 with them; effect-free Gauss-Markov
  // runs naming an effect 3 -> 1 of 160. (Tried when the amplitude was the likelihood's maximum:
  // false alarms 3 -> 10 of 160, not kept then.)
  const std::vector<DwellRecord>& blocks = model.rest_blocks;
  std::optional<std::size_t> rest_row;
  if (blocks.size() >= 4) {
    for (std::size_t i = 0; i < rows; ++i) {
      const DwellRecord& r = table.rows[i];
      if (blocks.front().t_start_s >= r.t_start_s - 1e-6 &&
          blocks.back().t_end_s <= r.t_end_s + 1e-6) {
        rest_row = i;
        break;
      }
    }
  }
  struct Observation {
    double t0, t1;
    std::size_t row;  // the table row whose prediction and Jacobian it shares
    const DwellRecord* record;
  };
  std::vector<Observation> obs;
  for (std::size_t i = 0; i < rows; ++i) {
    if (rest_row && i == *rest_row) {
      for (const DwellRecord& b : blocks) obs.push_back({b.t_start_s, b.t_end_s, i, &b});
    } else {
      obs.push_back({table.rows[i].t_start_s, table.rows[i].t_end_s, i, &table.rows[i]});
    }
  }
  const Eigen::Index n = static_cast<Eigen::Index>(obs.size());
  for (int s = 0; s < 3; ++s) {
    // Axis s: normalized residuals and the Jacobian's rows of this accelerometer.
    Eigen::VectorXd z(n), se_obs(n);
    Eigen::MatrixXd X(n, p);
    bool usable = true;
    for (Eigen::Index i = 0; i < n; ++i) {
      const Observation& o = obs[static_cast<std::size_t>(i)];
      const double se_row = se[o.row](s);
      const double prediction = table.rows[o.row].mean(s) - residuals[o.row](s);
      const double se_o = o.record == &table.rows[o.row]
                              ? se_row
                              : o.record->std(s) / std::sqrt(static_cast<double>(o.record->n));
      if (!(se_o > 0.0)) usable = false;
      se_obs(i) = se_o;
      z(i) = (o.record->mean(s) - prediction) / se_o;
      X.row(i) = J.row(3 * static_cast<Eigen::Index>(o.row) + s) * (se_row / se_o);
    }
    if (!usable) continue;
    const Eigen::MatrixXd U = residual_complement(X);
    if (U.cols() < 4) continue;
    const Eigen::VectorXd w = U.transpose() * z;
    const std::vector<AxisNoiseModel> shapes = slow_part_shapes(span, model.axes[s]);
    std::vector<Eigen::MatrixXd> kernels;
    for (const AxisNoiseModel& shape : shapes) {
      NoiseModel unit;
      unit.axes[s] = shape;
      Eigen::MatrixXd K(n, n);
      for (Eigen::Index i = 0; i < n; ++i) {
        const Observation& a = obs[static_cast<std::size_t>(i)];
        for (Eigen::Index j = 0; j <= i; ++j) {
          const Observation& b = obs[static_cast<std::size_t>(j)];
          K(i, j) = K(j, i) =
              unit.slow_covariance(s, a.t0, a.t1, b.t0, b.t1, t_first) / (se_obs(i) * se_obs(j));
        }
      }
      kernels.push_back(U.transpose() * K * U);
    }
    const SlowShapeChoice choice = choose_slow_shape(w, kernels, shapes);
    AxisNoiseModel& axis = model.axes[s];
    const AxisNoiseModel slow =
        choice.shape >= 0 ? scaled_shape(shapes[static_cast<std::size_t>(choice.shape)], choice.fit)
                          : AxisNoiseModel();
    axis.gm_sigma = slow.gm_sigma;
    axis.gm_tau_s = slow.gm_tau_s;
    axis.rw_density = slow.rw_density;
    axis.slow_scale_rel_var = slow.slow_scale_rel_var;
  }
  model.source += slow_part_note(rest_row ? "the run's dwell means and the long rest's " +
                                                std::to_string(blocks.size()) + " blocks"
                                          : std::string("the run's dwell means"),
                                 model);
  return model;
}

}  // namespace core
}  // namespace accel_intrinsics
