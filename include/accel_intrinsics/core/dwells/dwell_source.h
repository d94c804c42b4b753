// Where dwells begin and end: one seam, two sources, both feeding the one DwellAssembler (and so
// the same rows for the run and the pipeline; docs/design.md sections 2 and 11).
//
//   commanded  the gimbal's MOVING / SETTLED / DONE commands bound the dwells (a gimbal run):
//              everything goes to the assembler as it comes.
//   detected   rests found in the IMU stream itself (RestDetector; a hand tumble, no gimbal):
//              samples wait until the detector has judged them; each rest then reaches the
//              assembler as a SETTLED at its first sample and a MOVING just after its last, with
//              its samples in between (a disturbance the detector cut out of a rest is left out
//              the same way, and the two sides are joined into one row again). Its rows are of
//              unknown orientation (phase "-"), numbered in time order, and equal the detector's
//              rests (the same samples; sums in another order).
//
// A source takes the streams in time order (the detected one needs it; the commanded one accepts
// the assembler's reorder window) and returns the rows each call completed.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/rest_detection.h"

namespace accel_intrinsics {
namespace core {

class DwellSource {
 public:
  // The source feeds `assembler` (not owned; it must outlive the source).
  explicit DwellSource(DwellAssembler* assembler) : assembler_(assembler) {}
  virtual ~DwellSource() = default;
  DwellSource(const DwellSource&) = delete;
  DwellSource& operator=(const DwellSource&) = delete;

  virtual const char* name() const = 0;  // "commanded" or "detected"
  virtual CompletedRows add_command(const GimbalEvent& event) = 0;
  virtual CompletedRows add_sample(const ImuSample& sample) = 0;
  virtual CompletedRows add_channel_sample(const ChannelSample& reading) = 0;
  // The streams ended: everything still held is judged and the assembler flushed.
  virtual CompletedRows finish() = 0;

  const DwellAssembler& assembler() const { return *assembler_; }

 protected:
  DwellAssembler* assembler_;
};

// Gimbal commands bound the dwells: the assembler gets every input as it comes.
class CommandedDwellSource : public DwellSource {
 public:
  using DwellSource::DwellSource;
  const char* name() const override { return "commanded"; }
  CompletedRows add_command(const GimbalEvent& event) override;
  CompletedRows add_sample(const ImuSample& sample) override;
  CompletedRows add_channel_sample(const ChannelSample& reading) override;
  CompletedRows finish() override;
};

// Rests found in the stream bound the dwells (RestDetector, streaming). Gimbal commands have no
// place here: they are ignored and counted (commands_ignored()).
class DetectedDwellSource : public DwellSource {
 public:
  // rate_hz: as RestDetector's (0: estimated from the first samples).
  DetectedDwellSource(DwellAssembler* assembler, const RestDetectionOptions& options,
                      double rate_hz = 0.0);
  const char* name() const override { return "detected"; }
  CompletedRows add_command(const GimbalEvent& event) override;
  // Throws std::invalid_argument for a stamp that goes back (as RestDetector::add).
  CompletedRows add_sample(const ImuSample& sample) override;
  CompletedRows add_channel_sample(const ChannelSample& reading) override;
  CompletedRows finish() override;

  // The quiet level of the stream when it is known beforehand (the batch detect_rests measures
  // it on the whole record first); else the detector learns it as it goes.
  void set_quiet_std(const Eigen::Vector3d& quiet_std) { detector_.set_quiet_std(quiet_std); }
  const RestDetector& detector() const { return detector_; }
  std::uint64_t commands_ignored() const { return commands_ignored_; }

 private:
  // Hands the detector's new rests to the assembler with the samples held up to each.
  CompletedRows release_rests();
  // Held samples (and channel readings) with stamps below `stamp_s` go to the assembler.
  void release_until(double stamp_s, CompletedRows* rows);
  void command(GimbalState state, double stamp_s, std::uint32_t step, CompletedRows* rows);

  RestDetector detector_;
  std::deque<ImuSample> held_;               // samples since the last released rest
  std::deque<ChannelSample> held_readings_;  // channel readings, likewise
  std::uint64_t commands_ignored_ = 0;
};

}  // namespace core
}  // namespace accel_intrinsics
