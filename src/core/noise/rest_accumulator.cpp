// The long rest accumulated as it streams (docs/design.md sections 8 and 12; docs/noise.md).
#include "accel_intrinsics/core/noise/rest_accumulator.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace accel_intrinsics {
namespace core {
namespace {

// overlapping_allan_deviation's stride: clusters of m > 16 start m / 16 samples apart.
constexpr std::size_t kMaxStrideDivisor = 16;

std::size_t stride_of(std::size_t m) {
  return std::max<std::size_t>(1, m / kMaxStrideDivisor);
}

std::size_t grid_size(int i, int points_per_decade) {
  return static_cast<std::size_t>(
      std::round(std::pow(10.0, static_cast<double>(i) / points_per_decade)));
}

// Duration of a sub-block at the start of a rest: 2^-10 s (about 1 ms); it doubles as the rest
// grows, so the start only sets how fine the sub-blocks of a short rest are.
constexpr double kFirstSubBlockS = 1.0 / 1024.0;

}  // namespace

std::vector<std::size_t> allan_cluster_sizes(std::size_t max_m, int points_per_decade) {
  std::vector<std::size_t> out;
  for (int i = 0;; ++i) {
    const double m = std::round(std::pow(10.0, static_cast<double>(i) / points_per_decade));
    if (m > static_cast<double>(max_m)) break;
    const std::size_t mi = static_cast<std::size_t>(m);
    if (out.empty() || mi != out.back()) out.push_back(mi);
  }
  return out;
}

// ---- StreamingAllan
// ------------------------------------------------------------------------------
//
// overlapping_allan_deviation sums, for each cluster size m, d_k^2 over k = 0, s, 2 s, ...,
// k <= n - 2 m, with d_k = theta[k + 2 m] - 2 theta[k + m] + theta[k] (theta[i]: the sum of the
// first i samples, mean removed; the second difference does not see the mean, nor any constant
// taken off every sample, here the first sample). Streaming, theta[j] is known when sample j - 1
// arrives: a term starts at index k (theta[k] kept), takes -2 theta[k + m] at k + m and ends at
// k + 2 m. A cluster of stride 1 (m < 32) reads theta[k] and theta[k + m] from the last 64
// cumulative sums instead.

void StreamingAllan::open_clusters_up_to(std::size_t index) {
  for (;;) {
    const std::size_t m = grid_size(next_grid_i_, kAllanPointsPerDecade);
    if (m == last_opened_m_) {
      ++next_grid_i_;
      continue;
    }
    // Nothing of m happens before index stride (the term at 0 starts from theta[0] = 0).
    if (stride_of(m) > index) return;
    Cluster c;
    c.m = m;
    c.stride = stride_of(m);
    c.m_mod = m % c.stride;
    c.m2_mod = (2 * m) % c.stride;
    c.next = index;  // at_index(index) looks at it first
    if (c.stride > 1) {
      c.pending.assign(2 * m / c.stride + 2, Sums{});
      c.started = 1;  // the term at k = 0, theta[0] = 0
    }
    clusters_.push_back(std::move(c));
    last_opened_m_ = m;
    ++next_grid_i_;
  }
}

void StreamingAllan::at_index(std::size_t j) {
  const Sums& t = theta_;
  for (Cluster& c : clusters_) {
    if (c.stride == 1) {
      if (j < 2 * c.m) continue;
      const Sums& a = history_[(j - c.m) % kHistory];
      const Sums& b = history_[(j - 2 * c.m) % kHistory];
      for (int s = 0; s < 3; ++s) {
        const long double d = t[s] - 2.0L * a[s] + b[s];
        c.sum[s] += d * d;
      }
      ++c.done;
      continue;
    }
    // A cluster of stride s acts only at indices j with j mod s in {0, m mod s, 2 m mod s}: at
    // most three in s; the others are skipped on one comparison.
    if (j < c.next) continue;
    const std::size_t phase = j % c.stride;
    const std::size_t cap = c.pending.size();
    if (j >= 2 * c.m && phase == c.m2_mod) {
      Sums& p = c.pending[c.done % cap];
      for (int s = 0; s < 3; ++s) {
        const long double d = p[s] + t[s];
        c.sum[s] += d * d;
      }
      ++c.done;
    }
    if (j >= c.m && phase == c.m_mod) {
      Sums& p = c.pending[c.halfway % cap];
      for (int s = 0; s < 3; ++s) p[s] -= 2.0L * t[s];
      ++c.halfway;
    }
    if (phase == 0) {
      c.pending[c.started % cap] = t;
      ++c.started;
    }
    // Steps to the next phase of the three (a full stride back to this one).
    auto ahead = [&](std::size_t target) {
      const std::size_t d = (target + c.stride - phase) % c.stride;
      return d == 0 ? c.stride : d;
    };
    c.next = j + std::min({ahead(0), ahead(c.m_mod), ahead(c.m2_mod)});
  }
}

void StreamingAllan::add(const Eigen::Vector3d& x) {
  if (n_ == 0) offset_ = x;
  for (int s = 0; s < 3; ++s)
    theta_[s] += static_cast<long double>(x(s)) - static_cast<long double>(offset_(s));
  ++n_;
  open_clusters_up_to(n_);
  history_[n_ % kHistory] = theta_;
  at_index(n_);
}

AllanCurve StreamingAllan::curve(double rate_hz) const {
  if (n_ < 16) throw std::invalid_argument("Allan deviation: fewer than 16 samples");
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz))
    throw std::invalid_argument("Allan deviation: the sample rate must be positive");
  AllanCurve curve;
  curve.samples = n_;
  curve.rate_hz = rate_hz;
  const std::vector<std::size_t> sizes = allan_cluster_sizes(n_ / 4, kAllanPointsPerDecade);
  std::size_t c = 0;
  for (std::size_t m : sizes) {
    while (c < clusters_.size() && clusters_[c].m < m) ++c;
    if (c == clusters_.size() || clusters_[c].m != m || clusters_[c].done == 0)
      throw std::logic_error("StreamingAllan: cluster size " + std::to_string(m) + " missing");
    const Cluster& k = clusters_[c];
    Eigen::Vector3d adev;
    const long double md = static_cast<long double>(m);
    for (int s = 0; s < 3; ++s)
      adev(s) = static_cast<double>(
          std::sqrt(k.sum[s] / static_cast<long double>(k.done) / (2.0L * md * md)));
    curve.adev.push_back(adev);
    curve.tau_s.push_back(static_cast<double>(m) / rate_hz);
    const double clusters = static_cast<double>(n_) / static_cast<double>(m);
    curve.relative_std.push_back(1.0 / std::sqrt(2.0 * std::max(1.0, clusters - 1.0)));
  }
  return curve;
}

void StreamingAllan::clear() {
  *this = StreamingAllan();
}

std::size_t StreamingAllan::memory_bytes() const {
  std::size_t bytes = sizeof(*this) + clusters_.capacity() * sizeof(Cluster);
  for (const Cluster& c : clusters_) bytes += c.pending.capacity() * sizeof(Sums);
  return bytes;
}

// ---- RestAccumulator
// -----------------------------------------------------------------------------

void RestAccumulator::SubBlock::add(double t, const Eigen::Vector3d& x) {
  if (n == 0) t_first = t;
  t_last = t;
  ++n;
  const Eigen::Vector3d delta = x - mean;
  mean += delta * (1.0 / static_cast<double>(n));  // one division, not three
  m2 += delta.cwiseProduct(x - mean);
}

void RestAccumulator::SubBlock::merge(const SubBlock& o) {
  if (o.n == 0) return;
  if (n == 0) {
    *this = o;
    return;
  }
  const double na = static_cast<double>(n), nb = static_cast<double>(o.n), nt = na + nb;
  const Eigen::Vector3d delta = o.mean - mean;
  mean += delta * (nb / nt);
  m2 += o.m2 + delta.cwiseAbs2() * (na * nb / nt);
  n += o.n;
  t_first = std::min(t_first, o.t_first);
  t_last = std::max(t_last, o.t_last);
}

void RestAccumulator::add(double stamp_s, const Eigen::Vector3d& outputs) {
  if (!std::isfinite(stamp_s) || !outputs.allFinite())
    throw std::invalid_argument("RestAccumulator: a sample is not finite");
  if (samples() == 0) {
    first_s_ = stamp_s;
    width_s_ = kFirstSubBlockS;
    per_width_ = 1.0 / kFirstSubBlockS;
    sub_.clear();
    sub_.reserve(kSubBlocks);
  } else if (stamp_s < last_s_) {
    throw std::invalid_argument("RestAccumulator: samples out of stamp order");
  }
  last_s_ = stamp_s;
  // A power of two: the product is the quotient, exactly.
  std::size_t i = static_cast<std::size_t>((stamp_s - first_s_) * per_width_);
  while (i >= kSubBlocks) {
    // Neighbours merged pairwise, the duration doubled: the sub-blocks stay of equal duration.
    const std::size_t half = (sub_.size() + 1) / 2;
    for (std::size_t k = 0; k < half; ++k) {
      SubBlock merged = sub_[2 * k];
      if (2 * k + 1 < sub_.size()) merged.merge(sub_[2 * k + 1]);
      sub_[k] = merged;
    }
    sub_.resize(half);
    width_s_ *= 2.0;
    per_width_ *= 0.5;
    i = static_cast<std::size_t>((stamp_s - first_s_) * per_width_);
  }
  if (i >= sub_.size()) sub_.resize(i + 1);
  sub_[i].add(stamp_s, outputs);
  allan_.add(outputs);
}

double RestAccumulator::rate_hz() const {
  if (samples() < 2 || !(last_s_ > first_s_)) return 0.0;
  return static_cast<double>(samples() - 1) / (last_s_ - first_s_);
}

std::vector<DwellRecord> RestAccumulator::rest_blocks() const {
  if (samples() == 0) return {};
  const double span = last_s_ - first_s_;
  const int count = std::max(1, std::min(kRestBlocks, static_cast<int>(std::floor(span))));
  const double length = span / count;
  std::vector<SubBlock> blocks(static_cast<std::size_t>(count));
  for (const SubBlock& s : sub_) {
    if (s.n == 0) continue;
    const double middle = 0.5 * (s.t_first + s.t_last);
    const std::size_t b =
        length > 0.0
            ? std::min(blocks.size() - 1,
                       static_cast<std::size_t>(std::max(0.0, (middle - first_s_) / length)))
            : 0;
    blocks[b].merge(s);
  }
  std::vector<DwellRecord> out;
  for (const SubBlock& b : blocks) {
    if (b.n < 2) continue;
    DwellRecord r;
    r.t_start_s = b.t_first;
    r.t_end_s = b.t_last;
    r.n = b.n;
    r.mean = b.mean;
    r.std = (b.m2 / static_cast<double>(b.n - 1)).cwiseMax(0.0).cwiseSqrt();
    r.orientation_unknown = true;
    out.push_back(r);
  }
  return out;
}

std::optional<NoiseModel> RestAccumulator::noise_model() const {
  if (samples() < 64 || !(last_s_ > first_s_)) return std::nullopt;
  const double rate = rate_hz();
  NoiseModel m = estimate_noise_model(allan_.curve(rate));
  m.rest_blocks = rest_blocks();
  return m;
}

void RestAccumulator::clear() {
  allan_.clear();
  first_s_ = last_s_ = 0.0;
  width_s_ = per_width_ = 0.0;
  sub_.clear();
}

std::size_t RestAccumulator::memory_bytes() const {
  return sizeof(*this) - sizeof(allan_) + allan_.memory_bytes() +
         sub_.capacity() * sizeof(SubBlock);
}

// ---- LongRestRecorder
// ----------------------------------------------------------------------------

void LongRestRecorder::add_command(const GimbalEvent& event) {
  if (stage_ == Stage::BeforeRest && event.state == GimbalState::Settled) {
    stage_ = Stage::InRest;
    start_s_ = event.stamp_s + settle_discard_s_;  // the expression of the dwell's t_start_s
  } else if (stage_ == Stage::InRest) {
    // Any command ends the first dwell, as it ends it in the assembler (a MOVING, a DONE, or a
    // SETTLED out of order).
    stage_ = Stage::After;
    end_s_ = event.stamp_s;
  }
}

void LongRestRecorder::add_sample(const ImuSample& sample) {
  if (stage_ == Stage::BeforeRest || sample.stamp_s < start_s_) return;
  // A sample stamped with the command that ends the rest arrives after it and still belongs to it.
  if (stage_ == Stage::After && sample.stamp_s > end_s_) return;
  // Released in stamp order; a stamp that goes back (the run rewound and fed again) is a sample
  // already counted.
  if (rest_.samples() > 0 && sample.stamp_s < rest_.last_stamp_s()) return;
  rest_.add(sample.stamp_s, sample.outputs);
}

void LongRestRecorder::clear() {
  stage_ = Stage::BeforeRest;
  start_s_ = end_s_ = 0.0;
  rest_.clear();
}

bool LongRestRecorder::holds_long_rest(const PositionTable& table, double initial_rest_s) const {
  const std::optional<LongRest> span = find_long_rest(table, initial_rest_s);
  // The rest's samples are all here when the recorded span [start_s_, end_s_] covers the rest's
  // row and what was accumulated lies inside it (a tumble's row ends just before its MOVING).
  return span && stage_ == Stage::After && rest_.samples() > 0 && start_s_ <= span->t_start_s &&
         end_s_ >= span->t_end_s && rest_.first_stamp_s() >= span->t_start_s &&
         rest_.last_stamp_s() <= span->t_end_s;
}

std::optional<NoiseModel> LongRestRecorder::noise_model(const PositionTable& table,
                                                        double initial_rest_s) const {
  if (!holds_long_rest(table, initial_rest_s)) return std::nullopt;
  return noise_model_of_rest(rest_, *find_long_rest(table, initial_rest_s));
}

std::optional<NoiseModel> noise_model_of_rest(const RestAccumulator& rest, const LongRest& span) {
  std::optional<NoiseModel> m = rest.noise_model();
  if (!m) return m;
  m->source = span.reason;
  m->rest_t_start_s = span.t_start_s;
  m->rest_t_end_s = span.t_end_s;
  return m;
}

}  // namespace core
}  // namespace accel_intrinsics
