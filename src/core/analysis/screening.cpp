// Screening of the candidate effects at the current fit (discrepancy.h, steps 3 and 4 of
// analyze()): score tests on the model's Jacobian, the step-down max-T calibration, the default
// candidates and the detection thresholds.
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
#include "accel_intrinsics/core/fit/preconditions.h"
#include "discrepancy_internal.h"

namespace accel_intrinsics {
namespace core {

namespace analysis_detail {

// ---- Jacobians of the one model (predict_outputs) by forward-mode automatic differentiation ----

using Jet1 = ceres::Jet<double, 1>;

// Parameters: S row-major (0..8), O (9..11), values of `terms` (12..). Returns d(R)/d(param)
// for every row and accelerometer (index 3 row + s), divided by the standard error.
Eigen::VectorXd weighted_derivative(const std::vector<DwellGeometry>& geoms,
                                    const std::vector<Eigen::Vector3d>& se, const Device& device,
                                    const std::vector<Effect>& terms, int param, double g) {
  Jet1 S[9], O[3];
  for (int i = 0; i < 9; ++i) S[i] = Jet1(device.S(i / 3, i % 3));
  for (int i = 0; i < 3; ++i) O[i] = Jet1(device.O(i));
  std::vector<Jet1> values(terms.size());
  for (std::size_t i = 0; i < terms.size(); ++i) values[i] = Jet1(terms[i].value);
  if (param < 9) {
    S[param].v[0] = 1.0;
  } else if (param < 12) {
    O[param - 9].v[0] = 1.0;
  } else {
    values.at(static_cast<std::size_t>(param - 12)).v[0] = 1.0;
  }
  const Jet1* value_ptr = values.empty() ? nullptr : values.data();
  Eigen::VectorXd column(3 * static_cast<Eigen::Index>(geoms.size()));
  for (std::size_t r = 0; r < geoms.size(); ++r) {
    const Eigen::Matrix<Jet1, 3, 1> R = predict_outputs<Jet1>(S, O, terms, value_ptr, geoms[r], g);
    for (int s = 0; s < 3; ++s) column(3 * static_cast<Eigen::Index>(r) + s) = R(s).v[0] / se[r](s);
  }
  return column;
}

// Orthonormal basis of the column space of A (numerical rank).
Eigen::MatrixXd column_space(const Eigen::MatrixXd& A) {
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  const Eigen::Index rank = qr.rank();
  Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(A.rows(), rank);
  return Q;
}

Screening screen(const PositionTable& table, const std::vector<DwellGeometry>& geoms,
                 const FitResult& fit, const std::vector<Effect>& model_terms,
                 const std::vector<Effect>& candidates, const AnalysisOptions& options,
                 int step_number) {
  const double g = options.local_gravity;
  const std::vector<Eigen::Vector3d> se = weights_for(table, fit);
  Device device = device_from_fit(fit);
  // The model terms with their fitted values (same order as model_terms).
  std::vector<Effect> terms = model_terms;
  for (Effect& t : terms) {
    for (const Effect& f : device.effects) {
      if (same_term(t, f)) t.value = f.value;
    }
  }
  device.effects = terms;
  // With a noise model that has a slow part (GLS), residuals and Jacobians are whitened by the
  // fit's L^-1: the score statistics are then chi2(1) under correlated noise as under white.
  const std::shared_ptr<const DwellCorrelation>& corr = fit.correlation;
  Eigen::VectorXd z = normalized_residuals(twin_residuals(table, device, g), se);
  if (corr) corr->whiten(z);
  const Eigen::Index n = z.size();
  const int p = 12 + static_cast<int>(terms.size());
  Eigen::MatrixXd A(n, p);
  for (int j = 0; j < p; ++j) A.col(j) = weighted_derivative(geoms, se, device, terms, j, g);
  if (corr) corr->whiten_columns(A);
  const Eigen::MatrixXd Q = column_space(A);

  Screening out;
  out.step.model = fit.model_label();
  std::vector<CandidateScore> scores;
  std::vector<Eigen::VectorXd> dirs;
  for (const Effect& c : candidates) {
    CandidateScore cs;
    cs.effect = c;
    cs.effect.value = 0.0;
    std::vector<Effect> with = terms;
    Effect zero = c;
    zero.value = 0.0;
    with.push_back(zero);
    Eigen::VectorXd b = weighted_derivative(geoms, se, device, with, p, g);
    if (corr) corr->whiten(b);
    const Eigen::VectorXd b_perp = b - Q * (Q.transpose() * b);
    const double bb = b.squaredNorm();
    const double pp = b_perp.squaredNorm();
    cs.information_ratio = bb > 0.0 ? pp / bb : 0.0;
    cs.identifiable =
        bb > 0.0 && std::isfinite(pp) && cs.information_ratio >= options.identifiability_floor;
    if (cs.identifiable) {
      const double dot = b_perp.dot(z);
      cs.score_chi2 = dot * dot / pp;
      cs.effect.value = dot / pp;
      cs.estimate_std = 1.0 / std::sqrt(pp);
      cs.p_raw = std::erfc(std::sqrt(0.5 * cs.score_chi2));
      dirs.push_back(b_perp / std::sqrt(pp));
    } else {
      dirs.emplace_back();
    }
    scores.push_back(cs);
  }
  // Strongest first (identifiable before unidentifiable).
  std::vector<std::size_t> order(scores.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (scores[a].identifiable != scores[b].identifiable) return scores[a].identifiable;
    return scores[a].score_chi2 > scores[b].score_chi2;
  });
  std::vector<int> ident;
  for (std::size_t k = 0; k < order.size(); ++k) {
    out.step.candidates.push_back(scores[order[k]]);
    out.directions.push_back(dirs[order[k]]);
    out.identifiable_index.push_back(scores[order[k]].identifiable ? static_cast<int>(ident.size())
                                                                   : -1);
    if (scores[order[k]].identifiable) ident.push_back(static_cast<int>(k));
  }
  const int m = static_cast<int>(ident.size());
  out.correlation = Eigen::MatrixXd::Identity(m, m);
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < i; ++j) {
      const double c = out.directions[ident[i]].dot(out.directions[ident[j]]);
      out.correlation(i, j) = out.correlation(j, i) = c;
    }
  }
  if (m == 0) return out;

  // Holm on the chi2(1) p-values (already in descending T = ascending p order).
  double running = 0.0;
  for (int k = 0; k < m; ++k) {
    CandidateScore& cs = out.step.candidates[ident[k]];
    running = std::max(running, std::min(1.0, cs.p_raw * (m - k)));
    cs.p_holm = running;
  }

  // Step-down max-T, calibrated by Monte Carlo: under "no effect" the score vector
  // (q_c . z)_c is N(0, C) with C the correlation of the directions (linearized model).
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(out.correlation);
  const Eigen::VectorXd lambda = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  const Eigen::MatrixXd L = eig.eigenvectors() * lambda.asDiagonal();
  std::mt19937_64 rng(options.seed + 7919u * static_cast<std::uint64_t>(step_number));
  std::normal_distribution<double> normal(0.0, 1.0);
  const int draws = options.monte_carlo_draws;
  std::vector<long> exceed(m, 0);
  std::vector<double> first_stage_max(draws);
  Eigen::VectorXd xi(m), w(m);
  std::vector<double> suffix(m);
  for (int d = 0; d < draws; ++d) {
    for (int i = 0; i < m; ++i) xi(i) = normal(rng);
    w = L * xi;
    double mx = 0.0;
    for (int k = m - 1; k >= 0; --k) {
      mx = std::max(mx, w(k) * w(k));
      suffix[k] = mx;
    }
    first_stage_max[d] = suffix[0];
    for (int k = 0; k < m; ++k) {
      if (suffix[k] >= out.step.candidates[ident[k]].score_chi2) ++exceed[k];
    }
  }
  running = 0.0;
  for (int k = 0; k < m; ++k) {
    CandidateScore& cs = out.step.candidates[ident[k]];
    running = std::max(running, (exceed[k] + 1.0) / (draws + 1.0));
    // The Monte Carlo resolves p down to 1 / (draws + 1); below that, Holm's chi2(1) bound (valid,
    // conservative) gives the finer figure.
    cs.p_adjusted = exceed[k] == 0 ? std::min(running, cs.p_holm) : running;
  }
  const std::size_t q =
      std::min<std::size_t>(first_stage_max.size() - 1,
                            static_cast<std::size_t>(std::ceil((1.0 - options.alpha) * draws)) - 1);
  std::nth_element(first_stage_max.begin(), first_stage_max.begin() + static_cast<long>(q),
                   first_stage_max.end());
  out.step.critical_chi2 = first_stage_max[q];
  const double lambda90 = noncentrality_for_power(out.step.critical_chi2, options.detection_power);
  for (int k = 0; k < m; ++k) {
    CandidateScore& cs = out.step.candidates[ident[k]];
    cs.detection_threshold = std::sqrt(lambda90) * cs.estimate_std;
  }
  return out;
}

double ambiguity_threshold_corr(const Screening& s, int a_row, int b_row) {
  return std::abs(s.correlation(a_row, b_row));
}

}  // namespace analysis_detail

using namespace analysis_detail;

std::vector<Effect> default_candidates(const PositionTable& table, double min_temperature_span_k) {
  const RunConditions run = run_conditions(table, dwell_geometries(table), min_temperature_span_k);
  std::vector<Effect> out;
  for (const EffectInfo& info : effect_catalog()) {
    for (int target : effect_targets(info.kind)) {
      const Effect effect{info.kind, target, 0.0};
      if (screenable(effect, run)) out.push_back(effect);
    }
  }
  return out;
}

double noncentrality_for_power(double critical_chi2, double power) {
  if (!(critical_chi2 > 0.0) || !(power > 0.0 && power < 1.0)) {
    throw std::invalid_argument(
        "noncentrality_for_power: need critical_chi2 > 0 and power in (0, 1)");
  }
  auto power_at = [&](double lambda) {
    if (lambda <= 0.0) return chi2_sf(critical_chi2, 1.0);
    boost::math::non_central_chi_squared_distribution<double> dist(1.0, lambda);
    return boost::math::cdf(boost::math::complement(dist, critical_chi2));
  };
  if (power_at(0.0) >= power) return 0.0;
  double lo = 0.0, hi = 1.0;
  while (power_at(hi) < power) hi *= 2.0;
  for (int i = 0; i < 200 && hi - lo > 1e-10 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (power_at(mid) < power ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace core
}  // namespace accel_intrinsics
