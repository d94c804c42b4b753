#include "accel_intrinsics/core/noise/slow_part_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <vector>

namespace accel_intrinsics {
namespace core {

namespace {

// Restricted log-likelihood of w ~ N(0, I + a diag(lambda)), w in the eigenbasis of the
// (whitened) projected kernel (w2 = squared components), up to a constant.
double restricted_log_likelihood(double a, const Eigen::VectorXd& lambda,
                                 const Eigen::VectorXd& w2) {
  double l = 0.0;
  for (Eigen::Index i = 0; i < lambda.size(); ++i) {
    const double v = 1.0 + a * lambda(i);
    l -= 0.5 * (std::log(v) + w2(i) / v);
  }
  return l;
}

// The expected (Fisher) information about a of the same likelihood.
double amplitude_information(double a, const Eigen::VectorXd& lambda) {
  double info = 0.0;
  for (Eigen::Index i = 0; i < lambda.size(); ++i) {
    const double q = lambda(i) / (1.0 + a * lambda(i));
    info += 0.5 * q * q;
  }
  return info;
}

}  // namespace

std::vector<AxisNoiseModel> slow_part_shapes(double span_s, const AxisNoiseModel& rest_axis) {
  std::vector<AxisNoiseModel> shapes;
  for (double tau = 0.5; tau <= 5.0 * span_s; tau *= std::pow(10.0, 0.2))
    shapes.push_back(AxisNoiseModel{0.0, 1.0, tau, 0.0});
  shapes.push_back(AxisNoiseModel{0.0, 0.0, 0.0, 1.0});
  AxisNoiseModel own = rest_axis;
  own.white_std = 0.0;
  if (own.slow()) shapes.push_back(own);
  return shapes;
}

Eigen::MatrixXd residual_complement(const Eigen::MatrixXd& X) {
  const Eigen::Index n = X.rows();
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(X);
  const Eigen::Index rank = qr.rank();
  const Eigen::MatrixXd full_q = qr.householderQ() * Eigen::MatrixXd::Identity(n, n);
  return full_q.rightCols(n - rank);
}

SlowAmplitude best_slow_amplitude(const Eigen::VectorXd& w_in, const Eigen::MatrixXd& M_in,
                                  const Eigen::MatrixXd& base_L) {
  // Against a base B = L L^T: w -> L^-1 w, M -> L^-1 M L^-T turns B + a M into I + a M'.
  Eigen::VectorXd w = w_in;
  Eigen::MatrixXd M = M_in;
  if (base_L.size() > 0) {
    base_L.triangularView<Eigen::Lower>().solveInPlace(w);
    base_L.triangularView<Eigen::Lower>().solveInPlace(M);
    Eigen::MatrixXd Mt = M.transpose();
    base_L.triangularView<Eigen::Lower>().solveInPlace(Mt);
    M = 0.5 * (Mt + Mt.transpose());
  }
  SlowAmplitude best;
  best.log_likelihood = -std::numeric_limits<double>::infinity();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(M);
  if (eig.info() != Eigen::Success) return best;
  const Eigen::VectorXd lambda = eig.eigenvalues().cwiseMax(0.0);
  const Eigen::VectorXd w2 = (eig.eigenvectors().transpose() * w).cwiseAbs2();
  best.log_likelihood = restricted_log_likelihood(0.0, lambda, w2);
  const double mean = lambda.size() > 0 ? lambda.mean() : 0.0;
  if (!(mean > 0.0)) return best;
  // A logarithmic grid over twelve decades around 1 / mean eigenvalue, 24 per decade: the
  // likelihood's maximum (to compare shapes) and the posterior moments of a under Jeffreys'
  // prior sqrt(I(a)) (proper at a = 0, scale-free above), integrated in log a.
  const int points = 289;
  std::vector<double> log_a(points), l(points);
  for (int k = 0; k < points; ++k) {
    log_a[k] = std::log(1.0 / mean) + std::log(10.0) * (-6.0 + 12.0 * k / (points - 1));
    l[k] = restricted_log_likelihood(std::exp(log_a[k]), lambda, w2);
    best.log_likelihood = std::max(best.log_likelihood, l[k]);
  }
  double mass = 0.0, first = 0.0, second = 0.0;
  for (int k = 0; k < points; ++k) {
    const double a = std::exp(log_a[k]);
    const double weight = std::exp(l[k] - best.log_likelihood) *
                          std::sqrt(amplitude_information(a, lambda)) * a;  // da = a d(log a)
    mass += weight;
    first += weight * a;
    second += weight * a * a;
  }
  if (!(mass > 0.0) || !(first > 0.0)) return best;
  best.amplitude = first / mass;
  best.relative_variance = std::max(0.0, second / mass - best.amplitude * best.amplitude) /
                           (best.amplitude * best.amplitude);
  return best;
}

SlowShapeChoice choose_slow_shape(const Eigen::VectorXd& w,
                                  const std::vector<Eigen::MatrixXd>& projected_kernels,
                                  const std::vector<AxisNoiseModel>& shapes,
                                  const Eigen::MatrixXd& base_L) {
  SlowShapeChoice best;
  best.fit.log_likelihood = -std::numeric_limits<double>::infinity();
  int walk = -1;
  SlowAmplitude walk_fit;
  for (std::size_t c = 0; c < shapes.size(); ++c) {
    const SlowAmplitude f = best_slow_amplitude(w, projected_kernels[c], base_L);
    if (f.log_likelihood > best.fit.log_likelihood) {
      best.fit = f;
      best.shape = f.amplitude > 0.0 ? static_cast<int>(c) : -1;
    }
    if (walk < 0 && shapes[c].rw_density > 0.0 && shapes[c].gm_sigma == 0.0) {
      walk = static_cast<int>(c);
      walk_fit = f;
    }
  }
  if (walk >= 0 && walk_fit.amplitude > 0.0 &&
      walk_fit.log_likelihood >= best.fit.log_likelihood - kWalkLikelihoodMargin) {
    best.shape = walk;
    best.fit = walk_fit;
  }
  return best;
}

RunSpan run_span(const PositionTable& table) {
  RunSpan span;
  if (table.rows.empty()) return span;
  span.t_first = table.rows.front().t_start_s;
  span.t_last = table.rows.front().t_end_s;
  for (const DwellRecord& r : table.rows) {
    span.t_first = std::min(span.t_first, r.t_start_s);
    span.t_last = std::max(span.t_last, r.t_end_s);
  }
  return span;
}

std::string slow_part_note(const std::string& fitted_to, const NoiseModel& model) {
  std::ostringstream note;
  note << std::setprecision(3) << "; slow part fitted to " << fitted_to
       << " (restricted likelihood: the shape of highest likelihood among Gauss-Markov times, a "
          "random walk and the rest's own, its amplitude's posterior mean, the scale's relative "
          "standard deviation in brackets; in the outputs' unit):";
  for (int s = 0; s < 3; ++s) {
    // Only the parts there are: no "Gauss-Markov 0 over 0 s".
    const AxisNoiseModel& axis = model.axes[s];
    note << (s > 0 ? ";" : "") << " "
         << "uvw"[s] << ":";
    if (!axis.slow()) note << " no slow part";
    if (axis.gm_sigma > 0.0)
      note << " Gauss-Markov " << axis.gm_sigma << " over " << axis.gm_tau_s << " s";
    if (axis.gm_sigma > 0.0 && axis.rw_density > 0.0) note << ",";
    if (axis.rw_density > 0.0) note << " random walk " << axis.rw_density << " per sqrt(s)";
    if (axis.slow()) note << " [" << std::sqrt(axis.slow_scale_rel_var) << "]";
  }
  return note.str();
}

AxisNoiseModel scaled_shape(const AxisNoiseModel& shape, const SlowAmplitude& fitted) {
  AxisNoiseModel axis;
  const double amplitude = fitted.amplitude;
  if (!(amplitude > 0.0)) return axis;
  axis.slow_scale_rel_var = fitted.relative_variance;
  const double c = std::sqrt(amplitude);
  axis.gm_sigma = shape.gm_sigma * c;
  axis.gm_tau_s = axis.gm_sigma > 0.0 ? shape.gm_tau_s : 0.0;
  axis.rw_density = shape.rw_density * c;
  return axis;
}

}  // namespace core
}  // namespace accel_intrinsics
