// The gap between the measurements and the digital twin (discrepancy.h compute_gap), its
// cross-validated form, and the slow part refitted to the run's residuals.
#include <ceres/jet.h>

#include <Eigen/Dense>
#include <algorithm>
#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/non_central_chi_squared.hpp>
#include <cmath>
#include <iomanip>
#include <limits>
#include <numeric>
#include <optional>
#include <ostream>
#include <random>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/noise/slow_part_fit.h"
#include "discrepancy_internal.h"

namespace accel_intrinsics {
namespace core {

namespace analysis_detail {

// P(chi2(dof) >= x).
double chi2_sf(double x, double dof) {
  if (!(x > 0.0)) return 1.0;
  boost::math::chi_squared_distribution<double> dist(dof);
  return boost::math::cdf(boost::math::complement(dist, x));
}

double chi2_quantile(double p, double dof) {
  boost::math::chi_squared_distribution<double> dist(dof);
  return boost::math::quantile(dist, p);
}

// Standard errors of the dwell means, the weights of every fit.
std::vector<Eigen::Vector3d> weights_for(const PositionTable& table, const FitResult& fit) {
  if (fit.standard_errors.size() == table.rows.size()) return fit.standard_errors;
  return dwell_standard_errors(table);
}

// Normalized twin residuals z (index 3 row + s).
Eigen::VectorXd normalized_residuals(const std::vector<Eigen::Vector3d>& residuals,
                                     const std::vector<Eigen::Vector3d>& se) {
  Eigen::VectorXd z(3 * static_cast<Eigen::Index>(residuals.size()));
  for (std::size_t r = 0; r < residuals.size(); ++r) {
    for (int s = 0; s < 3; ++s)
      z(3 * static_cast<Eigen::Index>(r) + s) = residuals[r](s) / se[r](s);
  }
  return z;
}

GapSummary summarize(double chi2, int dof, double sum_sq, int n) {
  GapSummary g;
  g.chi2 = chi2;
  g.dof = dof;
  g.rms = n > 0 ? std::sqrt(sum_sq / n) : 0.0;
  if (dof > 0) {
    g.reduced_chi2 = chi2 / dof;
    g.p_value = chi2_sf(chi2, dof);
    g.band99_low = chi2_quantile(0.005, dof) / dof;
    g.band99_high = chi2_quantile(0.995, dof) / dof;
    g.consistent_with_noise = g.reduced_chi2 >= g.band99_low && g.reduced_chi2 <= g.band99_high;
  }
  return g;
}

}  // namespace analysis_detail

using namespace analysis_detail;

Device device_from_fit(const FitResult& fit) {
  Device d;
  d.S = fit.S;
  d.O = fit.O;
  d.effects = fit.effects;
  return d;
}

std::vector<Eigen::Vector3d> twin_residuals(const PositionTable& table, const Device& device,
                                            double local_gravity) {
  const std::vector<DwellGeometry> geoms = dwell_geometries(table);
  std::vector<Eigen::Vector3d> out(table.rows.size());
  for (std::size_t r = 0; r < table.rows.size(); ++r) {
    out[r] = table.rows[r].mean - predict_outputs(device, geoms[r], local_gravity);
  }
  return out;
}

Gap compute_gap(const PositionTable& table, const FitResult& fit, int harmonics, int time_bins) {
  const std::vector<DwellGeometry> geoms = dwell_geometries(table);
  const std::vector<Eigen::Vector3d> se = weights_for(table, fit);
  const std::vector<Eigen::Vector3d> res =
      twin_residuals(table, device_from_fit(fit), fit.local_gravity);
  // Normalized residuals; whitened by the fit's correlation when it used one (GLS), so that
  // every summary below is judged against unit-variance independent entries.
  std::vector<Eigen::Vector3d> zn(res.size());
  {
    Eigen::VectorXd z = normalized_residuals(res, se);
    if (fit.correlation && fit.correlation->rows == res.size()) fit.correlation->whiten(z);
    for (std::size_t r = 0; r < res.size(); ++r)
      zn[r] = z.segment<3>(3 * static_cast<Eigen::Index>(r));
  }
  Gap gap;
  double chi2 = 0.0, sum_sq = 0.0;
  for (std::size_t r = 0; r < res.size(); ++r) {
    for (int s = 0; s < 3; ++s) {
      const double zz = zn[r](s);
      chi2 += zz * zz;
      sum_sq += res[r](s) * res[r](s);
    }
  }
  const int n = 3 * static_cast<int>(res.size());
  const int dof = n - 12 - static_cast<int>(fit.effects.size());
  gap.summary = summarize(chi2, dof, sum_sq, n);

  // Phase x accelerometer cells with harmonic powers.
  for (int p = 0; p < 3; ++p) {
    std::vector<std::size_t> rows;
    for (std::size_t r = 0; r < geoms.size(); ++r) {
      if (index(geoms[r].phase) == p) rows.push_back(r);
    }
    for (int s = 0; s < 3; ++s) {
      CellGap cell;
      cell.phase = p;
      cell.accelerometer = s;
      cell.n = static_cast<int>(rows.size());
      Eigen::VectorXd zc(cell.n);
      double cell_sq = 0.0;
      for (int i = 0; i < cell.n; ++i) {
        const std::size_t r = rows[i];
        zc(i) = zn[r](s);
        cell_sq += res[r](s) * res[r](s);
      }
      cell.chi2 = zc.squaredNorm();
      cell.rms = cell.n > 0 ? std::sqrt(cell_sq / cell.n) : 0.0;
      for (int k = 0; k <= harmonics; ++k) {
        if (cell.n == 0) {
          cell.harmonic_power.push_back(0.0);
          continue;
        }
        Eigen::MatrixXd X(cell.n, k == 0 ? 1 : 2);
        for (int i = 0; i < cell.n; ++i) {
          const double a = geoms[rows[i]].angle_rad;
          if (k == 0) {
            X(i, 0) = 1.0;
          } else {
            X(i, 0) = std::cos(k * a);
            X(i, 1) = std::sin(k * a);
          }
        }
        // Explained sum of squares of the least-squares projection onto the harmonic.
        Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(X);
        const Eigen::VectorXd coef = cod.solve(zc);
        cell.harmonic_power.push_back((X * coef).squaredNorm());
      }
      gap.cells.push_back(cell);
    }
  }

  // Time bins and trends.
  if (!geoms.empty()) {
    double t_min = geoms.front().time_s, t_max = geoms.front().time_s;
    for (const DwellGeometry& g : geoms) {
      t_min = std::min(t_min, g.time_s);
      t_max = std::max(t_max, g.time_s);
    }
    const int bins = std::max(1, time_bins);
    const double width = (t_max - t_min) / bins;
    gap.time_bins.resize(bins);
    std::vector<double> bin_sq(bins, 0.0);
    for (int b = 0; b < bins; ++b) {
      gap.time_bins[b].t_begin_s = t_min + b * width;
      gap.time_bins[b].t_end_s = b + 1 == bins ? t_max : t_min + (b + 1) * width;
    }
    double t_mean = 0.0;
    for (const DwellGeometry& g : geoms) t_mean += g.time_s;
    t_mean /= static_cast<double>(geoms.size());
    double stt = 0.0;
    std::array<double, 3> stz{{0, 0, 0}};
    for (std::size_t r = 0; r < geoms.size(); ++r) {
      int b = width > 0.0 ? static_cast<int>((geoms[r].time_s - t_min) / width) : 0;
      b = std::min(std::max(b, 0), bins - 1);
      const double dt = geoms[r].time_s - t_mean;
      stt += dt * dt;
      for (int s = 0; s < 3; ++s) {
        const double zz = zn[r](s);
        gap.time_bins[b].chi2 += zz * zz;
        gap.time_bins[b].n += 1;
        bin_sq[b] += res[r](s) * res[r](s);
        stz[s] += dt * zz;
      }
    }
    for (int b = 0; b < bins; ++b) {
      gap.time_bins[b].rms =
          gap.time_bins[b].n > 0 ? std::sqrt(bin_sq[b] / gap.time_bins[b].n) : 0.0;
    }
    for (int s = 0; s < 3; ++s) gap.trend_z[s] = stt > 0.0 ? stz[s] / std::sqrt(stt) : 0.0;
  }
  return gap;
}

CrossValidatedGap cross_validated_gap(const PositionTable& table, const FitOptions& options,
                                      int folds) {
  CrossValidatedGap out;
  const std::size_t n = table.rows.size();
  if (folds < 2 || n < static_cast<std::size_t>(2 * folds)) return out;
  // The dwells in time order, cut into contiguous blocks of (nearly) equal count.
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  auto mid = [&](std::size_t i) { return 0.5 * (table.rows[i].t_start_s + table.rows[i].t_end_s); };
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return mid(a) < mid(b); });
  std::vector<int> fold_of(n);
  for (std::size_t k = 0; k < n; ++k)
    fold_of[order[k]] = static_cast<int>(k * static_cast<std::size_t>(folds) / n);
  // The model's inputs of every row from the whole run (approach, drift clock, temperature
  // reference), so a held-out row is predicted where the full run puts it.
  const std::vector<DwellGeometry> geoms = dwell_geometries(table);
  const std::vector<Eigen::Vector3d> se = dwell_standard_errors(table);
  const double origin = effective_time_origin(table);
  double t_first = table.rows.front().t_start_s;
  for (const DwellRecord& r : table.rows) t_first = std::min(t_first, r.t_start_s);
  double total = 0.0;
  for (int f = 0; f < folds; ++f) {
    PositionTable train;
    train.time_origin_s = origin;
    std::vector<std::size_t> test;
    for (std::size_t i = 0; i < n; ++i) {
      if (fold_of[i] == f) {
        test.push_back(i);
      } else {
        train.rows.push_back(table.rows[i]);
      }
    }
    FitResult fitted;
    try {
      fitted = fit(train, options);
    } catch (const std::exception&) {
      ++out.failed_folds;
      continue;
    }
    const Device device = device_from_fit(fitted);
    const Eigen::Index m = static_cast<Eigen::Index>(test.size());
    for (int s = 0; s < 3; ++s) {
      Eigen::VectorXd r(m);
      Eigen::MatrixXd C = Eigen::MatrixXd::Zero(m, m);
      for (Eigen::Index a = 0; a < m; ++a) {
        const std::size_t i = test[static_cast<std::size_t>(a)];
        r(a) = table.rows[i].mean(s) - predict_outputs(device, geoms[i], options.local_gravity)(s);
        C(a, a) = se[i](s) * se[i](s);
        if (options.noise_model.white()) continue;
        for (Eigen::Index b = 0; b <= a; ++b) {
          const DwellRecord& ra = table.rows[i];
          const DwellRecord& rb = table.rows[test[static_cast<std::size_t>(b)]];
          const double k = options.noise_model.slow_covariance(s, ra.t_start_s, ra.t_end_s,
                                                               rb.t_start_s, rb.t_end_s, t_first);
          C(a, b) += k;
          if (a != b) C(b, a) += k;
        }
      }
      total += r.dot(C.ldlt().solve(r));
    }
    ++out.folds;
    out.points += 3 * static_cast<int>(m);
  }
  if (out.points > 0) out.cv_chi2_per_point = total / out.points;
  return out;
}

NoiseModel slow_part_from_run(const PositionTable& table, const FitOptions& options) {
  NoiseModel model = options.noise_model;
  const std::size_t rows = table.rows.size();
  if (!model.slow_part_to_fit() || rows < 8) return model;
  // The residuals and the Jacobian of the base model, white-weighted: the restricted likelihood
  // depends on the data only through their part outside the Jacobian's column space, which is
  // the same for every fit in it.
  FitOptions white_options = options;
  white_options.noise_model = NoiseModel();
  const FitResult base = fit(table, white_options);
  const std::vector<Eigen::Vector3d> se = weights_for(table, base);
  const std::vector<DwellGeometry> geoms = dwell_geometries(table);
  const Device device = device_from_fit(base);
  // Only the base model is projected out, not the candidate effects: projecting out a drift
  // would also remove the slow noise's low-frequency part, which sets the offsets' uncertainty
  // (tried: the offsets' RMS z-score rose from 1.4 to 2.3 on the scenario). The price: a
  // real drift is partly taken for noise, which costs the screening power against drift.
  const int p = 12 + static_cast<int>(device.effects.size());
  Eigen::MatrixXd J(3 * static_cast<Eigen::Index>(rows), p);
  for (int j = 0; j < p; ++j)
    J.col(j) = weighted_derivative(geoms, se, device, device.effects, j, options.local_gravity);
  return slow_part_from_residuals(table, model, base.residuals, se, J);
}

}  // namespace core
}  // namespace accel_intrinsics
