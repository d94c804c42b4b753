#include "accel_intrinsics/core/model/protocol.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "accel_intrinsics/core/model/constants.h"

namespace accel_intrinsics {
namespace core {

const char* phase_name(Phase p) {
  switch (p) {
    case Phase::X: return "x";
    case Phase::Y: return "y";
    case Phase::Z: return "z";
  }
  return "?";
}

bool parse_phase(const std::string& text, Phase* phase) {
  if (text == "x" || text == "X") {
    *phase = Phase::X;
    return true;
  }
  if (text == "y" || text == "Y") {
    *phase = Phase::Y;
    return true;
  }
  if (text == "z" || text == "Z") {
    *phase = Phase::Z;
    return true;
  }
  return false;
}

const char* accelerometer_name(int accelerometer) {
  static const char* const kNames[] = {"u", "v", "w"};
  return (accelerometer >= 0 && accelerometer < 3) ? kNames[accelerometer] : "?";
}

double step_angle(std::uint32_t step, std::uint32_t steps) {
  return 2.0 * kPi * static_cast<double>(step) / static_cast<double>(steps);
}

namespace {
void require_time(double value, const char* name, bool allow_zero) {
  if (!std::isfinite(value) || value < 0.0 || (!allow_zero && value == 0.0)) {
    throw std::invalid_argument(std::string("protocol: ") + name + " must be a finite " +
                                (allow_zero ? "non-negative" : "positive") +
                                " number of seconds, got " + std::to_string(value));
  }
}
}  // namespace

void validate(const ProtocolOptions& options) {
  if (options.steps_per_phase < 3) {
    throw std::invalid_argument(
        "protocol: steps_per_phase must be at least 3 (the fit has three unknowns per "
        "accelerometer and phase), got " +
        std::to_string(options.steps_per_phase));
  }
  require_time(options.move_s, "move_s", true);
  require_time(options.settle_s, "settle_s", true);
  require_time(options.dwell_s, "dwell_s", false);
  require_time(options.phase_change_s, "phase_change_s", true);
  require_time(options.initial_rest_s, "initial_rest_s", true);
  // two_way and closing_position combine freely: the closing position tops the up-sweep.
}

std::uint32_t scheduled_positions_per_phase(const ProtocolOptions& options) {
  const std::uint32_t n = options.steps_per_phase;
  return n * (options.two_way ? 2u : 1u) + (options.closing_position ? 1u : 0u);
}

double dwell_duration_s(const ProtocolOptions& options, std::size_t index) {
  return index == 0 ? std::max(options.dwell_s, options.initial_rest_s) : options.dwell_s;
}

std::vector<ScheduledPosition> build_schedule(const ProtocolOptions& options) {
  validate(options);
  const std::uint32_t n = options.steps_per_phase;
  // The visit order of one phase: (step, approach).
  std::vector<std::pair<std::uint32_t, int>> visits;
  for (std::uint32_t i = 0; i < n; ++i) visits.emplace_back(i, +1);
  // The closing position continues the up-sweep to 2 pi, so it is approached from below.
  if (options.closing_position) visits.emplace_back(n, +1);
  // The return sweep approaches every position from above (after the closing position it comes
  // down from 2 pi; without it the controller overshoots before its first return position), so
  // backlash shows as a two-valued angle error.
  if (options.two_way) {
    for (std::uint32_t i = 0; i < n; ++i) visits.emplace_back(n - 1 - i, -1);
  }
  std::vector<ScheduledPosition> schedule;
  schedule.reserve(kNumPhases * visits.size());
  double t = 0.0;
  for (Phase phase : kPhases) {
    bool first_of_phase = true;
    for (const auto& visit : visits) {
      ScheduledPosition position;
      position.phase = phase;
      position.step = visit.first;
      position.steps = n;
      position.angle_rad = step_angle(position.step, n);
      position.approach = visit.second;
      position.move_start_s = t;
      t += first_of_phase ? options.phase_change_s : options.move_s;
      t += options.settle_s;
      position.settled_s = t;
      t += dwell_duration_s(options, schedule.size());
      position.dwell_end_s = t;
      schedule.push_back(position);
      first_of_phase = false;
    }
  }
  return schedule;
}

}  // namespace core
}  // namespace accel_intrinsics
