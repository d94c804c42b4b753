#include "accel_intrinsics/core/dwells/rest_detection.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/dwells/dwell_source.h"

namespace accel_intrinsics {
namespace core {
namespace {

constexpr std::size_t kStartupSamples = 21;  // to estimate the sample rate of a live stream
constexpr std::uint64_t kMinBlockSamples = 5;

std::string seconds(double s) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(2) << s << " s";
  return out.str();
}

double quantile_of(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const std::size_t k =
      std::min(values.size() - 1, static_cast<std::size_t>(q * static_cast<double>(values.size())));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

std::uint64_t block_samples_for(double block_s, double rate_hz) {
  return std::max<std::uint64_t>(kMinBlockSamples,
                                 static_cast<std::uint64_t>(std::llround(block_s * rate_hz)));
}

// Smallest non-zero change between consecutive samples, per axis: the output step of a
// quantized stream (infinite when no axis ever changes).
Eigen::Vector3d output_step(const std::vector<ImuSample>& samples) {
  Eigen::Vector3d step = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  for (std::size_t i = 1; i < samples.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const double d = std::abs(samples[i].outputs(k) - samples[i - 1].outputs(k));
      if (d > 0.0 && d < step(k)) step(k) = d;
    }
  }
  return step;
}

// The quiet std floored at half an output step: quantized quiet blocks can read constant.
Eigen::Vector3d floored(const Eigen::Vector3d& quiet, const Eigen::Vector3d& step) {
  Eigen::Vector3d out = quiet;
  for (int k = 0; k < 3; ++k) {
    if (std::isfinite(step(k))) out(k) = std::max(out(k), 0.5 * step(k));
  }
  return out;
}

}  // namespace

void validate(const RestDetectionOptions& o) {
  auto positive = [](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0.0))
      throw std::invalid_argument(std::string("rest detection: ") + name + " must be > 0");
  };
  positive(o.min_rest_s, "min_rest_s (--rest-min-s)");
  positive(o.block_s, "block_s");
  positive(o.still_factor, "still_factor");
  positive(o.mean_step_factor, "mean_step_factor");
  positive(o.creep_factor, "creep_factor");
  positive(o.gap_factor, "gap_factor");
  if (!(std::isfinite(o.trim_s) && o.trim_s >= 0.0))
    throw std::invalid_argument("rest detection: trim_s must be >= 0");
  if (!(std::isfinite(o.merge_gap_s) && o.merge_gap_s >= 0.0))
    throw std::invalid_argument("rest detection: merge_gap_s must be >= 0");
  if (!(o.quiet_quantile > 0.0 && o.quiet_quantile < 1.0))
    throw std::invalid_argument("rest detection: quiet_quantile must be in (0, 1)");
}

// ---- BlockStatistics -------------------------------------------------------------------------

void BlockStatistics::add(double t_s, const Eigen::Vector3d& x) {
  if (n == 0) t_first_s = t_s;
  t_last_s = t_s;
  ++n;
  const Eigen::Vector3d delta = x - mean;
  mean += delta / static_cast<double>(n);
  m2 += delta.cwiseProduct(x - mean);
}

void BlockStatistics::join(const BlockStatistics& later) {
  if (later.n == 0) return;
  if (n == 0) {
    *this = later;
    return;
  }
  const double na = static_cast<double>(n);
  const double nb = static_cast<double>(later.n);
  const Eigen::Vector3d delta = later.mean - mean;
  mean += delta * (nb / (na + nb));
  m2 += later.m2 + delta.cwiseProduct(delta) * (na * nb / (na + nb));
  n += later.n;
  t_last_s = later.t_last_s;
}

Eigen::Vector3d BlockStatistics::sample_std() const {
  if (n < 2) return Eigen::Vector3d::Zero();
  return (m2 / static_cast<double>(n - 1)).cwiseMax(0.0).cwiseSqrt();
}

// ---- RestDetector ----------------------------------------------------------------------------

RestDetector::RestDetector(const RestDetectionOptions& options, double rate_hz)
    : options_(options), rate_hz_(rate_hz) {
  validate(options_);
  if (rate_hz_ < 0.0 || !std::isfinite(rate_hz_))
    throw std::invalid_argument("rest detection: rate_hz must be >= 0");
  if (rate_hz_ > 0.0) start_blocks();
}

void RestDetector::set_quiet_std(const Eigen::Vector3d& quiet_std) {
  quiet_fixed_ = true;
  quiet_std_ = quiet_std;
}

void RestDetector::start_blocks() {
  block_n_ = block_samples_for(options_.block_s, rate_hz_);
}

// The longest gap between two trimmed still runs that may still be one rest: the disturbance
// itself, the trims on both sides, and a block of misalignment on each side.
double RestDetector::join_window_s() const {
  return options_.merge_gap_s + 2.0 * (options_.trim_s + options_.block_s);
}

double RestDetector::current_still_s() const {
  return in_run_ ? run_.t_end_s - run_.t_start_s : 0.0;
}

void RestDetector::add(double t_s, const Eigen::Vector3d& x) {
  if (!std::isfinite(t_s) || !x.allFinite())
    throw std::invalid_argument("rest detection: a sample is not finite");
  if (t_s < last_t_s_) {
    std::ostringstream m;
    m << "rest detection: the stamps go back (" << std::setprecision(12) << t_s << " s after "
      << last_t_s_ << " s): sort the samples by time";
    throw std::invalid_argument(m.str());
  }
  if (rate_hz_ <= 0.0) {
    // A live stream: estimate the rate from the first samples, then replay them.
    startup_.emplace_back(t_s, x);
    last_t_s_ = t_s;
    if (startup_.size() < kStartupSamples) return;
    std::vector<double> dt;
    for (std::size_t i = 1; i < startup_.size(); ++i)
      dt.push_back(startup_[i].first - startup_[i - 1].first);
    const double median = quantile_of(dt, 0.5);
    if (!(median > 0.0))
      throw std::invalid_argument("rest detection: the first samples share one stamp");
    rate_hz_ = 1.0 / median;
    start_blocks();
    std::vector<std::pair<double, Eigen::Vector3d>> replay;
    replay.swap(startup_);
    last_t_s_ = -std::numeric_limits<double>::infinity();
    for (const auto& s : replay) add(s.first, s.second);
    return;
  }
  // A gap in the stream ends the block and the run: nothing is known about the gap.
  if (samples_ > 0 && t_s - last_t_s_ > options_.gap_factor / rate_hz_) {
    if (in_run_) end_run();
    rejected_.push_back(RejectedSpan{
        last_t_s_, t_s, "gap in the stream: " + seconds(t_s - last_t_s_) + " without samples"});
    block_ = BlockStatistics();
    have_previous_block_ = false;
  }
  if (samples_ > 0) {
    for (int k = 0; k < 3; ++k) {
      const double d = std::abs(x(k) - last_x_(k));
      if (d > 0.0 && d < resolution_(k)) resolution_(k) = d;
    }
  }
  ++samples_;
  last_t_s_ = t_s;
  last_x_ = x;
  // A rest that waits for a possible join is given out once the join window has passed.
  if (have_pending_ && !in_run_ && t_s - pending_.t_end_s > join_window_s()) settle_pending();
  block_.add(t_s, x);
  if (block_.n >= block_n_) close_block();
}

Eigen::Vector3d RestDetector::learned_quiet_std() const {
  Eigen::Vector3d q;
  for (int k = 0; k < 3; ++k) q(k) = quantile_of(block_std_history_[k], options_.quiet_quantile);
  return q;
}

bool RestDetector::block_is_still(const BlockStatistics& block) const {
  const Eigen::Vector3d quiet = floored(quiet_std_, resolution_);
  const Eigen::Vector3d sd = block.sample_std();
  const double step_se = std::sqrt(2.0 / static_cast<double>(block.n));
  for (int k = 0; k < 3; ++k) {
    if (sd(k) > options_.still_factor * quiet(k)) return false;
    if (have_previous_block_ && std::abs(block.mean(k) - previous_block_mean_(k)) >
                                    options_.mean_step_factor * quiet(k) * step_se)
      return false;
  }
  return true;
}

void RestDetector::close_block() {
  if (!quiet_fixed_) {
    const Eigen::Vector3d sd = block_.sample_std();
    for (int k = 0; k < 3; ++k) block_std_history_[k].push_back(sd(k));
    // The quantile moves slowly once many blocks are in: refresh it less often.
    const std::size_t blocks = block_std_history_[0].size();
    if (blocks < 256 || blocks % 16 == 0) quiet_std_ = learned_quiet_std();
  }
  const bool still = block_is_still(block_);
  if (still) {
    if (!in_run_) {
      in_run_ = true;
      run_ = Run();
      run_.t_start_s = block_.t_first_s;
    }
    run_.blocks.push_back(block_);
    run_.t_end_s = block_.t_last_s;
  } else if (in_run_) {
    end_run();
  }
  have_previous_block_ = true;
  previous_block_mean_ = block_.mean;
  block_ = BlockStatistics();
}

void RestDetector::end_run() {
  in_run_ = false;
  Run run = std::move(run_);
  run_ = Run();
  // Trim whole blocks at both ends: the hand letting go, the first touch of the next turn.
  const std::size_t trim =
      static_cast<std::size_t>(std::ceil(options_.trim_s / options_.block_s - 1e-9));
  const double span_start = run.t_start_s;
  const double span_end = run.t_end_s;
  if (run.blocks.size() <= 2 * trim) {
    rejected_.push_back(RejectedSpan{span_start, span_end,
                                     "too short: still for " + seconds(span_end - span_start) +
                                         ", nothing left after trimming " +
                                         seconds(options_.trim_s) + " at both ends"});
    return;
  }
  run.blocks.erase(run.blocks.end() - static_cast<std::ptrdiff_t>(trim), run.blocks.end());
  run.blocks.erase(run.blocks.begin(), run.blocks.begin() + static_cast<std::ptrdiff_t>(trim));
  run.t_start_s = run.blocks.front().t_first_s;
  run.t_end_s = run.blocks.back().t_last_s;

  if (have_pending_) {
    // Join when the disturbance between the two was short and the device came back to the same
    // orientation (means agree at the block level).
    const double gap = run.t_start_s - pending_.t_end_s;
    bool same = gap <= join_window_s();
    if (same) {
      BlockStatistics a, b;
      for (const BlockStatistics& blk : pending_.blocks) a.join(blk);
      for (const BlockStatistics& blk : run.blocks) b.join(blk);
      const Eigen::Vector3d quiet = floored(quiet_std_, resolution_);
      const double se = std::sqrt(2.0 / static_cast<double>(block_n_));
      for (int k = 0; k < 3; ++k)
        if (std::abs(a.mean(k) - b.mean(k)) > options_.mean_step_factor * quiet(k) * se)
          same = false;
    }
    if (same) {
      pending_.cut.push_back(RejectedSpan{pending_.t_end_s, run.t_start_s,
                                          "disturbance inside a rest (a jolt or a short shake): " +
                                              seconds(run.t_start_s - pending_.t_end_s) +
                                              " cut out, the two sides joined"});
      for (BlockStatistics& blk : run.blocks) pending_.blocks.push_back(blk);
      pending_.t_end_s = run.t_end_s;
      return;
    }
    settle_pending();
  }
  pending_ = std::move(run);
  have_pending_ = true;
}

void RestDetector::settle_pending() {
  if (!have_pending_) return;
  have_pending_ = false;
  emit(std::move(pending_));
  pending_ = Run();
}

void RestDetector::emit(Run&& run) {
  const double duration = run.t_end_s - run.t_start_s;
  if (duration < options_.min_rest_s) {
    std::ostringstream m;
    m << "too short: still for " << seconds(duration) << " after trimming, rest-min-s is "
      << seconds(options_.min_rest_s);
    rejected_.push_back(RejectedSpan{run.t_start_s, run.t_end_s, m.str()});
    return;
  }
  // A creeping mean (a slow turn, a device settling on a soft surface): compare the thirds.
  const std::size_t third = std::max<std::size_t>(1, run.blocks.size() / 3);
  BlockStatistics first, last, all;
  for (std::size_t i = 0; i < third; ++i) first.join(run.blocks[i]);
  for (std::size_t i = run.blocks.size() - third; i < run.blocks.size(); ++i)
    last.join(run.blocks[i]);
  for (const BlockStatistics& blk : run.blocks) all.join(blk);
  const Eigen::Vector3d quiet = floored(quiet_std_, resolution_);
  const double se = std::sqrt(2.0 / static_cast<double>(block_n_));
  for (int k = 0; k < 3; ++k) {
    const double change = last.mean(k) - first.mean(k);
    if (std::abs(change) > options_.creep_factor * quiet(k) * se) {
      std::ostringstream m;
      m << "slow motion, not a rest: output "
        << "uvw"[k] << " moves by " << std::setprecision(3) << change << " ("
        << std::setprecision(2) << std::abs(change) / quiet(k)
        << " quiet std) from the first to the last third";
      rejected_.push_back(RejectedSpan{run.t_start_s, run.t_end_s, m.str()});
      return;
    }
  }
  for (RejectedSpan& cut : run.cut) rejected_.push_back(std::move(cut));
  DwellRecord rest;
  rest.orientation_unknown = true;
  rest.step = next_index_++;
  rest.angle_rad = 0.0;
  rest.t_start_s = all.t_first_s;
  rest.t_end_s = all.t_last_s;
  rest.n = all.n;
  rest.mean = all.mean;
  rest.std = all.sample_std();
  completed_.push_back(rest);
}

void RestDetector::finish() {
  if (rate_hz_ <= 0.0) {
    if (startup_.size() >= 2) {
      // Too short a stream to have estimated the rate while running: do it now.
      std::vector<std::pair<double, Eigen::Vector3d>> replay;
      replay.swap(startup_);
      std::vector<double> dt;
      for (std::size_t i = 1; i < replay.size(); ++i)
        dt.push_back(replay[i].first - replay[i - 1].first);
      const double median = quantile_of(dt, 0.5);
      if (median > 0.0) {
        rate_hz_ = 1.0 / median;
        start_blocks();
        last_t_s_ = -std::numeric_limits<double>::infinity();
        for (const auto& s : replay) add(s.first, s.second);
      }
    }
    if (rate_hz_ <= 0.0) return;
  }
  if (in_run_) end_run();
  settle_pending();
}

std::vector<DwellRecord> RestDetector::take_rests() {
  std::vector<DwellRecord> out;
  out.swap(completed_);
  return out;
}

// ---- batch -----------------------------------------------------------------------------------

StreamCleanup put_in_time_order(std::vector<ImuSample>* samples) {
  StreamCleanup c;
  std::vector<ImuSample>& v = *samples;
  for (std::size_t i = 1; i < v.size(); ++i) c.reordered += v[i].stamp_s < v[i - 1].stamp_s ? 1 : 0;
  std::stable_sort(v.begin(), v.end(),
                   [](const ImuSample& a, const ImuSample& b) { return a.stamp_s < b.stamp_s; });
  std::size_t kept = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (kept > 0 && v[i].stamp_s == v[kept - 1].stamp_s) {
      if (v[i].outputs == v[kept - 1].outputs)
        ++c.duplicates;
      else
        ++c.conflicting;
      continue;
    }
    v[kept++] = v[i];
  }
  v.resize(kept);
  return c;
}

double median_rate_hz(const std::vector<ImuSample>& samples) {
  if (samples.size() < 2) return 0.0;
  std::vector<double> dt;
  dt.reserve(samples.size() - 1);
  for (std::size_t i = 1; i < samples.size(); ++i)
    dt.push_back(samples[i].stamp_s - samples[i - 1].stamp_s);
  const double median = quantile_of(std::move(dt), 0.5);
  return median > 0.0 ? 1.0 / median : 0.0;
}

Eigen::Vector3d quiet_std_of(const std::vector<ImuSample>& samples, std::uint64_t block_samples,
                             double quantile) {
  std::vector<double> stds[3];
  const std::size_t blocks = samples.size() / block_samples;
  for (int k = 0; k < 3; ++k) stds[k].reserve(blocks);
  for (std::size_t b = 0; b < blocks; ++b) {
    // Sums about the block's first sample: no cancellation for outputs far from zero (counts).
    const std::size_t begin = b * block_samples;
    const Eigen::Vector3d origin = samples[begin].outputs;
    Eigen::Vector3d s1 = Eigen::Vector3d::Zero(), s2 = Eigen::Vector3d::Zero();
    for (std::size_t i = begin; i < begin + block_samples; ++i) {
      const Eigen::Vector3d d = samples[i].outputs - origin;
      s1 += d;
      s2 += d.cwiseProduct(d);
    }
    const double n = static_cast<double>(block_samples);
    const Eigen::Vector3d var = (s2 - s1.cwiseProduct(s1) / n) / (n - 1.0);
    for (int k = 0; k < 3; ++k) stds[k].push_back(std::sqrt(std::max(0.0, var(k))));
  }
  Eigen::Vector3d quiet;
  for (int k = 0; k < 3; ++k) quiet(k) = quantile_of(std::move(stds[k]), quantile);
  return floored(quiet, output_step(samples));
}

RestDetection detect_rests(const std::vector<ImuSample>& samples,
                           const RestDetectionOptions& options) {
  validate(options);
  if (samples.size() < 10)
    throw std::invalid_argument("rest detection: " + std::to_string(samples.size()) +
                                " samples, too few for a stream of rests");
  const double rate = median_rate_hz(samples);
  if (!(rate > 0.0))
    throw std::invalid_argument("rest detection: the samples share one stamp (no sample rate)");
  RestDetection out;
  out.rate_hz = rate;
  out.block_samples = block_samples_for(options.block_s, rate);
  out.quiet_std = quiet_std_of(samples, out.block_samples, options.quiet_quantile);
  // The rests as rows of the dwell assembler, through the detected dwell source (one path from
  // samples to rows for gimbal runs and tumbles alike, docs/design.md section 2).
  DwellAssembler assembler;
  DetectedDwellSource source(&assembler, options, rate);
  source.set_quiet_std(out.quiet_std);
  for (const ImuSample& s : samples) {
    // The source would drop a sample that is not finite (as a live stream does); a file with
    // one is bad input.
    if (!std::isfinite(s.stamp_s) || !s.outputs.allFinite())
      throw std::invalid_argument("rest detection: a sample is not finite");
    const CompletedRows rows = source.add_sample(s);
    out.rests.insert(out.rests.end(), rows.begin(), rows.end());
  }
  const CompletedRows last = source.finish();
  out.rests.insert(out.rests.end(), last.begin(), last.end());
  out.rejected = source.detector().rejected();
  std::sort(out.rejected.begin(), out.rejected.end(),
            [](const RejectedSpan& a, const RejectedSpan& b) { return a.t_start_s < b.t_start_s; });
  out.samples = samples.size();
  out.t_start_s = samples.front().stamp_s;
  out.t_end_s = samples.back().stamp_s;
  return out;
}

}  // namespace core
}  // namespace accel_intrinsics
