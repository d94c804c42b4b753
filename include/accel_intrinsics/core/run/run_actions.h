// What a calibration run asks of its shell (calibration_run.h): the actions every input returns.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace core {

// What the run asks of the gimbal controller (ResumeAt, Abort).
struct ControllerRequest {
  Phase phase = Phase::X;
  std::uint32_t step = 0;
  int approach = +1;   // direction the position is approached from (-1: return sweep)
  bool after = false;  // continue at the position after (phase, step, approach)
  std::string reason;
  std::uint64_t run_generation = 0;  // replies to a request of a reset run are ignored
};

struct RunAction {
  enum class Kind {
    DwellAccepted,    // row: append it to the checkpointed position table
    Log,              // level, text
    CheckpointState,  // write checkpoint_state()
    ClearCheckpoint,  // remove the checkpoint files (a new run starts)
    FitNow,           // fit table() (with recorded_moves() for the timing lag)
    ResumeAt,         // request: call gimbal_controller/resume, then on_resume_reply()
    Abort,            // request.reason: call gimbal_controller/abort
  };
  enum class Level { Info, Warn, Error };
  Kind kind = Kind::Log;
  Level level = Level::Info;
  std::string text;
  bool repeating = false;     // Log of a counter that may grow fast (drops): throttle it
  DwellRecord row;            // DwellAccepted
  ControllerRequest request;  // ResumeAt, Abort
  // FitNow: what to fit (a copy: the run may move on before the shell fits), the recorded
  // moves (record_moves) and the ticket to hand back to fit_may_publish / on_fit_finished.
  PositionTable table;
  std::vector<GimbalEvent> move_commands;
  std::vector<ImuSample> move_samples;
  AssemblerCounters counters;  // of the run at the fit (the result's "samples" block)
  // FitNow: the noise model of the run's long rest, to weight the fit and the analysis with
  // (core::with_noise_model); none: white.
  std::optional<NoiseModel> noise_model;
  std::uint64_t fit_ticket = 0;
};
using RunActions = std::vector<RunAction>;

}  // namespace core
}  // namespace accel_intrinsics
