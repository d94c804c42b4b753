// White and Allan-deviation noise: per-dwell noise, overlapping Allan deviation, a static
// record's noise parameters (noise.h).
#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/noise/rest_accumulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

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

AllanCurve overlapping_allan_deviation(const std::vector<Eigen::Vector3d>& samples, double rate_hz,
                                       int points_per_decade) {
  const std::size_t n = samples.size();
  if (n < 16) throw std::invalid_argument("Allan deviation: fewer than 16 samples");
  if (points_per_decade < 1) throw std::invalid_argument("Allan deviation: points_per_decade < 1");
  AllanCurve curve;
  curve.samples = n;
  curve.rate_hz = rate_hz;
  const std::vector<std::size_t> sizes = allan_cluster_sizes(n / 4, points_per_decade);
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

  if (!read_line(
          -0.5, 1.0, 0.95, [&](double tau) { return a / tau; }, &out.white_points,
          &out.white_density, &out.white_density_std)) {
    out.white_density = std::sqrt(a);
    out.white_density_std = a > 0.0 ? std::sqrt(model.cov(0, 0)) / (2.0 * std::sqrt(a)) : 0.0;
  }
  // u(c) from the model with all three terms, also when c came out negative and was dropped.
  const LinearFit full = fit_noise_model_all_terms(curve.tau_s, avar, avar_std);
  const double c_std = std::sqrt(std::max(full.cov(2, 2), model.cov(2, 2)));
  const bool walk_seen = c > 2.0 * c_std;
  if (!walk_seen || !read_line(
                        0.5, 3.0, 0.8, [&](double tau) { return c * tau; }, &out.random_walk_points,
                        &out.random_walk, &out.random_walk_std)) {
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

}  // namespace core
}  // namespace accel_intrinsics
