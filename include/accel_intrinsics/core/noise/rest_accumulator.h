// The long rest's statistics accumulated as its samples arrive (docs/design.md sections 8 and
// 12; docs/noise.md "The long rest in constant memory"): what the noise model of a run needs
// (noise_model_of_run), in memory that does not grow with the rate or the rest's length. One
// accumulator for the live run (LongRestRecorder, fed by the dwell assembler in stamp order) and
// for offline_fit (noise_model_of_run on a recorded stream), so both give the same model.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/dwell_record.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace core {

// The cluster sizes of every Allan curve: about `points_per_decade` per decade,
// round(10^(i / points_per_decade)) for i = 0, 1, ..., each once, up to max_m.
std::vector<std::size_t> allan_cluster_sizes(std::size_t max_m, int points_per_decade);
constexpr int kAllanPointsPerDecade = 10;

// The overlapping Allan variance of overlapping_allan_deviation (noise.h) at the cluster sizes
// allan_cluster_sizes(n / 4, kAllanPointsPerDecade), computed as the samples arrive: the same
// terms (cluster pairs starting every max(1, m / 16) samples), summed in a different order, so
// the figures agree to rounding. Memory: for each cluster size m, the terms under way (those
// whose 2 m samples are not all in yet, at most 2 m / stride + 1: 63 for m < 32, at most 36
// above), and the last 64 cumulative sums; about 80 cluster sizes for 10^7 samples (a size is
// opened when the record reaches m / 16 samples, log-many). The cumulative sums are taken about
// the first sample, in long double, so that their second differences keep the precision the
// mean-removed batch sums have.
class StreamingAllan {
 public:
  void add(const Eigen::Vector3d& x);
  std::size_t samples() const { return n_; }
  // The curve of the samples so far at rate_hz, equal to overlapping_allan_deviation(samples,
  // rate_hz, kAllanPointsPerDecade). Throws std::invalid_argument for fewer than 16 samples or a
  // rate that is not positive.
  AllanCurve curve(double rate_hz) const;
  void clear();
  // Bytes held (the test of constant memory and the docs' figure).
  std::size_t memory_bytes() const;

 private:
  using Sums = std::array<long double, 3>;
  struct Cluster {
    std::size_t m = 0, stride = 1;
    std::size_t next = 0;               // the next index at which the cluster acts (stride > 1)
    std::size_t m_mod = 0, m2_mod = 0;  // m mod stride, 2 m mod stride
    std::vector<Sums> pending;          // terms under way, a ring by term number
    std::size_t started = 0, halfway = 0, done = 0;  // term counters
    Sums sum{};                                      // of the squared second differences
  };
  void open_clusters_up_to(std::size_t index);
  void at_index(std::size_t index);

  std::size_t n_ = 0;
  Eigen::Vector3d offset_ = Eigen::Vector3d::Zero();  // the first sample
  Sums theta_{};                                      // sum of (x - offset) so far
  static constexpr std::size_t kHistory = 64;  // last cumulative sums (clusters with stride 1)
  std::array<Sums, kHistory> history_{};
  std::vector<Cluster> clusters_;
  int next_grid_i_ = 0;  // next i of round(10^(i / 10)) to open
  std::size_t last_opened_m_ = 0;
};

// One long rest: its samples' stamps and outputs, in stamp order.
//  - the Allan curve of its outputs (StreamingAllan) at the rate (n - 1) / (last - first);
//  - its blocks (rest_blocks(): kRestBlocks blocks of equal duration over [first, last] stamp,
//    fewer when they would be shorter than 1 s). The length is not known while the rest streams,
//    so the samples go into fine sub-blocks of equal duration (at most kSubBlocks; when a sample
//    falls beyond them, neighbours are merged pairwise and the duration doubles); at the end each
//    sub-block joins the block that holds its samples' middle stamp. A block is then its whole
//    sub-blocks: its mean, std, n and first and last stamps are exactly those of the samples in
//    [t_start_s, t_end_s], and its edges lie within one sub-block (span / kSubBlocks to 2 span /
//    kSubBlocks, 3 % to 6 % of a block) of the equal-duration edges.
// Memory: kSubBlocks x 72 bytes (74 kB) plus StreamingAllan's (about 0.1 MB), about 0.2 MB at any
// rate and length. 1024 sub-blocks, not more: a block's mean, std, n and stamps are exact whatever
// the sub-block count; only its edges move (the slow-part fit takes each block at its own stamps).
class RestAccumulator {
 public:
  static constexpr std::size_t kSubBlocks = 1024;
  // Samples must come in stamp order (non-decreasing); others throw std::invalid_argument.
  void add(double stamp_s, const Eigen::Vector3d& outputs);
  std::size_t samples() const { return allan_.samples(); }
  double first_stamp_s() const { return first_s_; }
  double last_stamp_s() const { return last_s_; }
  // Duration of a sub-block now.
  double sub_block_s() const { return width_s_; }
  // (n - 1) / (last - first); 0 with fewer than two samples or no span.
  double rate_hz() const;
  std::vector<DwellRecord> rest_blocks() const;
  // The Allan curve of the outputs at rate_hz() (throws as StreamingAllan::curve).
  AllanCurve allan_curve() const { return allan_.curve(rate_hz()); }
  // The noise model of the rest (estimate_noise_model's fit on the streamed Allan curve) with its
  // rest_blocks and rest_samples; nothing with fewer than 64 samples or no span; throws
  // std::invalid_argument as estimate_noise_model does (shorter than 10 s). The caller fills
  // source, rest_t_start_s and rest_t_end_s.
  std::optional<NoiseModel> noise_model() const;
  void clear();
  std::size_t memory_bytes() const;

 private:
  struct SubBlock {
    std::uint64_t n = 0;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    Eigen::Vector3d m2 = Eigen::Vector3d::Zero();
    double t_first = 0.0, t_last = 0.0;
    void add(double t, const Eigen::Vector3d& x);
    void merge(const SubBlock& o);
  };
  StreamingAllan allan_;
  double first_s_ = 0.0, last_s_ = 0.0;
  double width_s_ = 0.0;
  double per_width_ = 0.0;  // 1 / width_s_
  std::vector<SubBlock> sub_;
};

// The long rest of a live run (docs/design.md section 12), accumulated as it comes: fed every
// gimbal event and sample in stamp order (from DwellAssembler::set_release_observers, as
// MoveSampleRecorder), it feeds a RestAccumulator with the samples of the run's first dwell: from
// the first SETTLED plus settle_discard_s (the dwell's t_start_s, as the assembler sets it) to
// the next command (its t_end_s; a sample stamped with that command still belongs to it). Every
// sample of the rest is used, at any rate and length, in constant memory. clear() when the run
// starts over.
class LongRestRecorder {
 public:
  explicit LongRestRecorder(double settle_discard_s = 0.0) : settle_discard_s_(settle_discard_s) {}
  void set_settle_discard_s(double s) { settle_discard_s_ = s; }
  void add_command(const GimbalEvent& event);
  void add_sample(const ImuSample& sample);
  void clear();
  std::size_t samples() const { return rest_.samples(); }
  const RestAccumulator& rest() const { return rest_; }
  std::size_t memory_bytes() const { return sizeof(*this) - sizeof(rest_) + rest_.memory_bytes(); }
  // The noise model of the run's long rest (find_long_rest(table, initial_rest_s)) when it is
  // the first dwell this recorder saw whole (its span covers the rest's row and every sample
  // accumulated lies in the row); nothing otherwise. Throws as
  // RestAccumulator::noise_model.
  std::optional<NoiseModel> noise_model(const PositionTable& table, double initial_rest_s) const;
  // Whether the long rest of `table` is the dwell this recorder accumulated whole (noise_model
  // then gives its model, or nothing when it has too few samples).
  bool holds_long_rest(const PositionTable& table, double initial_rest_s) const;

 private:
  enum class Stage { BeforeRest, InRest, After };
  double settle_discard_s_;
  Stage stage_ = Stage::BeforeRest;
  double start_s_ = 0.0;  // SETTLED + settle_discard_s
  double end_s_ = 0.0;    // the command that ended the rest
  RestAccumulator rest_;
};

// The model of a long rest from its accumulated samples: RestAccumulator::noise_model with the
// rest's source and span.
std::optional<NoiseModel> noise_model_of_rest(const RestAccumulator& rest, const LongRest& span);

}  // namespace core
}  // namespace accel_intrinsics
