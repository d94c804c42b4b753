#include "accel_intrinsics/core/analysis/log_histogram.h"

#include <algorithm>
#include <cmath>

namespace accel_intrinsics {
namespace core {

namespace {
constexpr double kLogWidth = 0.005;                 // log of the ratio between adjacent buckets
constexpr double kLogLowest = -46.0517018598809;    // log(1e-20)
constexpr double kLogHighest = 13.815510557964274;  // log(1e6)
const std::size_t kBuckets = static_cast<std::size_t>((kLogHighest - kLogLowest) / kLogWidth) + 1;
}  // namespace

LogHistogram::LogHistogram() : counts_(kBuckets + 1, 0) {}

void LogHistogram::clear() {
  std::fill(counts_.begin(), counts_.end(), 0u);
  count_ = 0;
}

std::size_t LogHistogram::bucket(double value) const {
  if (!(value > 0.0)) return 0;
  const double i = std::floor((std::log(value) - kLogLowest) / kLogWidth);
  if (i < 0.0) return 1;
  if (i >= static_cast<double>(kBuckets)) return kBuckets;
  return static_cast<std::size_t>(i) + 1;
}

double LogHistogram::value_of(std::size_t bucket) const {
  if (bucket == 0) return 0.0;
  return std::exp(kLogLowest + (static_cast<double>(bucket - 1) + 0.5) * kLogWidth);
}

void LogHistogram::add(double value) {
  ++counts_[bucket(value)];
  ++count_;
}

double LogHistogram::at_rank(std::uint64_t rank) const {
  return at_rank_with({}, rank);
}

double LogHistogram::at_rank_with(const std::vector<double>& sorted, std::uint64_t rank) const {
  std::uint64_t passed = 0;
  std::size_t i = 0;  // next of `sorted`
  for (std::size_t b = 0; b < counts_.size(); ++b) {
    if (counts_[b] == 0) continue;
    const double value = value_of(b);
    for (; i < sorted.size() && sorted[i] < value; ++i) {
      if (passed++ == rank) return sorted[i];
    }
    passed += counts_[b];
    if (passed > rank) return value;
  }
  for (; i < sorted.size(); ++i) {
    if (passed++ == rank) return sorted[i];
  }
  return sorted.empty() ? 0.0 : sorted.back();
}

std::size_t LogHistogram::memory_bytes() const {
  return sizeof(*this) + counts_.capacity() * sizeof(std::uint32_t);
}

}  // namespace core
}  // namespace accel_intrinsics
