// The gimbal controller's parameters, read once (a bad one stops the node with a ParamError that
// names it; config/*_gimbal.yaml documents the drivers'), and the gimbal backend they name.
#include <cmath>
#include <stdexcept>

#include "accel_intrinsics/drivers/grbl_driver.h"
#include "accel_intrinsics/drivers/smc100_driver.h"
#include "accel_intrinsics/ros/gimbal_controller_node.h"
#include "accel_intrinsics/ros/params.h"

namespace accel_intrinsics {

namespace {

// ~<driver>/...: the serial gimbal and its per-phase axis map.
void read_serial_options(const ros::NodeHandle& pnh, const std::string& driver,
                         GimbalControllerOptions* o) {
  const ros::NodeHandle dn(pnh, driver);
  SerialGimbalOptions& s = o->serial;
  s.baud = driver == "smc100" ? 57600 : 115200;
  s.settle_s = o->protocol.settle_s;
  read_param(dn, "port", &s.port);
  read_param(dn, "baud", &s.baud);
  s.xon_xoff = driver == "smc100";
  read_param(dn, "xon_xoff", &s.xon_xoff);
  read_param(dn, "connect_timeout_s", &s.connect_timeout_s);
  read_param(dn, "reply_timeout_s", &s.reply_timeout_s);
  read_param(dn, "poll_interval_s", &s.poll_interval_s);
  read_param(dn, "tolerance_deg", &s.tolerance_deg);
  read_param(dn, "settle_s", &s.settle_s);
  read_param(dn, "home_at_start", &s.home_at_start);
  read_param(dn, "home_timeout_s", &s.home_timeout_s);
  read_param(dn, "unlock_at_start", &s.unlock_at_start);
  read_param(dn, "reset_at_start", &s.reset_at_start);
  for (int p = 0; p < 3; ++p) {
    const std::string key = std::string("phases/") + "xyz"[p];
    if (!dn.hasParam(key)) {
      throw ParamError("parameter " + param_name(dn, key) + " is missing: the axis map of phase " +
                       "xyz"[p] + " (see config/" + driver + "_gimbal.yaml)");
    }
    const ros::NodeHandle ph(dn, key);
    PhaseAxes& axes = s.axis_map.phases[p];
    XmlRpc::XmlRpcValue axis;
    if (ph.getParam("axis", axis)) {
      if (axis.getType() == XmlRpc::XmlRpcValue::TypeString) {
        axes.axis = static_cast<std::string>(axis);
      } else if (axis.getType() == XmlRpc::XmlRpcValue::TypeInt) {
        axes.axis = std::to_string(static_cast<int>(axis));
      } else {
        throw ParamError("parameter " + param_name(ph, "axis") +
                         " must be an axis letter (grbl) or a controller address (smc100)");
      }
    }
    read_param(ph, "sign", &axes.sign);
    read_param(ph, "zero_deg", &axes.zero_deg);
    read_param(ph, "manual_remount", &axes.manual_remount);
    XmlRpc::XmlRpcValue hold;
    if (ph.getParam("hold", hold)) {
      if (hold.getType() != XmlRpc::XmlRpcValue::TypeStruct) {
        throw ParamError("parameter " + param_name(ph, "hold") +
                         " must be a map axis: position_deg ({Y: 90.0})");
      }
      for (auto it = hold.begin(); it != hold.end(); ++it) {
        const XmlRpc::XmlRpcValue& v = it->second;
        if (v.getType() == XmlRpc::XmlRpcValue::TypeDouble) {
          axes.hold[it->first] = static_cast<double>(const_cast<XmlRpc::XmlRpcValue&>(v));
        } else if (v.getType() == XmlRpc::XmlRpcValue::TypeInt) {
          axes.hold[it->first] = static_cast<int>(const_cast<XmlRpc::XmlRpcValue&>(v));
        } else {
          throw ParamError("parameter " + param_name(ph, "hold/" + it->first) +
                           " must be a number (deg)");
        }
      }
    }
  }
  try {
    s.validate();
    s.axis_map.validate({});
  } catch (const std::invalid_argument& e) {
    throw ParamError("parameter " + dn.getNamespace() + "/" + e.what());
  }
}

}  // namespace

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
  require(o.driver == "simulated" || o.driver == "grbl" || o.driver == "smc100", pnh, "driver",
          "unknown gimbal driver '" + o.driver + "' (known: simulated, grbl, smc100)");
  if (o.driver != "simulated") read_serial_options(pnh, o.driver, &o);
  read_param(pnh, "world_frame", &o.world_frame);
  read_param(pnh, "gimbal_frame", &o.gimbal_frame);
  read_param(pnh, "dut_frame", &o.dut_frame);
  require(!o.world_frame.empty(), pnh, "world_frame", "must not be empty");
  require(!o.gimbal_frame.empty(), pnh, "gimbal_frame", "must not be empty");
  require(!o.dut_frame.empty(), pnh, "dut_frame", "must not be empty");

  // The simulated gimbal: by default it moves and settles in the protocol's times.
  const ros::NodeHandle sim(pnh, "simulated");
  o.simulated.move_s = o.protocol.move_s;
  o.simulated.settle_s = o.protocol.settle_s;
  o.simulated.phase_change_s = o.protocol.phase_change_s;
  read_param(sim, "move_s", &o.simulated.move_s);
  read_param(sim, "settle_s", &o.simulated.settle_s);
  read_param(sim, "phase_change_s", &o.simulated.phase_change_s);
  read_param(sim, "ringing_rad", &o.simulated.ringing_rad);
  read_param(sim, "ringing_hz", &o.simulated.ringing_hz);
  read_effects(sim, "effects", &o.simulated.effects);
  read_param(sim, "never_settle_phase", &o.simulated.never_settle_phase);
  read_param(sim, "never_settle_at_step", &o.simulated.never_settle_at_step);
  try {
    o.simulated.validate();
  } catch (const std::invalid_argument& e) {
    throw ParamError("parameter " + sim.getNamespace() + "/" + e.what());
  }
  return o;
}

std::unique_ptr<GimbalDriver> make_gimbal_driver(const GimbalControllerOptions& options) {
  if (options.driver == "simulated") {
    return std::unique_ptr<GimbalDriver>(new SimulatedGimbalDriver(options.simulated));
  }
  // A serial gimbal that cannot be brought up (port missing, no reply, alarm at start) keeps the
  // node from starting, with the device's words.
  try {
    if (options.driver == "grbl") {
      return std::unique_ptr<GimbalDriver>(new GrblDriver(options.serial));
    }
    if (options.driver == "smc100") {
      return std::unique_ptr<GimbalDriver>(new Smc100Driver(options.serial));
    }
  } catch (const GimbalFault& e) {
    throw ParamError(std::string("the gimbal did not start: ") + e.what());
  }
  throw ParamError("unknown gimbal driver '" + options.driver + "'");
}

}  // namespace accel_intrinsics
