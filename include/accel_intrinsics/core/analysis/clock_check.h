// Do the IMU and the gimbal stamp on one clock? (docs/design.md section 5.) A DUT that turns
// changes its outputs while the gimbal moves, so the motion seen in the IMU stream must fall inside
// the gimbal's MOVING -> SETTLED intervals. ClockCheck collects a compact summary of both streams
// (IMU bin sums of `bin_s`, the gimbal's commands) and finds the shift of the IMU stamps:
//  1. coarse: the shifts that put most of the IMU motion inside the moves (every shift that lets
//     the streams overlap; periodic moves make shifts by whole steps almost as good);
//  2. among those, the one whose dwell means fit the rig model best (a shift by a step assigns
//     every dwell the wrong angle);
//  3. fine: the median, over the step moves, of the motion's centroid minus the move's midpoint;
//     then the motion's edges in each move (where `edge_share` of it has passed, and where
//     1 - edge_share has). When the motion fills the moves (its start as far after MOVING as its
//     end before SETTLED, within fill_share of a move: raised cosine, trapezoid), the centroid
//     shift is the offset. When it takes only part of them (a servo that overshoots and settles,
//     a settle timer, SETTLED reported late), the middle says nothing: the gimbal starts turning
//     when it reports MOVING, so the offset is the motion's start minus MOVING (median over the
//     moves), named from max(onset_tolerance_s, onset_duration_share x the motion's duration) up
//     (how quickly a motion starts is not known).
// A shift of `min_offset_s` or more is an unsynchronized clock: the run must not be fitted.
// Smaller lags are the timing-lag analysis' job (raw_stream_analysis.h). A centroid shift, or an
// onset shift whose onsets scatter between moves by more than onset_spread_s (a head turned by
// hand), is reported only if it moves motion out of the dwells (min_gain).
//
// Memory: one bin (32 bytes) per `bin_s` of IMU time (100 per second by default, 3.2 kB per second
// of the run), whatever the IMU rate, in chunks of kChunkBins consecutive bins: a stream that
// jumps between epochs costs one chunk per stretch, not the bins in between. A still stretch (a
// rest) is not kept bin by bin: once a chunk's motion (step 1's signal, computed as the chunk
// completes) stays below the noise floor seen so far at every bin boundary, the chunk joins the
// still stretch before it, which keeps its first and last block of bins (so the motion next to it
// is the same), the sum of the bins between, and their motion values in a LogHistogram (for the
// noise floor's median). A rest of any length then costs the same few kB.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "accel_intrinsics/core/analysis/log_histogram.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"

namespace accel_intrinsics {
namespace core {

struct ClockCheckOptions {
  double bin_s = 0.01;  // resolution of the offset found
  // Motion is the change between the mean outputs of two adjacent blocks of this length: long
  // enough to rise above the noise, short against a move.
  double block_s = 0.1;
  double min_offset_s = 0.05;
  double min_rate_hz = 20.0;  // sparser IMU streams are not checked  // smaller shifts pass (timing
                              // lag, filter delay)
  // The IMU motion must follow the moves: at the best shift at least this share of it lies
  // inside them, or the check cannot tell (a DUT that does not turn, a table of other data).
  double min_explained = 0.5;
  // An offset must put at least this share of the motion more inside the (unpadded) step moves
  // than none: the motion it would otherwise leave in the dwells. A gimbal that reports SETTLED a
  // delay after it stops looks like an IMU clock half that delay early, but all its motion lies
  // inside the moves: it passes.
  double min_gain = 0.01;
  // Coarse shifts explaining at least (1 - alias_tolerance) x the best are compared by fit.
  double alias_tolerance = 0.1;
  // The motion's edges in a move: where this share of its motion has passed (and 1 - this).
  double edge_share = 0.02;
  // The motion fills the moves when its mean gap to MOVING and to SETTLED is at most this share
  // of the typical step move; else the offset is taken from where the motion starts.
  double fill_share = 0.2;
  // An offset found from the motion's start is named from this size up: the edge share is reached
  // a little after the motion begins (about 0.1 of a raised-cosine move), a little before for a
  // sudden start (the motion signal spreads over +-block_s).
  double onset_tolerance_s = 0.15;
  // ... and from this share of the motion's duration (edge to edge) up: a slow start (raised
  // cosine) reaches the edge share about 0.4 of that duration after it begins.
  double onset_duration_share = 0.7;
  // Onsets (start minus MOVING) scattering more than this between moves (median absolute
  // deviation) come from the gimbal, not a clock: then min_gain decides.
  double onset_spread_s = 0.1;
  // Longest stretch of IMU time summarized (bins beyond it are not allocated): a guard against a
  // stream that jumps between epochs.
  double max_span_s = 2.0e5;
};

struct ClockCheckResult {
  bool checked = false;         // enough moves and IMU motion to tell
  std::string not_checked_why;  // when !checked
  bool offset_found = false;
  // IMU stamp minus gimbal time of the same instant: positive = IMU stamps later. Shift the IMU
  // stamps by -offset_s (--imu-time-offset) to fix it.
  double offset_s = 0.0;
  double explained_at_zero = 0.0;  // share of the IMU motion inside the moves, unshifted
  double explained_at_offset = 0.0;
  double best_shift_s = 0.0;  // the shift found, also when too small to matter
  double gain = 0.0;          // motion share gained inside the unpadded moves by that shift
  // Step 3's edges (medians over the step moves, on the gimbal's clock + the IMU's offset):
  double start_gap_s = 0.0;         // motion start minus MOVING
  double end_gap_s = 0.0;           // SETTLED minus motion end
  bool motion_fills_moves = false;  // the centroid shift was used, else the start's
  // When offset_found: "IMU stamps are 5.00 s later than the gimbal's: clocks not synchronized;
  // pass <fix_option> -5.00" (fix_option given to message()).
  std::string message(const std::string& fix_option) const;
};

class ClockCheck {
 public:
  explicit ClockCheck(const ClockCheckOptions& options = {});

  void add_command(const GimbalEvent& event);
  void add_sample(const ImuSample& sample);
  void reset();

  ClockCheckResult result() const;
  // Bytes held (bins and commands): the test of memory per second of the run.
  std::size_t memory_bytes() const;
  static constexpr std::int64_t kChunkBins = 256;

 private:
  struct Bin {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    std::uint64_t n = 0;
  };
  using Chunk = std::vector<Bin>;  // kChunkBins bins from its key x kChunkBins
  // Bins [first, last] of a rest: the first and last `block` bins kept, the sum of those between.
  struct Still {
    std::int64_t first = 0, last = 0;
    Chunk head, tail;
    Eigen::Vector3d middle_sum = Eigen::Vector3d::Zero();
    std::uint64_t middle_n = 0;
    // Its boundaries whose motion rose above the noise floor so far, with that motion.
    std::vector<std::pair<std::int64_t, double>> loud;
  };
  static constexpr std::size_t kMaxLoud = 16;  // per chunk, for a chunk to join a still stretch

  std::int64_t block_bins() const;
  // The bin k, if kept (in a chunk, or a still stretch's head or tail); nullptr else.
  const Bin* find_bin(std::int64_t k) const;
  // A sample for bin k, if k lies in a still stretch (a late one): true when taken.
  bool add_to_still(std::int64_t k, const Eigen::Vector3d& outputs);
  // Evaluate the chunks complete by now (before chunk `newest` - 1): join the still ones.
  void collapse_before(std::int64_t newest);
  void try_collapse(std::map<std::int64_t, Chunk>::iterator chunk);

  ClockCheckOptions options_;
  std::vector<GimbalEvent> commands_;
  bool have_origin_ = false;
  double origin_s_ = 0.0;  // bins count from the first IMU stamp
  std::map<std::int64_t, Chunk> chunks_;
  std::map<std::int64_t, Chunk>::iterator last_chunk_;
  std::uint64_t bins_used_ = 0;                // bins with a sample
  std::int64_t first_bin_ = 0, last_bin_ = 0;  // the lowest and highest with one
  std::uint64_t samples_ = 0;
  std::uint64_t bins_refused_ = 0;
  Eigen::Vector3d total_sum_ = Eigen::Vector3d::Zero();
  std::map<std::int64_t, Still> stills_;  // by first bin
  std::int64_t newest_chunk_ = 0;
  std::int64_t next_evaluated_chunk_ = 0;
  LogHistogram still_motion_;  // motion at the boundaries inside still stretches
  LogHistogram all_motion_;    // at every boundary evaluated: the noise floor so far
};

}  // namespace core
}  // namespace accel_intrinsics
