// ClockCheck's still stretches (clock_check.h, "Memory"): a rest summarized as it arrives.
#include <algorithm>
#include <cmath>
#include <iterator>

#include "accel_intrinsics/core/analysis/clock_check.h"

namespace accel_intrinsics {
namespace core {

std::int64_t ClockCheck::block_bins() const {
  return static_cast<std::int64_t>(std::max(1.0, std::round(options_.block_s / options_.bin_s)));
}

const ClockCheck::Bin* ClockCheck::find_bin(std::int64_t k) const {
  const std::int64_t c = (k >= 0 ? k : k - (kChunkBins - 1)) / kChunkBins;
  const auto chunk = chunks_.find(c);
  if (chunk != chunks_.end()) return &chunk->second[static_cast<std::size_t>(k - c * kChunkBins)];
  auto it = stills_.upper_bound(k);
  if (it == stills_.begin()) return nullptr;
  const Still& s = std::prev(it)->second;
  const auto edge = static_cast<std::int64_t>(s.head.size());
  if (k > s.last) return nullptr;
  if (k < s.first + edge) return &s.head[static_cast<std::size_t>(k - s.first)];
  if (k > s.last - edge) return &s.tail[static_cast<std::size_t>(k - (s.last - edge + 1))];
  return nullptr;  // in the middle: summed
}

bool ClockCheck::add_to_still(std::int64_t k, const Eigen::Vector3d& outputs) {
  auto it = stills_.upper_bound(k);
  if (it == stills_.begin()) return false;
  Still& s = std::prev(it)->second;
  if (k > s.last) return false;
  const auto edge = static_cast<std::int64_t>(s.head.size());
  Bin* bin = nullptr;
  if (k < s.first + edge) bin = &s.head[static_cast<std::size_t>(k - s.first)];
  if (k > s.last - edge) bin = &s.tail[static_cast<std::size_t>(k - (s.last - edge + 1))];
  if (bin == nullptr) {
    s.middle_sum += outputs;
    ++s.middle_n;
    return true;
  }
  if (bin->n == 0) ++bins_used_;
  bin->sum += outputs;
  ++bin->n;
  return true;
}

void ClockCheck::collapse_before(std::int64_t newest) {
  // A chunk is complete when samples reach two chunks later (they arrive nearly in order: a
  // reorder window is far shorter than a chunk); its last boundaries need the next chunk's bins.
  for (auto it = chunks_.lower_bound(next_evaluated_chunk_);
       it != chunks_.end() && it->first <= newest - 2;) {
    const auto next = std::next(it);
    try_collapse(it);
    it = next;
  }
  next_evaluated_chunk_ = std::max(next_evaluated_chunk_, newest - 1);
}

void ClockCheck::try_collapse(std::map<std::int64_t, Chunk>::iterator chunk) {
  const std::int64_t edge = block_bins();
  if (4 * edge > kChunkBins) return;  // blocks too long for a chunk: keep every bin
  const std::int64_t c0 = chunk->first * kChunkBins;
  // Bins c0 - edge .. c0 + kChunkBins + edge - 2: the blocks either side of the chunk's boundaries
  // c0 .. c0 + kChunkBins - 1, as result() computes its motion signal.
  const std::int64_t width = kChunkBins + 2 * edge - 1;
  std::vector<Eigen::Vector3d> cum_sum(static_cast<std::size_t>(width + 1),
                                       Eigen::Vector3d::Zero());
  std::vector<double> cum_n(static_cast<std::size_t>(width + 1), 0.0);
  for (std::int64_t i = 0; i < width; ++i) {
    const Bin* bin = find_bin(c0 - edge + i);
    const auto j = static_cast<std::size_t>(i);
    cum_sum[j + 1] = cum_sum[j] + (bin != nullptr ? bin->sum : Eigen::Vector3d::Zero());
    cum_n[j + 1] = cum_n[j] + (bin != nullptr ? static_cast<double>(bin->n) : 0.0);
  }
  std::vector<double> motion(static_cast<std::size_t>(kChunkBins), -1.0);  // -1: a gap
  for (std::int64_t b = 0; b < kChunkBins; ++b) {
    const auto lo = static_cast<std::size_t>(b), mid = lo + static_cast<std::size_t>(edge),
               hi = mid + static_cast<std::size_t>(edge);
    const double n_before = cum_n[mid] - cum_n[lo], n_after = cum_n[hi] - cum_n[mid];
    if (n_before <= 0.0 || n_after <= 0.0) continue;
    const Eigen::Vector3d before = (cum_sum[mid] - cum_sum[lo]) / n_before;
    const Eigen::Vector3d after = (cum_sum[hi] - cum_sum[mid]) / n_after;
    motion[static_cast<std::size_t>(b)] = (after - before).cwiseAbs().sum();
  }
  // The noise floor so far, as result() takes it from the whole run.
  const bool floor_known = all_motion_.count() >= 2 * static_cast<std::uint64_t>(kChunkBins);
  for (double m : motion) {
    if (m >= 0.0) all_motion_.add(m);
  }
  if (!floor_known) return;
  const Eigen::Vector3d level = total_sum_ / std::max(1.0, static_cast<double>(samples_));
  const double floor =
      std::max(3.0 * all_motion_.at_rank(all_motion_.count() / 2), 1e-9 * (1.0 + level.norm()));
  // A rest's noise rises above the floor now and then (a boundary in a few hundred): those few
  // values are kept as they are (result() takes them as motion); more of them, or a gap, is no
  // rest: its bins are kept.
  std::size_t loud = 0;
  for (double m : motion) {
    if (m < 0.0) return;
    if (m > floor) ++loud;
  }
  if (loud > kMaxLoud) return;
  auto add_motion = [&](Still& s, std::int64_t b) {
    const double m = motion[static_cast<std::size_t>(b)];
    if (m > floor) {
      s.loud.emplace_back(c0 + b, m);
    } else {
      still_motion_.add(m);
    }
  };
  const Chunk& bins = chunk->second;
  const auto e = static_cast<std::size_t>(edge), n = static_cast<std::size_t>(kChunkBins);
  auto add_middle = [](Still& s, const Bin& bin) {
    s.middle_sum += bin.sum;
    s.middle_n += bin.n;
  };
  auto before = stills_.lower_bound(c0);
  Still* joined = nullptr;
  if (before != stills_.begin() && std::prev(before)->second.last == c0 - 1)
    joined = &std::prev(before)->second;
  if (joined != nullptr) {  // the rest goes on: its old tail and this chunk join the middle
    for (const Bin& bin : joined->tail) add_middle(*joined, bin);
    for (std::size_t i = 0; i + e < n; ++i) add_middle(*joined, bins[i]);
    joined->tail.assign(bins.end() - static_cast<std::ptrdiff_t>(e), bins.end());
    joined->last = c0 + kChunkBins - 1;
    for (std::int64_t b = 0; b < kChunkBins; ++b) add_motion(*joined, b);
  } else {
    Still s;
    s.first = c0;
    s.last = c0 + kChunkBins - 1;
    s.head.assign(bins.begin(), bins.begin() + static_cast<std::ptrdiff_t>(e));
    s.tail.assign(bins.end() - static_cast<std::ptrdiff_t>(e), bins.end());
    for (std::size_t i = e; i + e < n; ++i) add_middle(s, bins[i]);
    for (std::int64_t b = 1; b < kChunkBins; ++b) add_motion(s, b);  // boundary c0 stays exact
    stills_.emplace(c0, std::move(s));
  }
  if (last_chunk_ == chunk) last_chunk_ = chunks_.end();
  chunks_.erase(chunk);
}

}  // namespace core
}  // namespace accel_intrinsics
