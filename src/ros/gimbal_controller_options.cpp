// The gimbal controller's parameters, read once (a bad one stops the node with a ParamError that
// names it; config/*_gimbal.yaml documents the drivers'), and the gimbal backend they name.
#include <cmath>
#include <stdexcept>

#include "accel_intrinsics/drivers/gimbal_driver_table.h"
#include "accel_intrinsics/ros/gimbal_controller_node.h"
#include "accel_intrinsics/ros/params.h"
#include "accel_intrinsics/ros/ros_driver_params.h"

namespace accel_intrinsics {

GimbalControllerOptions GimbalControllerOptions::load(const ros::NodeHandle& pnh) {
  GimbalControllerOptions o;
  o.protocol = read_protocol(pnh);
  read_param(pnh, "autostart", &o.autostart);
  read_param(pnh, "start_delay_s", &o.start_delay_s);
  require(std::isfinite(o.start_delay_s) && o.start_delay_s >= 0.0, pnh, "start_delay_s",
          "must be finite and >= 0 s");
  read_param(pnh, "tick_hz", &o.tick_hz);
  require(std::isfinite(o.tick_hz) && o.tick_hz >= 1.0 && o.tick_hz <= 10000.0, pnh, "tick_hz",
          "must be in [1, 10000] Hz");
  read_param(pnh, "progress_hz", &o.progress_hz);
  require(std::isfinite(o.progress_hz) && o.progress_hz > 0.0, pnh, "progress_hz",
          "must be > 0 Hz");
  read_param(pnh, "settle_timeout_s", &o.settle_timeout_s);
  require(std::isfinite(o.settle_timeout_s) && o.settle_timeout_s > 0.0, pnh, "settle_timeout_s",
          "must be > 0 s");
  read_param(pnh, "resume_phase", &o.resume_phase);
  require(o.resume_phase.empty() || o.resume_phase == "x" || o.resume_phase == "y" ||
              o.resume_phase == "z",
          pnh, "resume_phase", "must be x, y or z (or empty: from the start)");
  read_param(pnh, "resume_step", &o.resume_step);
  // Step N is the closing position at 2 pi, part of the schedule only with closing_position.
  require(o.resume_step < o.protocol.steps_per_phase ||
              (o.protocol.closing_position && o.resume_step == o.protocol.steps_per_phase),
          pnh, "resume_step",
          "must be below steps (" + std::to_string(o.protocol.steps_per_phase) + ")" +
              (o.protocol.closing_position ? ", or equal to it (the closing position)" : ""));
  read_param(pnh, "resume_approach", &o.resume_approach);
  require(o.resume_approach == 1 || o.resume_approach == -1, pnh, "resume_approach",
          "must be +1 (up sweep) or -1 (return sweep)");
  require(o.resume_approach == 1 || o.protocol.two_way, pnh, "resume_approach",
          "-1 needs two_way: true");
  require(o.resume_approach == 1 || o.resume_step < o.protocol.steps_per_phase, pnh,
          "resume_approach", "the closing position is only approached from below (+1)");
  read_param(pnh, "driver", &o.driver);
  const GimbalDriverRow* row = find_gimbal_driver(o.driver);
  require(row != nullptr, pnh, "driver",
          "unknown gimbal driver '" + o.driver + "' (known: " + gimbal_driver_names() + ")");
  GimbalDriverDefaults defaults;
  defaults.move_s = o.protocol.move_s;
  defaults.settle_s = o.protocol.settle_s;
  defaults.phase_change_s = o.protocol.phase_change_s;
  try {
    o.driver_options = row->read_options(RosDriverParams(pnh), defaults);
  } catch (const std::invalid_argument& e) {
    throw ParamError(e.what());
  }
  read_param(pnh, "world_frame", &o.world_frame);
  read_param(pnh, "gimbal_frame", &o.gimbal_frame);
  read_param(pnh, "dut_frame", &o.dut_frame);
  require(!o.world_frame.empty(), pnh, "world_frame", "must not be empty");
  require(!o.gimbal_frame.empty(), pnh, "gimbal_frame", "must not be empty");
  require(!o.dut_frame.empty(), pnh, "dut_frame", "must not be empty");

  return o;
}

std::unique_ptr<GimbalDriver> make_gimbal_driver(const GimbalControllerOptions& options) {
  const GimbalDriverRow* row = find_gimbal_driver(options.driver);
  if (row == nullptr) {
    throw ParamError("unknown gimbal driver '" + options.driver +
                     "' (known: " + gimbal_driver_names() + ")");
  }
  // A gimbal that cannot be brought up (port missing, no reply, alarm at start) keeps the node
  // from starting, with the device's words.
  try {
    return row->make(options.driver_options);
  } catch (const GimbalFault& e) {
    throw ParamError(std::string("the gimbal did not start: ") + e.what());
  } catch (const std::bad_any_cast&) {
    throw ParamError("the options of gimbal driver '" + options.driver + "' were not read");
  }
}

}  // namespace accel_intrinsics
