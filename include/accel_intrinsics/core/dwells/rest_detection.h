// Rests found in a raw accelerometer stream (docs/design.md section 11): the dwell source of a hand
// tumble, where no gimbal says when the device is still.
//
// The stream is cut into blocks of `block_s`. A block is still when, on every axis, its standard
// deviation stays below `still_factor` times the stream's quiet standard deviation (learned from
// its quietest blocks) and its mean moves less than `mean_step_factor` standard errors from the
// previous block's (a slow turn has a small standard deviation but a moving mean). A run of still
// blocks, trimmed by `trim_s` at both ends, is a rest when it lasts `min_rest_s`. A short
// disturbance inside a rest (a jolt, a brief shake) is cut out and the two sides joined when
// their means agree; a rest whose mean creeps (slow turn, a device settling on a soft surface) is
// rejected. Every rejected span is listed with its reason.
//
// RestDetector is the streaming form (the calibration node's tumble mode): samples in, rests out
// as each one ends. detect_rests() is the batch form (offline_fit): it learns the quiet level from
// the whole stream first, then runs the same detector with it fixed. Both are O(1) per sample.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <limits>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/position_table.h"

namespace accel_intrinsics {
namespace core {

struct RestDetectionOptions {
  double min_rest_s = 2.0;  // shortest rest kept (after trimming)
  double block_s = 0.25;    // block of the moving statistics
  double trim_s = 0.25;     // dropped at both ends of a rest (settling, the hand letting go)
  // A block is still when its std is below still_factor x the quiet std on every axis ...
  double still_factor = 3.0;
  // ... and its mean differs from the previous block's by less than mean_step_factor standard
  // errors of that difference (quiet std x sqrt(2 / block samples)).
  double mean_step_factor = 8.0;
  // A disturbance up to merge_gap_s long between two still runs whose means agree within
  // mean_step_factor standard errors is cut out and the runs joined (a jolt inside one rest).
  double merge_gap_s = 1.0;
  // A rest whose first and last thirds differ by more than creep_factor standard errors is a
  // slow motion, not a rest.
  double creep_factor = 15.0;
  // The quiet std is this quantile of all block stds (batch) or of the blocks so far (stream).
  double quiet_quantile = 0.05;
  // Samples further apart than gap_factor x the sample interval end a run (a gap in the stream).
  double gap_factor = 5.0;
};

// Throws std::invalid_argument naming the field.
void validate(const RestDetectionOptions& options);

struct RejectedSpan {
  double t_start_s = 0.0;
  double t_end_s = 0.0;
  std::string reason;
};

// What detect_rests found, and the levels it used (stated in the result).
struct RestDetection {
  std::vector<DwellRecord> rests;  // orientation_unknown rows, in time order
  std::vector<RejectedSpan> rejected;
  Eigen::Vector3d quiet_std = Eigen::Vector3d::Zero();  // per axis, output units
  double rate_hz = 0.0;
  std::uint64_t block_samples = 0;
  std::uint64_t samples = 0;
  double t_start_s = 0.0;
  double t_end_s = 0.0;
};

// Mean, sample count and M2 of a run of samples (Chan's parallel update joins two).
struct BlockStatistics {
  std::uint64_t n = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d m2 = Eigen::Vector3d::Zero();
  double t_first_s = 0.0;
  double t_last_s = 0.0;
  void add(double t_s, const Eigen::Vector3d& x);
  void join(const BlockStatistics& later);
  Eigen::Vector3d sample_std() const;
};

class RestDetector {
 public:
  // rate_hz > 0: the nominal sample rate; 0: estimated from the first samples.
  explicit RestDetector(const RestDetectionOptions& options = {}, double rate_hz = 0.0);

  // Fixes the quiet std (batch mode); otherwise it is learned from the blocks seen so far.
  void set_quiet_std(const Eigen::Vector3d& quiet_std);

  // Samples in time order. Throws std::invalid_argument for a stamp that goes back.
  void add(double t_s, const Eigen::Vector3d& outputs);
  // The stream ended: the last run is judged.
  void finish();

  // Rests completed since the last call (in time order), moved out.
  std::vector<DwellRecord> take_rests();
  // Every rejected span so far.
  const std::vector<RejectedSpan>& rejected() const { return rejected_; }
  Eigen::Vector3d quiet_std() const { return quiet_std_; }
  double rate_hz() const { return rate_hz_; }
  std::uint64_t block_samples() const { return block_n_; }
  std::uint64_t samples() const { return samples_; }
  // Seconds of the run of still blocks in progress (0 when moving): live guidance.
  double current_still_s() const;

 private:
  struct Run {
    std::vector<BlockStatistics> blocks;  // still blocks, contiguous
    double t_start_s = 0.0;
    double t_end_s = 0.0;
    std::vector<RejectedSpan> cut;  // disturbances cut out of this run
  };
  void start_blocks();
  void close_block();
  bool block_is_still(const BlockStatistics& block) const;
  void end_run();
  void settle_pending();
  void emit(Run&& run);
  Eigen::Vector3d learned_quiet_std() const;
  double join_window_s() const;

  RestDetectionOptions options_;
  double rate_hz_ = 0.0;
  std::uint64_t block_n_ = 0;
  bool quiet_fixed_ = false;
  Eigen::Vector3d quiet_std_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d resolution_ = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  std::vector<double> block_std_history_[3];                 // stream mode: for the quiet quantile
  std::vector<std::pair<double, Eigen::Vector3d>> startup_;  // samples before the rate is known
  std::uint64_t samples_ = 0;
  double last_t_s_ = -std::numeric_limits<double>::infinity();
  Eigen::Vector3d last_x_ = Eigen::Vector3d::Zero();
  BlockStatistics block_;
  bool have_previous_block_ = false;
  Eigen::Vector3d previous_block_mean_ = Eigen::Vector3d::Zero();
  bool in_run_ = false;
  Run run_;
  bool have_pending_ = false;
  Run pending_;
  double moving_since_s_ = 0.0;
  std::vector<DwellRecord> completed_;
  std::vector<RejectedSpan> rejected_;
  std::uint32_t next_index_ = 0;
};

// Batch: the quiet std from the quiet_quantile of all block stds, then RestDetector with it.
// Throws std::invalid_argument for fewer than 10 samples or stamps that go back.
RestDetection detect_rests(const std::vector<ImuSample>& samples,
                           const RestDetectionOptions& options = {});

// The quiet std of a stream: the quiet_quantile of its block stds per axis, floored at half
// an output step (quantized outputs whose quiet blocks read constant).
Eigen::Vector3d quiet_std_of(const std::vector<ImuSample>& samples, std::uint64_t block_samples,
                             double quantile);

// A recorded stream in time order, as the dwell assembler would have it: sorted by stamp (stable),
// an exact repeat (same stamp and values) kept once, a second sample at a stamp with other values
// dropped (a device clock that went back). Returns what it removed.
struct StreamCleanup {
  std::uint64_t reordered = 0;    // samples that arrived before an earlier-stamped one
  std::uint64_t duplicates = 0;   // exact repeats removed
  std::uint64_t conflicting = 0;  // same stamp, other values: dropped
};
StreamCleanup put_in_time_order(std::vector<ImuSample>* samples);

// Median sample rate of a stream (1 / median interval); 0 for fewer than two samples.
double median_rate_hz(const std::vector<ImuSample>& samples);

}  // namespace core
}  // namespace accel_intrinsics
