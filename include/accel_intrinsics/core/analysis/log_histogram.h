// Counts of positive values in log-spaced buckets (a relative width of 0.5 %), in constant memory:
// the clock check's motion values of the still stretches it no longer keeps bin by bin, for the
// median of its noise floor (clock_check.h).
#pragma once

#include <cstdint>
#include <vector>

namespace accel_intrinsics {
namespace core {

class LogHistogram {
 public:
  LogHistogram();
  void add(double value);  // values <= 0 count as 0; out of [1e-20, 1e6] clamp to the ends
  void clear();
  std::uint64_t count() const { return count_; }
  // The value of rank `rank` (0-based, ascending): the geometric middle of its bucket, 0 for the
  // zeros. rank < count().
  double at_rank(std::uint64_t rank) const;
  // The value of rank `rank` of this histogram's values merged with `sorted` (ascending, exact).
  double at_rank_with(const std::vector<double>& sorted, std::uint64_t rank) const;
  std::size_t memory_bytes() const;

 private:
  std::size_t bucket(double value) const;
  double value_of(std::size_t bucket) const;

  std::vector<std::uint32_t> counts_;  // [0]: zeros, then the log-spaced buckets
  std::uint64_t count_ = 0;
};

}  // namespace core
}  // namespace accel_intrinsics
