// The long rest: found in a run's table, recorded live, cut into blocks and turned into a noise
// model (noise.h).
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

}  // namespace core
}  // namespace accel_intrinsics
