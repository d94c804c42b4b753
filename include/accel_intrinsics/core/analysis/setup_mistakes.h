// Setup mistakes (docs/design.md section 15): a stand wired or configured wrongly, named before
// any physical effect. One home for the judgement behind `supervise --check-mount` (six pose
// means, mount_check.h) and behind the analysis and the quality gate on a finished run (a
// position table).
//
// The judgement compares, per phase, the outputs' response at alpha = 0 and at alpha = 90 deg with
// docs/design.md section 1 (eq. 4: phase x reads +z at 0 and +y at 90 deg, phase y +z and +x,
// phase z +y and +x), the DUT frame being the IMU's own axes (S near the identity, a MEMS triad
// within a few degrees of them). Each response is snapped to the nearest signed DUT axis; the
// turn from the 0 deg to the 90 deg response is a rotation about the axis n = d0 x d90:
//  - n opposite to section 1's: axis_sign[p] (phase p turns the wrong way);
//  - n along another DUT axis: axes_swapped[p] (phase p turns the DUT about that axis);
//  - n right but the 0 deg response elsewhere: zero_offset[p] (alpha = 0 is not where eq. 4 has
//  it);
//  - a response between axes or no turn at all: pose_unclear[p].
// And for the whole stand: imu_silent (no samples), imu_motionless (no phase turns the readings:
// a simulated gimbal with a real IMU, or an IMU not on the gimbal), output_unit (gravity reads
// |f| near 1: g, not m/s^2; far above 20: counts).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/quality.h"
#include "accel_intrinsics/core/model/constants.h"

namespace accel_intrinsics {
namespace core {

struct SetupMistake {
  std::string name;           // axis_sign, axes_swapped, zero_offset, pose_unclear, imu_motionless,
                              // output_unit, imu_silent
  std::string target;         // the phase ("x", "y", "z") for the per-phase mistakes, else empty
  std::string finding;        // what was seen
  std::string fix;            // what to change, in the axis map or the launch
  std::string label() const;  // "axis_sign[y]", "output_unit"
  std::string text() const;   // "axis_sign[y]: <finding>; fix: <fix>"
};

// One phase's response: the outputs at alpha = 0 and at alpha = 90 deg (output unit). For a
// finished run the harmonic fit's cos and sin parts (offsets removed); for a mount check the pose
// means themselves.
struct PhaseResponse {
  bool present = false;
  Eigen::Vector3d at_0 = Eigen::Vector3d::Zero();
  Eigen::Vector3d at_90 = Eigen::Vector3d::Zero();
  Eigen::Vector3d level = Eigen::Vector3d::Zero();  // what does not turn (offsets; the mount
                                                    // check: the mean of the two poses)
};

struct SetupObservation {
  std::array<PhaseResponse, 3> phases;
  // |g| in the output unit as the readings show it (the mean magnitude of the turning part).
  double gravity_in_outputs = 0.0;
  // Silent poses or dwells, as "phase x at 90 deg" (empty: every one had samples).
  std::vector<std::string> silent;
  bool all_silent = false;
};

struct SetupOptions {
  double local_gravity = kStandardGravity;  // m/s^2
  // Unit of the outputs the calibration is told (docs/design.md section 6). Only "m/s^2" is
  // checked against |g|: any other unit is the user's word.
  std::string output_unit = "m/s^2";
  // In m/s^2, |g| in the outputs must lie in [min, max] x g: the gate's responsivity range.
  double min_gravity_ratio = 0.5;
  double max_gravity_ratio = 2.0;
  // A response is on a DUT axis when within this angle of it, deg: a MEMS triad on its fixture is
  // within a few degrees; 35 deg leaves room for a crooked fixture and large offsets.
  double axis_tolerance_deg = 35.0;
  // The IMU does not move: in every phase the turning part is below this fraction of |g| seen in
  // the level (a 90 deg turn changes the reading by sqrt(2) |g|).
  double motionless_fraction = 0.05;
  // A finished run: geometry mistakes are named only when the table read as the mistake says fits
  // at least this many times better (chi-square, or the sum of squares when the table has no
  // standard deviations) than the table as labelled. A setup mistake leaves residuals of the
  // order of g against noise of the order of 1e-3 g; a rotated but correct mount fits both ways
  // equally (ratio 1) and is never named.
  double confirm_ratio = 25.0;
};

// The judgement. Order: imu_silent, imu_motionless, output_unit, then per phase x, y, z.
std::vector<SetupMistake> judge_setup(const SetupObservation& observation,
                                      const SetupOptions& options = {});

// A finished run (rows with phase and angle; rows with known directions or unknown orientations
// are not judged). Per phase with at least 3 distinct angles: outputs = level + at_0 cos(alpha) +
// at_90 sin(alpha) by least squares; then judge_setup, and a geometry mistake is kept only when
// the confirmation (SetupOptions::confirm_ratio) holds.
std::vector<SetupMistake> detect_setup_mistakes(const PositionTable& table,
                                                const SetupOptions& options = {});
SetupObservation observe_run(const PositionTable& table);

// The second opinion that needs no gimbal angles (docs/design.md section 11).
extern const char* const kUnknownOrientationsAdvice;

// The analysis (discrepancy.h analyze) tests the setup mistakes first: with one found it fills
// result->setup_mistakes, the base fit and its gap, a stop_reason that names them, and returns
// true: no physical effect is screened on a run read wrongly. False (result untouched but for
// the empty setup_mistakes) otherwise.
struct AnalysisOptions;
struct AnalysisResult;
bool stop_analysis_on_setup_mistakes(const PositionTable& table, const AnalysisOptions& options,
                                     AnalysisResult* result);

// The quality gate's reasons (quality.h) on a failed run that shows a setup mistake: the
// mistakes, each with its fix, and kUnknownOrientationsAdvice, in place of the symptoms they
// cause (a chi-square far above its band, responsivities outside their range). A passing
// quality, or one without a setup mistake, is left as it is.
void name_setup_mistakes(const PositionTable& table, const SetupOptions& options, Quality* quality);

}  // namespace core
}  // namespace accel_intrinsics
