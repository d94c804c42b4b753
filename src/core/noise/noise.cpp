#include "accel_intrinsics/core/noise/noise.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace accel_intrinsics {
namespace core {

// ---- Noise that is not white -------------------------------------------------------------------

namespace {

// Shortest interval the covariance formulas take (a zero-length interval is a point; the closed
// forms below divide by the lengths).
constexpr double kMinInterval = 1e-3;

// Double integral of k(t - s) over t in [a0, a1], s in [b0, b1] from H with H'' = k:
// H(a1 - b0) - H(a0 - b0) - H(a1 - b1) + H(a0 - b1).
template <typename H>
double double_integral(double a0, double a1, double b0, double b1, H&& h) {
  return h(a1 - b0) - h(a0 - b0) - h(a1 - b1) + h(a0 - b1);
}

// Covariance of the means over two intervals of a unit-variance Gauss-Markov process of
// correlation time tau: H(x) = tau^2 exp(-|x| / tau) + tau |x|.
double gm_mean_covariance(double a0, double a1, double b0, double b1, double tau) {
  const double ta = a1 - a0, tb = b1 - b0;
  if (ta < 1e-3 * tau && tb < 1e-3 * tau)
    return std::exp(-std::abs(0.5 * (a0 + a1) - 0.5 * (b0 + b1)) / tau);
  const double v = double_integral(a0, a1, b0, b1, [tau](double x) {
    const double ax = std::abs(x);
    return tau * tau * std::exp(-ax / tau) + tau * ax;
  });
  return v / (ta * tb);
}

// Mean of min(t, s) - origin over the two intervals (a unit random walk from origin):
// min = (t + s - |t - s|) / 2, and the double integral of |t - s| from H(x) = |x|^3 / 6.
double rw_mean_covariance(double a0, double a1, double b0, double b1, double origin) {
  a0 = std::max(a0, origin);
  b0 = std::max(b0, origin);
  a1 = std::max(a1, a0 + kMinInterval);
  b1 = std::max(b1, b0 + kMinInterval);
  const double ta = a1 - a0, tb = b1 - b0;
  const double abs_mean = double_integral(a0, a1, b0, b1,
                                          [](double x) {
                                            const double ax = std::abs(x);
                                            return ax * ax * ax / 6.0;
                                          }) /
                          (ta * tb);
  return 0.5 * (0.5 * (a0 + a1) + 0.5 * (b0 + b1)) - origin - 0.5 * abs_mean;
}

// Allan variance of a unit-variance Gauss-Markov process at cluster time T: the variance of a
// cluster mean minus the covariance of two adjacent ones.
double gm_allan_variance(double T, double tau) {
  return gm_mean_covariance(0.0, T, 0.0, T, tau) - gm_mean_covariance(0.0, T, T, 2.0 * T, tau);
}

}  // namespace

bool NoiseModel::white() const {
  for (const AxisNoiseModel& a : axes)
    if (a.slow()) return false;
  return true;
}

std::string NoiseModel::kind() const {
  bool gm = false, rw = false;
  for (const AxisNoiseModel& a : axes) {
    gm = gm || (a.gm_sigma > 0.0 && a.gm_tau_s > 0.0);
    rw = rw || a.rw_density > 0.0;
  }
  if (gm && rw) return "gauss_markov+random_walk";
  if (gm) return "gauss_markov";
  if (rw) return "random_walk";
  return "white";
}

double NoiseModel::slow_covariance(int axis, double a0, double a1, double b0, double b1,
                                   double t_origin) const {
  const AxisNoiseModel& m = axes[axis];
  a1 = std::max(a1, a0 + kMinInterval);
  b1 = std::max(b1, b0 + kMinInterval);
  double c = 0.0;
  if (m.gm_sigma > 0.0 && m.gm_tau_s > 0.0)
    c += m.gm_sigma * m.gm_sigma * gm_mean_covariance(a0, a1, b0, b1, m.gm_tau_s);
  if (m.rw_density > 0.0)
    c += m.rw_density * m.rw_density * rw_mean_covariance(a0, a1, b0, b1, t_origin);
  return c;
}

double NoiseModel::variance_of_mean(int axis, double duration_s, double n) const {
  const AxisNoiseModel& m = axes[axis];
  const double white = n > 0.0 ? m.white_std * m.white_std / n : 0.0;
  return white + slow_covariance(axis, 0.0, duration_s, 0.0, duration_s, 0.0);
}

double NoiseModel::allan_variance(int axis, double tau_s) const {
  const AxisNoiseModel& m = axes[axis];
  double v = rate_hz > 0.0 ? m.white_std * m.white_std / (rate_hz * tau_s) : 0.0;
  if (m.gm_sigma > 0.0 && m.gm_tau_s > 0.0)
    v += m.gm_sigma * m.gm_sigma * gm_allan_variance(tau_s, m.gm_tau_s);
  v += m.rw_density * m.rw_density * tau_s / 3.0;
  return v;
}

NoiseModel white_noise_model(const Eigen::Vector3d& white_std, double rate_hz) {
  NoiseModel m;
  for (int s = 0; s < 3; ++s) m.axes[s].white_std = white_std(s);
  m.rate_hz = rate_hz;
  return m;
}

namespace {

// Non-negative weighted least squares of y on the three columns of A: the best of the subsets
// of columns whose solution is non-negative (7 subsets; A has 3 columns).
struct NonNegativeFit {
  Eigen::Vector3d coef = Eigen::Vector3d::Zero();
  double chi2 = std::numeric_limits<double>::infinity();
};

NonNegativeFit non_negative_fit(const Eigen::MatrixXd& A, const Eigen::VectorXd& y,
                                const Eigen::VectorXd& sigma) {
  NonNegativeFit best;
  for (int mask = 1; mask < 8; ++mask) {
    std::vector<int> cols;
    for (int j = 0; j < 3; ++j)
      if (mask & (1 << j)) cols.push_back(j);
    Eigen::MatrixXd Aw(A.rows(), static_cast<Eigen::Index>(cols.size()));
    for (std::size_t j = 0; j < cols.size(); ++j)
      Aw.col(static_cast<Eigen::Index>(j)) = A.col(cols[j]).cwiseQuotient(sigma);
    const Eigen::VectorXd yw = y.cwiseQuotient(sigma);
    const Eigen::VectorXd c = Aw.colPivHouseholderQr().solve(yw);
    if (!c.allFinite() || c.minCoeff() < 0.0) continue;
    const double chi2 = (Aw * c - yw).squaredNorm();
    if (chi2 < best.chi2) {
      best.chi2 = chi2;
      best.coef.setZero();
      for (std::size_t j = 0; j < cols.size(); ++j)
        best.coef(cols[j]) = c(static_cast<Eigen::Index>(j));
    }
  }
  return best;
}

}  // namespace

// The record's length checked before its curve is computed (both overloads).
static double checked_duration(std::size_t samples, double rate_hz) {
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz))
    throw std::invalid_argument("estimate_noise_model: the rate must be positive");
  const double duration = static_cast<double>(samples) / rate_hz;
  if (samples < 64 || duration < 10.0)
    throw std::invalid_argument("estimate_noise_model: the rest holds " + std::to_string(samples) +
                                " samples over " + std::to_string(duration) +
                                " s; at least 64 samples and 10 s are needed");
  return duration;
}

NoiseModel estimate_noise_model(const std::vector<Eigen::Vector3d>& samples, double rate_hz) {
  checked_duration(samples.size(), rate_hz);
  return estimate_noise_model(overlapping_allan_deviation(samples, rate_hz, 10));
}

NoiseModel estimate_noise_model(const AllanCurve& curve) {
  const double rate_hz = curve.rate_hz;
  const double duration = checked_duration(curve.samples, rate_hz);
  NoiseModel model;
  model.rate_hz = rate_hz;
  model.rest_samples = curve.samples;
  const std::size_t k = curve.tau_s.size();
  // Correlation times tried: 0.5 s to 5 times the record, 8 per decade.
  std::vector<double> taus;
  for (double t = 0.5; t <= 5.0 * duration; t *= std::pow(10.0, 1.0 / 8.0)) taus.push_back(t);
  for (int axis = 0; axis < 3; ++axis) {
    Eigen::VectorXd y(k), rel(k);
    for (std::size_t i = 0; i < k; ++i) {
      y(i) = curve.adev[i](axis) * curve.adev[i](axis);
      rel(i) = 2.0 * curve.relative_std[i];  // of a variance: twice that of the deviation
    }
    AxisNoiseModel best;
    double best_chi2 = std::numeric_limits<double>::infinity();
    for (double tau_c : taus) {
      Eigen::MatrixXd A(k, 3);
      for (std::size_t i = 0; i < k; ++i) {
        const double T = curve.tau_s[i];
        A(i, 0) = 1.0 / (rate_hz * T);
        A(i, 1) = gm_allan_variance(T, tau_c);
        A(i, 2) = T / 3.0;
      }
      // Weights from the model's own prediction (reweighted twice): weighting by the measured
      // points would favour the points that came out low and bias the slow part down.
      Eigen::VectorXd sigma = rel.cwiseProduct(y).cwiseMax(1e-300);
      NonNegativeFit f;
      for (int iteration = 0; iteration < 3; ++iteration) {
        f = non_negative_fit(A, y, sigma);
        if (!std::isfinite(f.chi2)) break;
        sigma = rel.cwiseProduct((A * f.coef).cwiseMax(1e-300));
      }
      if (!std::isfinite(f.chi2)) continue;
      // The final chi2 with the final weights.
      const double chi2 = ((A * f.coef - y).cwiseQuotient(sigma)).squaredNorm();
      if (chi2 < best_chi2) {
        best_chi2 = chi2;
        best.white_std = std::sqrt(f.coef(0));
        best.gm_sigma = std::sqrt(f.coef(1));
        best.gm_tau_s = f.coef(1) > 0.0 ? tau_c : 0.0;
        best.rw_density = std::sqrt(f.coef(2));
      }
    }
    model.axes[axis] = best;
  }
  return model;
}

void DwellCorrelation::whiten(Eigen::VectorXd& v) const {
  const Eigen::Index n = static_cast<Eigen::Index>(rows);
  Eigen::VectorXd part(n);
  for (int s = 0; s < 3; ++s) {
    for (Eigen::Index i = 0; i < n; ++i) part(i) = v(3 * i + s);
    L[s].triangularView<Eigen::Lower>().solveInPlace(part);
    for (Eigen::Index i = 0; i < n; ++i) v(3 * i + s) = part(i);
  }
}

void DwellCorrelation::whiten_columns(Eigen::MatrixXd& m) const {
  const Eigen::Index n = static_cast<Eigen::Index>(rows);
  Eigen::MatrixXd part(n, m.cols());
  for (int s = 0; s < 3; ++s) {
    for (Eigen::Index i = 0; i < n; ++i) part.row(i) = m.row(3 * i + s);
    L[s].triangularView<Eigen::Lower>().solveInPlace(part);
    for (Eigen::Index i = 0; i < n; ++i) m.row(3 * i + s) = part.row(i);
  }
}

std::shared_ptr<const DwellCorrelation> dwell_correlation(const PositionTable& table,
                                                          const std::vector<Eigen::Vector3d>& se,
                                                          const NoiseModel& model) {
  if (model.white() || table.rows.empty()) return nullptr;
  const std::size_t n = table.rows.size();
  auto out = std::make_shared<DwellCorrelation>();
  out->rows = n;
  double origin = table.rows.front().t_start_s;
  for (const DwellRecord& r : table.rows) origin = std::min(origin, r.t_start_s);
  for (int s = 0; s < 3; ++s) {
    Eigen::MatrixXd R =
        Eigen::MatrixXd::Identity(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
    if (model.axes[s].slow()) {
      for (std::size_t i = 0; i < n; ++i) {
        for (std::size_t j = 0; j <= i; ++j) {
          const DwellRecord& a = table.rows[i];
          const DwellRecord& b = table.rows[j];
          const double k =
              model.slow_covariance(s, a.t_start_s, a.t_end_s, b.t_start_s, b.t_end_s, origin) /
              (se[i](s) * se[j](s));
          R(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) += k;
          if (i != j) R(static_cast<Eigen::Index>(j), static_cast<Eigen::Index>(i)) += k;
        }
      }
    }
    Eigen::LLT<Eigen::MatrixXd> llt(R);
    if (llt.info() != Eigen::Success)
      throw std::runtime_error("dwell_correlation: the covariance of the dwell means of " +
                               std::string(1, "uvw"[s]) + " is not positive definite");
    out->L[s] = llt.matrixL();
  }
  return out;
}

bool has_estimated_scale(const NoiseModel& model) {
  for (const AxisNoiseModel& a : model.axes)
    if (a.slow() && a.slow_scale_rel_var > 0.0) return true;
  return false;
}

Eigen::MatrixXd estimated_scale_covariance(const NoiseModel& model, const DwellCorrelation& corr,
                                           const Eigen::MatrixXd& whitened_jacobian,
                                           const Eigen::MatrixXd& phi) {
  const Eigen::Index n = static_cast<Eigen::Index>(corr.rows);
  const Eigen::Index p = phi.rows();
  if (whitened_jacobian.rows() != 3 * n || whitened_jacobian.cols() != p || phi.cols() != p)
    throw std::invalid_argument("estimated_scale_covariance: the Jacobian is " +
                                std::to_string(whitened_jacobian.rows()) + " x " +
                                std::to_string(whitened_jacobian.cols()) + ", expected " +
                                std::to_string(3 * n) + " x " + std::to_string(p));
  Eigen::MatrixXd widening = Eigen::MatrixXd::Zero(p, p);
  for (int s = 0; s < 3; ++s) {
    const AxisNoiseModel& axis = model.axes[s];
    if (!axis.slow() || !(axis.slow_scale_rel_var > 0.0)) continue;
    Eigen::MatrixXd Js(n, p);
    for (Eigen::Index i = 0; i < n; ++i) Js.row(i) = whitened_jacobian.row(3 * i + s);
    // R = L L^T = I + slow part, so L^-1 (R - I) L^-T = I - L^-1 L^-T.
    Eigen::MatrixXd inverse_L = Eigen::MatrixXd::Identity(n, n);
    corr.L[s].triangularView<Eigen::Lower>().solveInPlace(inverse_L);
    Eigen::MatrixXd H = -inverse_L * inverse_L.transpose();
    H.diagonal().array() += 1.0;
    const Eigen::MatrixXd HJ = H * Js;
    const Eigen::MatrixXd P = Js.transpose() * HJ;
    const Eigen::MatrixXd Q = HJ.transpose() * HJ;
    widening += axis.slow_scale_rel_var * (Q - P * phi * P);
  }
  const Eigen::MatrixXd adjusted = phi + 2.0 * phi * widening * phi;
  return 0.5 * (adjusted + adjusted.transpose());
}

}  // namespace core
}  // namespace accel_intrinsics
