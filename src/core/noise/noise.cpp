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
namespace {

// Cluster sizes about points_per_decade per decade, 1 .. max_m, each once.
std::vector<std::size_t> cluster_sizes(std::size_t max_m, int points_per_decade) {
  std::vector<std::size_t> out;
  for (int i = 0;; ++i) {
    const double m = std::round(std::pow(10.0, static_cast<double>(i) / points_per_decade));
    if (m > static_cast<double>(max_m)) break;
    const std::size_t mi = static_cast<std::size_t>(m);
    if (out.empty() || mi != out.back()) out.push_back(mi);
  }
  return out;
}

// Weighted least squares of y on the columns of A that `use` selects; returns the coefficients
// (zero where not used), their covariance and chi2.
struct LinearFit {
  Eigen::Vector3d coef = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  double chi2 = std::numeric_limits<double>::infinity();
};

LinearFit weighted_fit(const Eigen::MatrixXd& A, const Eigen::VectorXd& y,
                       const Eigen::VectorXd& sigma, const std::array<bool, 3>& use) {
  std::vector<int> cols;
  for (int j = 0; j < 3; ++j) {
    if (use[j]) cols.push_back(j);
  }
  const int k = static_cast<int>(cols.size());
  Eigen::MatrixXd Aw(A.rows(), k);
  for (int j = 0; j < k; ++j) Aw.col(j) = A.col(cols[j]).cwiseQuotient(sigma);
  const Eigen::VectorXd yw = y.cwiseQuotient(sigma);
  const Eigen::MatrixXd normal = Aw.transpose() * Aw;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(normal);
  const Eigen::VectorXd c = ldlt.solve(Aw.transpose() * yw);
  const Eigen::MatrixXd cov = ldlt.solve(Eigen::MatrixXd::Identity(k, k));
  LinearFit out;
  out.chi2 = (Aw * c - yw).squaredNorm();
  const double dof = static_cast<double>(A.rows() - k);
  const double scale = dof > 0.0 ? std::max(1.0, out.chi2 / dof) : 1.0;
  for (int i = 0; i < k; ++i) {
    out.coef(cols[i]) = c(i);
    for (int j = 0; j < k; ++j) out.cov(cols[i], cols[j]) = cov(i, j) * scale;
  }
  return out;
}

// AVAR(tau) = a / tau + b + c tau with a, b, c >= 0: the best fit among the subsets of terms
// whose coefficients all come out non-negative.
void design(const std::vector<double>& tau, const std::vector<double>& avar,
            const std::vector<double>& avar_std, Eigen::MatrixXd* A, Eigen::VectorXd* y,
            Eigen::VectorXd* s) {
  const int n = static_cast<int>(tau.size());
  A->resize(n, 3);
  y->resize(n);
  s->resize(n);
  for (int i = 0; i < n; ++i) {
    (*A)(i, 0) = 1.0 / tau[i];
    (*A)(i, 1) = 1.0;
    (*A)(i, 2) = tau[i];
    (*y)(i) = avar[i];
    (*s)(i) = avar_std[i];
  }
}

LinearFit fit_noise_model_all_terms(const std::vector<double>& tau, const std::vector<double>& avar,
                                    const std::vector<double>& avar_std) {
  Eigen::MatrixXd A;
  Eigen::VectorXd y, s;
  design(tau, avar, avar_std, &A, &y, &s);
  return weighted_fit(A, y, s, {true, true, true});
}

LinearFit fit_noise_model(const std::vector<double>& tau, const std::vector<double>& avar,
                          const std::vector<double>& avar_std) {
  const int n = static_cast<int>(tau.size());
  Eigen::MatrixXd A;
  Eigen::VectorXd y, s;
  design(tau, avar, avar_std, &A, &y, &s);
  LinearFit best;
  for (int mask = 7; mask >= 1; --mask) {
    const std::array<bool, 3> use = {(mask & 1) != 0, (mask & 2) != 0, (mask & 4) != 0};
    int terms = use[0] + use[1] + use[2];
    if (terms > n) continue;
    const LinearFit f = weighted_fit(A, y, s, use);
    if ((f.coef.array() < 0.0).any()) continue;
    if (f.chi2 < best.chi2) best = f;
  }
  return best;
}

}  // namespace

std::optional<DwellNoise> dwell_noise(const PositionTable& table) {
  Eigen::Vector3d sum_sq = Eigen::Vector3d::Zero();
  double dof = 0.0, samples = 0.0, duration = 0.0;
  for (const DwellRecord& row : table.rows) {
    if (row.n < 2 || !row.std.allFinite()) continue;
    const double w = static_cast<double>(row.n - 1);
    sum_sq += w * row.std.cwiseAbs2();
    dof += w;
    const double d = row.t_end_s - row.t_start_s;
    if (std::isfinite(d) && d > 0.0) {
      samples += static_cast<double>(row.n);
      duration += d;
    }
  }
  if (dof < 1.0 || !(duration > 0.0) || !(sum_sq.array() > 0.0).all()) return std::nullopt;
  DwellNoise out;
  out.dof = static_cast<std::uint64_t>(dof);
  out.rate_hz = samples / duration;
  out.sample_std = (sum_sq / dof).cwiseSqrt();
  out.density = out.sample_std / std::sqrt(out.rate_hz);
  // A pooled variance with dof degrees of freedom: relative std of its root 1 / sqrt(2 dof).
  out.density_std = out.density / std::sqrt(2.0 * dof);
  return out;
}

std::vector<double> overlapping_allan_deviation(const std::vector<double>& x, double rate_hz,
                                                const std::vector<std::size_t>& sizes,
                                                std::size_t max_stride_divisor) {
  const std::size_t n = x.size();
  if (n < 16) throw std::invalid_argument("Allan deviation: fewer than 16 samples");
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) {
    throw std::invalid_argument("Allan deviation: the sample rate must be positive");
  }
  double mean = 0.0;
  for (double v : x) mean += v;
  mean /= static_cast<double>(n);
  // theta[i]: sum of the first i (mean-removed) samples; a cluster mean is a difference of two.
  std::vector<double> theta(n + 1);
  theta[0] = 0.0;
  for (std::size_t i = 0; i < n; ++i) theta[i + 1] = theta[i] + (x[i] - mean);

  std::vector<double> out;
  out.reserve(sizes.size());
  for (std::size_t m : sizes) {
    if (m == 0 || 2 * m > n) throw std::invalid_argument("Allan deviation: bad cluster size");
    const std::size_t stride = std::max<std::size_t>(1, m / max_stride_divisor);
    const std::size_t last = n - 2 * m;  // k = 0 .. last
    const double* t0 = theta.data();
    const double* t1 = theta.data() + m;
    const double* t2 = theta.data() + 2 * m;
    // Four accumulators: independent chains the compiler can keep in flight.
    double acc[4] = {0.0, 0.0, 0.0, 0.0};
    std::size_t k = 0, terms = 0;
    for (; k + 3 * stride <= last; k += 4 * stride, terms += 4) {
      for (int j = 0; j < 4; ++j) {
        const std::size_t kk = k + j * stride;
        const double d = t2[kk] - 2.0 * t1[kk] + t0[kk];
        acc[j] += d * d;
      }
    }
    for (; k <= last; k += stride, ++terms) {
      const double d = t2[k] - 2.0 * t1[k] + t0[k];
      acc[0] += d * d;
    }
    const double sum = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    const double md = static_cast<double>(m);
    out.push_back(std::sqrt(sum / static_cast<double>(terms) / (2.0 * md * md)));
  }
  return out;
}

AllanCurve overlapping_allan_deviation(const std::vector<Eigen::Vector3d>& samples,
                                       double rate_hz, int points_per_decade) {
  const std::size_t n = samples.size();
  if (n < 16) throw std::invalid_argument("Allan deviation: fewer than 16 samples");
  if (points_per_decade < 1) throw std::invalid_argument("Allan deviation: points_per_decade < 1");
  AllanCurve curve;
  curve.samples = n;
  curve.rate_hz = rate_hz;
  const std::vector<std::size_t> sizes = cluster_sizes(n / 4, points_per_decade);
  curve.adev.assign(sizes.size(), Eigen::Vector3d::Zero());
  std::vector<double> axis(n);
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < n; ++i) axis[i] = samples[i](a);
    const std::vector<double> adev = overlapping_allan_deviation(axis, rate_hz, sizes);
    for (std::size_t j = 0; j < sizes.size(); ++j) curve.adev[j](a) = adev[j];
  }
  for (std::size_t m : sizes) {
    curve.tau_s.push_back(static_cast<double>(m) / rate_hz);
    const double clusters = static_cast<double>(n) / static_cast<double>(m);
    curve.relative_std.push_back(1.0 / std::sqrt(2.0 * std::max(1.0, clusters - 1.0)));
  }
  return curve;
}

StaticRecordNoise analyze_static_record(const std::vector<double>& stamps_s,
                                        const std::vector<Eigen::Vector3d>& outputs) {
  const std::size_t n = outputs.size();
  if (stamps_s.size() != n) throw std::invalid_argument("stamps and outputs differ in number");
  if (n < 100) {
    throw std::invalid_argument("a static record needs at least 100 samples (got " +
                                std::to_string(n) + ")");
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(stamps_s[i]) || !outputs[i].allFinite()) {
      throw std::invalid_argument("sample " + std::to_string(i) + " is not finite");
    }
    if (i > 0 && !(stamps_s[i] > stamps_s[i - 1])) {
      throw std::invalid_argument("stamps do not increase at sample " + std::to_string(i));
    }
  }
  StaticRecordNoise out;
  out.duration_s = stamps_s.back() - stamps_s.front();
  out.rate_hz = static_cast<double>(n - 1) / out.duration_s;
  out.curve = overlapping_allan_deviation(outputs, out.rate_hz);
  for (int a = 0; a < 3; ++a) out.axes[a] = noise_parameters(out.curve, a);
  return out;
}

NoiseParameters noise_parameters(const AllanCurve& curve, int axis) {
  if (axis < 0 || axis > 2) throw std::invalid_argument("noise_parameters: axis must be 0, 1 or 2");
  const std::size_t n = curve.tau_s.size();
  if (n < 3) throw std::invalid_argument("noise_parameters: fewer than 3 points on the curve");
  std::vector<double> avar(n), avar_std(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double a = curve.adev[i](axis);
    avar[i] = a * a;
    avar_std[i] = std::max(2.0 * curve.relative_std[i] * avar[i], 1e-300);
  }
  const LinearFit model = fit_noise_model(curve.tau_s, avar, avar_std);
  const double a = model.coef(0), c = model.coef(2);
  auto model_at = [&](double tau) { return a / tau + model.coef(1) + c * tau; };

  NoiseParameters out;
  // A line of fixed slope through the points where its term dominates: the weighted mean of the
  // points' log values read at the reference tau. Its relative uncertainty: the RMS of the points'
  // (they are strongly correlated, so averaging them gains little; the long-tau points of a
  // random walk, with few clusters, weigh in as they should).
  auto read_line = [&](double slope, double tau_ref, double share, auto term, int* points,
                       double* value, double* value_std) {
    double sw = 0.0, swl = 0.0, srel2 = 0.0;
    int k = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double tau = curve.tau_s[i];
      if (term(tau) < share * model_at(tau)) continue;
      const double w = 1.0 / (curve.relative_std[i] * curve.relative_std[i]);
      sw += w;
      srel2 += curve.relative_std[i] * curve.relative_std[i];
      swl += w * (std::log(curve.adev[i](axis)) - slope * std::log(tau / tau_ref));
      ++k;
    }
    *points = k;
    if (k == 0) return false;
    *value = std::exp(swl / sw);
    *value_std = *value * std::sqrt(srel2 / k);
    return true;
  };

  if (!read_line(-0.5, 1.0, 0.95, [&](double tau) { return a / tau; }, &out.white_points,
                 &out.white_density, &out.white_density_std)) {
    out.white_density = std::sqrt(a);
    out.white_density_std = a > 0.0 ? std::sqrt(model.cov(0, 0)) / (2.0 * std::sqrt(a)) : 0.0;
  }
  // u(c) from the model with all three terms, also when c came out negative and was dropped.
  const LinearFit full = fit_noise_model_all_terms(curve.tau_s, avar, avar_std);
  const double c_std = std::sqrt(std::max(full.cov(2, 2), model.cov(2, 2)));
  const bool walk_seen = c > 2.0 * c_std;
  if (!walk_seen || !read_line(0.5, 3.0, 0.8, [&](double tau) { return c * tau; },
                               &out.random_walk_points, &out.random_walk, &out.random_walk_std)) {
    out.random_walk_points = 0;
    out.random_walk = std::sqrt(3.0 * c);
    const double resolvable = std::sqrt(3.0 * c_std);
    const double delta = c > 0.0 ? 3.0 * c_std / (2.0 * out.random_walk) : resolvable;
    out.random_walk_std = std::max(delta, resolvable);
  }
  std::size_t i_min = 0;
  for (std::size_t i = 1; i < n; ++i) {
    if (curve.adev[i](axis) < curve.adev[i_min](axis)) i_min = i;
  }
  out.bias_instability = curve.adev[i_min](axis) / kBiasInstabilityFloor;
  out.bias_instability_std = out.bias_instability * curve.relative_std[i_min];
  out.bias_instability_tau_s = curve.tau_s[i_min];
  out.bias_instability_floor_seen = i_min + 1 < n;
  return out;
}

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
  const double abs_mean = double_integral(a0, a1, b0, b1, [](double x) {
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
      for (std::size_t j = 0; j < cols.size(); ++j) best.coef(cols[j]) = c(static_cast<Eigen::Index>(j));
    }
  }
  return best;
}

}  // namespace

NoiseModel estimate_noise_model(const std::vector<Eigen::Vector3d>& samples, double rate_hz) {
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz))
    throw std::invalid_argument("estimate_noise_model: the rate must be positive");
  const double duration = static_cast<double>(samples.size()) / rate_hz;
  if (samples.size() < 64 || duration < 10.0)
    throw std::invalid_argument("estimate_noise_model: the rest holds " +
                                std::to_string(samples.size()) + " samples over " +
                                std::to_string(duration) +
                                " s; at least 64 samples and 10 s are needed");
  const AllanCurve curve = overlapping_allan_deviation(samples, rate_hz, 10);
  NoiseModel model;
  model.rate_hz = rate_hz;
  model.rest_samples = samples.size();
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

std::optional<LongRest> find_long_rest(const PositionTable& table, double initial_rest_s) {
  if (table.rows.empty()) return std::nullopt;
  std::vector<std::size_t> order(table.rows.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return table.rows[a].t_start_s < table.rows[b].t_start_s;
  });
  auto length = [&](std::size_t i) { return table.rows[i].t_end_s - table.rows[i].t_start_s; };
  auto make = [&](std::size_t i, const std::string& reason) {
    LongRest r;
    r.row = i;
    r.t_start_s = table.rows[i].t_start_s;
    r.t_end_s = table.rows[i].t_end_s;
    r.reason = reason;
    return r;
  };
  const bool tumble = table.rows.front().orientation_unknown;
  if (tumble) {
    for (std::size_t i : order)
      if (length(i) >= 30.0) return make(i, "the first rest of at least 30 s");
    return std::nullopt;
  }
  if (initial_rest_s > 0.0) {
    const std::size_t first = order.front();
    const DwellRecord& r = table.rows[first];
    // 95 %: the dwell ends at the next MOVING, the settle time and stamp rounding shave a little.
    if (!r.has_direction && r.phase == Phase::X && r.step == 0 &&
        length(first) >= 0.95 * initial_rest_s)
      return make(first, "the initial rest (phase x, step 0)");
  }
  if (table.rows.size() < 3) return std::nullopt;
  std::vector<double> lengths;
  for (std::size_t i = 0; i < table.rows.size(); ++i) lengths.push_back(length(i));
  std::nth_element(lengths.begin(), lengths.begin() + static_cast<long>(lengths.size() / 2),
                   lengths.end());
  const double median = lengths[lengths.size() / 2];
  if (!(median > 0.0)) return std::nullopt;
  for (std::size_t i : order)
    if (length(i) >= 10.0 * median) return make(i, "a dwell at least 10 times the median dwell");
  return std::nullopt;
}

namespace {

// The samples stamped in [first, last] cut into blocks of equal duration (kRestBlocks, fewer
// when that would make them shorter than 1 s): each block's mean, std, n and its first and last
// stamps.
std::vector<DwellRecord> rest_blocks(const std::vector<double>& stamps_s,
                                     const std::vector<Eigen::Vector3d>& outputs, double first,
                                     double last) {
  const double span = last - first;
  const int count = std::max(1, std::min(kRestBlocks, static_cast<int>(std::floor(span))));
  const double length = span / count;
  std::vector<DwellRecord> blocks(static_cast<std::size_t>(count));
  std::vector<DwellAccumulator> stats(blocks.size());
  for (std::size_t i = 0; i < stamps_s.size(); ++i) {
    if (stamps_s[i] < first || stamps_s[i] > last) continue;
    const std::size_t b = std::min(blocks.size() - 1,
                                   static_cast<std::size_t>((stamps_s[i] - first) / length));
    if (stats[b].count() == 0) blocks[b].t_start_s = stamps_s[i];
    blocks[b].t_end_s = stamps_s[i];
    stats[b].add(outputs[i]);
  }
  std::vector<DwellRecord> out;
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    if (stats[b].count() < 2) continue;
    blocks[b].n = stats[b].count();
    blocks[b].mean = stats[b].mean();
    blocks[b].std = stats[b].sample_std();
    blocks[b].orientation_unknown = true;
    out.push_back(blocks[b]);
  }
  return out;
}

}  // namespace

std::optional<NoiseModel> noise_model_of_run(const PositionTable& table,
                                             const std::vector<double>& stamps_s,
                                             const std::vector<Eigen::Vector3d>& outputs,
                                             double initial_rest_s) {
  const std::optional<LongRest> rest = find_long_rest(table, initial_rest_s);
  if (!rest || stamps_s.size() != outputs.size()) return std::nullopt;
  std::vector<Eigen::Vector3d> inside;
  double first = 0.0, last = 0.0;
  for (std::size_t i = 0; i < stamps_s.size(); ++i) {
    if (stamps_s[i] < rest->t_start_s || stamps_s[i] > rest->t_end_s) continue;
    if (inside.empty()) first = stamps_s[i];
    last = stamps_s[i];
    inside.push_back(outputs[i]);
  }
  if (inside.size() < 64 || !(last > first)) return std::nullopt;
  const double rate = static_cast<double>(inside.size() - 1) / (last - first);
  NoiseModel m = estimate_noise_model(inside, rate);
  m.source = rest->reason;
  m.rest_t_start_s = rest->t_start_s;
  m.rest_t_end_s = rest->t_end_s;
  m.rest_blocks = rest_blocks(stamps_s, outputs, first, last);
  return m;
}

void LongRestRecorder::add_command(const GimbalEvent& event) {
  if (stage_ == Stage::BeforeRest && event.state == GimbalState::Settled) {
    stage_ = Stage::InRest;
  } else if (stage_ == Stage::InRest && event.state != GimbalState::Settled) {
    stage_ = Stage::After;
    end_s_ = event.stamp_s;
  }
}

void LongRestRecorder::add_sample(const ImuSample& sample) {
  // A sample stamped with the MOVING that ends the rest arrives after it and still belongs to it.
  if (stage_ == Stage::BeforeRest || (stage_ == Stage::After && sample.stamp_s > end_s_)) return;
  if (stamps_.size() >= max_samples_) {
    ++dropped_;
    return;
  }
  stamps_.push_back(sample.stamp_s);
  outputs_.push_back(sample.outputs);
}

void LongRestRecorder::clear() {
  stage_ = Stage::BeforeRest;
  end_s_ = 0.0;
  stamps_.clear();
  outputs_.clear();
  dropped_ = 0;
}

std::optional<NoiseModel> LongRestRecorder::noise_model(const PositionTable& table,
                                                        double initial_rest_s) const {
  return noise_model_of_run(table, stamps_, outputs_, initial_rest_s);
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
    Eigen::MatrixXd R = Eigen::MatrixXd::Identity(static_cast<Eigen::Index>(n),
                                                  static_cast<Eigen::Index>(n));
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
