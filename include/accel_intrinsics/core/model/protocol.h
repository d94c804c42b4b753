// The rotation protocol (docs/design.md section 1): phases x, y, z, N positions each, and the
// specific force eq. (4) of docs/design.md's reference [1] assigns to a commanded angle.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace accel_intrinsics {
namespace core {

enum class Phase : std::uint8_t { X = 0, Y = 1, Z = 2 };
constexpr int kNumPhases = 3;
constexpr Phase kPhases[kNumPhases] = {Phase::X, Phase::Y, Phase::Z};

inline int index(Phase p) {
  return static_cast<int>(p);
}
// "x", "y", "z".
const char* phase_name(Phase p);
// Accepts "x"/"y"/"z" (and upper case); returns false otherwise.
bool parse_phase(const std::string& text, Phase* phase);
// "u", "v", "w" for accelerometer 0, 1, 2.
const char* accelerometer_name(int accelerometer);

// Unit specific-force direction in the DUT frame for phase p at true angle alpha, eq. (4):
//   x: (0, sin a, cos a)   y: (sin a, 0, cos a)   z: (sin a, cos a, 0)
// Templated so the same definition serves the simulator and autodiff fits.
template <typename T>
Eigen::Matrix<T, 3, 1> in_plane_direction(Phase p, const T& alpha) {
  using std::cos;
  using std::sin;
  const T s = sin(alpha);
  const T c = cos(alpha);
  const T zero(0.0);
  switch (p) {
    case Phase::X: return Eigen::Matrix<T, 3, 1>(zero, s, c);
    case Phase::Y: return Eigen::Matrix<T, 3, 1>(s, zero, c);
    case Phase::Z:
    default: return Eigen::Matrix<T, 3, 1>(s, c, zero);
  }
}

// Commanded angle of step n of N: alpha_n = 2 pi n / N. Step N is the closing position at 2 pi
// (ProtocolOptions::closing_position); the angle is not wrapped, so an angle-scale error there is
// eps * 2 pi.
double step_angle(std::uint32_t step, std::uint32_t steps);

// Steps 0..N-1 are the sweep; step N (= steps) is the closing position at 2 pi.
inline bool is_closing_step(std::uint32_t step, std::uint32_t steps) {
  return steps > 0 && step == steps;
}
// Whether (step, steps) can come from build_schedule(): steps > 0 and step <= steps.
inline bool step_in_protocol(std::uint32_t step, std::uint32_t steps) {
  return steps > 0 && step <= steps;
}

// Timing and shape of a protocol run. All times in seconds.
struct ProtocolOptions {
  std::uint32_t steps_per_phase = 24;  // N
  double move_s = 1.0;                 // time the gimbal takes to move one step
  double settle_s = 0.5;               // wait after the move before SETTLED
  double dwell_s = 2.0;                // SETTLED to next MOVING
  double phase_change_s = 5.0;         // remount / reorient between phases (within MOVING)
  bool two_way = false;                // sweep up then back down (reveals backlash)
  // After the up-sweep of each phase, visit step N at 2 pi: the 0 deg orientation again, one turn
  // and most of the phase's time later, approached from below (+1). There a drift has changed the
  // outputs by d * dt, an angle offset reads as at 0 deg and an angle-scale error has grown to
  // eps * 2 pi: the experiment the discrepancy analysis proposes to tell them apart, and the
  // position with the most information on the angle scale. With two_way the closing position is
  // the top of the up-sweep, before the turn: 0..N-1, N, then N-1..0 from above; appending it
  // after the return sweep (which ends at 0) would need a full extra turn up and back.
  bool closing_position = false;
  // A long rest at the first position (phase x, step 0) before the sweep: that dwell lasts
  // max(dwell_s, initial_rest_s). From it the noise model is estimated (white density and the
  // slow part, docs/design.md section 12; noise.h find_long_rest). 0 (default): no long rest.
  double initial_rest_s = 0.0;
};

// Throws std::invalid_argument naming the offending field.
void validate(const ProtocolOptions& options);

// How long the dwell at position `index` of the schedule lasts: the first one (the long rest)
// max(dwell_s, initial_rest_s), every other one dwell_s. The schedule, the simulator and the
// gimbal controller all hold the dwells this long.
double dwell_duration_s(const ProtocolOptions& options, std::size_t index);

// One visit of the gimbal: where it goes and, on the nominal timeline, when.
struct ScheduledPosition {
  Phase phase = Phase::X;
  std::uint32_t step = 0;
  std::uint32_t steps = 0;
  double angle_rad = 0.0;
  int approach = +1;        // +1: approached from below (increasing angle), -1: from above
  double move_start_s = 0;  // MOVING stamp, relative to the run start
  double settled_s = 0;     // SETTLED stamp
  double dwell_end_s = 0;   // next MOVING or DONE stamp
};

// Positions visited per phase: N, plus N for two_way, plus 1 for closing_position.
std::uint32_t scheduled_positions_per_phase(const ProtocolOptions& options);

// The full visit order: phase x, y, z; in each, steps 0..N-1, then step N at 2 pi when
// closing_position, then back N-1..0 when two_way. Times start at 0 with the first MOVING, every
// position (the closing one too) takes one move, settle and dwell. Used by the gimbal controller
// and the simulator alike.
std::vector<ScheduledPosition> build_schedule(const ProtocolOptions& options);

}  // namespace core
}  // namespace accel_intrinsics
