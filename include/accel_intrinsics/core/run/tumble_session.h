// A live hand tumble (docs/design.md section 11, the calibration node's mode: tumble): samples in,
// rests found as they end (the detected dwell source: RestDetector feeding the dwell assembler,
// core/dwell_source.h), and after each rest the progress a person turning the device needs: the
// rests so far, the coverage, the current relative uncertainties and the next pose to try; the fit
// when asked or when every relative uncertainty is below a target. ROS-free; the node
// (ros/tumble_calibration_node.h) is a shell around it.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_source.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/dwells/rest_detection.h"
#include "accel_intrinsics/core/fit/tumble.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/noise/rest_accumulator.h"
#include "accel_intrinsics/core/run/calibrate.h"

namespace accel_intrinsics {
namespace core {

struct TumbleSessionOptions {
  RestDetectionOptions rests;
  double local_gravity = kStandardGravity;
  std::size_t min_rests = 10;
  // Fit automatically once the coverage is complete and every relative uncertainty
  // (relative_uncertainties()) is at or below this; 0: only when asked.
  double target_relative_std = 0.0;
};

// Throws std::invalid_argument naming the field.
void validate(const TumbleSessionOptions& options);

struct TumbleProgress {
  std::size_t rests = 0;
  std::size_t rejected = 0;
  std::uint64_t samples = 0;
  double still_s = 0.0;   // how long the device has been still now
  bool fitted = false;    // enough rests, and they determine the intrinsics
  std::string fit_error;  // why not, when rests >= min_rests but the fit failed
  std::optional<TumbleCoverage> coverage;
  std::vector<RelativeUncertainty> relative;
  double largest_relative_std = std::numeric_limits<double>::quiet_NaN();
  std::string largest_name;
  // The pose to try next: from the Fisher information once fitted, before that the next axis
  // direction of a fixed sequence (each axis up and down, then the diagonals).
  Eigen::Vector3d next_up = Eigen::Vector3d::UnitZ();
  std::string next_pose_words;
  bool target_reached = false;
  std::string message;  // one line for the person holding the device
};

class TumbleSession {
 public:
  explicit TumbleSession(const TumbleSessionOptions& options);
  TumbleSession(const TumbleSession&) = delete;  // its source points at its assembler
  TumbleSession& operator=(const TumbleSession&) = delete;

  // One sample in time order; a sample whose stamp goes back is dropped and counted. Returns
  // true when a rest ended with it (the progress changed).
  bool add_sample(double t_s, const Eigen::Vector3d& outputs);
  // The stream ended: the last rest is judged. Returns true when it added one.
  bool finish();
  void reset();

  const TumbleProgress& progress() const { return progress_; }
  // The rests so far as a table (rows of unknown orientation).
  const PositionTable& table() const { return table_; }
  const RestDetector& detector() const { return source_->detector(); }
  std::uint64_t dropped_out_of_order() const { return dropped_; }
  // The noise model of the first rest when it is the session's long rest (at least 30 s:
  // core::find_long_rest, as offline_fit finds it in a recorded tumble), from its samples
  // accumulated as they came (rest_accumulator.h); none (white) otherwise. A person starts with the
  // long rest.
  std::optional<NoiseModel> noise_model() const;

  // The whole pipeline on the rests so far (core::calibrate), weighted with noise_model();
  // throws FitError as fit() does.
  CalibrationReport report(const CalibrateOptions& options) const;

 private:
  bool take_new_rests(const CompletedRows& rests);
  void update_progress();
  void start();  // a fresh source, assembler and long-rest recorder

  TumbleSessionOptions options_;
  DwellAssembler assembler_;
  std::unique_ptr<DetectedDwellSource> source_;  // feeds assembler_
  LongRestRecorder long_rest_;                   // fed by assembler_ in stamp order
  PositionTable table_;
  TumbleProgress progress_;
  std::uint64_t dropped_ = 0;
  double last_t_s_ = -std::numeric_limits<double>::infinity();
};

}  // namespace core
}  // namespace accel_intrinsics
