// Helpers shared by the files of CalibrationRun (calibration_run.h). Not installed.
#pragma once

#include <cstdint>
#include <sstream>
#include <string>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {
namespace run_detail {

inline std::string position_label(Phase phase, std::uint32_t step, int approach) {
  std::ostringstream s;
  s << "phase " << phase_name(phase) << " step " << step;
  if (approach < 0) s << " (return sweep)";
  return s.str();
}

inline void add_counters(const AssemblerCounters& from, AssemblerCounters* to) {
  to->samples_used += from.samples_used;
  to->dropped_outside_dwell += from.dropped_outside_dwell;
  to->dropped_settle_discard += from.dropped_settle_discard;
  to->dropped_non_finite += from.dropped_non_finite;
  to->dropped_backwards += from.dropped_backwards;
  to->duplicates += from.duplicates;
  to->dropped_late += from.dropped_late;
  to->commands += from.commands;
  for (std::size_t c = 0; c < kChannelCount; ++c) {
    to->channel_used[c] += from.channel_used[c];
    to->channel_dropped[c] += from.channel_dropped[c];
  }
  to->commands_out_of_order += from.commands_out_of_order;
  if (to->last_warning.empty()) to->last_warning = from.last_warning;
}

}  // namespace run_detail
}  // namespace core
}  // namespace accel_intrinsics
