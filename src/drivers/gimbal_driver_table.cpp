// The gimbal driver table (gimbal_driver_table.h): one row per driver, with its options reader.
#include "accel_intrinsics/drivers/gimbal_driver_table.h"

#include <stdexcept>

#include "accel_intrinsics/drivers/grbl_driver.h"
#include "accel_intrinsics/drivers/manual_gimbal.h"
#include "accel_intrinsics/drivers/ros_joint_gimbal.h"
#include "accel_intrinsics/drivers/smc100_driver.h"

namespace accel_intrinsics {

namespace {

// A driver's validate() text ("tolerance_deg must be > 0") prefixed with its namespace.
template <typename Options>
void validated(const DriverParams& params, const std::string& driver, const Options& o) {
  try {
    o.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("parameter " + params.name(driver) + "/" + e.what());
  }
}

std::any read_simulated(const DriverParams& params, const GimbalDriverDefaults& d) {
  SimulatedGimbalOptions o;
  o.move_s = d.move_s;
  o.settle_s = d.settle_s;
  o.phase_change_s = d.phase_change_s;
  params.get("simulated/move_s", &o.move_s);
  params.get("simulated/settle_s", &o.settle_s);
  params.get("simulated/phase_change_s", &o.phase_change_s);
  params.get("simulated/ringing_rad", &o.ringing_rad);
  params.get("simulated/ringing_hz", &o.ringing_hz);
  params.get_effects("simulated/effects", &o.effects);
  params.get("simulated/never_settle_phase", &o.never_settle_phase);
  params.get("simulated/never_settle_at_step", &o.never_settle_at_step);
  validated(params, "simulated", o);
  return o;
}

// ~grbl/... and ~smc100/...: the serial gimbal and its axis map.
SerialGimbalOptions read_serial(const DriverParams& params, const GimbalDriverDefaults& d,
                                const std::string& driver, int baud, bool xon_xoff) {
  SerialGimbalOptions s;
  s.baud = baud;
  s.xon_xoff = xon_xoff;
  s.settle_s = d.settle_s;
  const std::string k = driver + "/";
  params.get(k + "port", &s.port);
  params.get(k + "baud", &s.baud);
  params.get(k + "xon_xoff", &s.xon_xoff);
  params.get(k + "connect_timeout_s", &s.connect_timeout_s);
  params.get(k + "reply_timeout_s", &s.reply_timeout_s);
  params.get(k + "poll_interval_s", &s.poll_interval_s);
  params.get(k + "tolerance_deg", &s.tolerance_deg);
  params.get(k + "settle_s", &s.settle_s);
  params.get(k + "home_at_start", &s.home_at_start);
  params.get(k + "home_timeout_s", &s.home_timeout_s);
  params.get(k + "unlock_at_start", &s.unlock_at_start);
  params.get(k + "reset_at_start", &s.reset_at_start);
  s.axis_map = read_axis_map(params, driver);
  validated(params, driver, s);
  try {
    s.axis_map.validate({});
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("parameter " + params.name(driver) + "/" + e.what());
  }
  return s;
}

std::any read_ros_joint(const DriverParams& params, const GimbalDriverDefaults& d) {
  RosJointOptions o;
  o.settle_s = d.settle_s;
  params.get("ros_joint/joint_states_topic", &o.joint_states_topic);
  for (const std::string& axis : params.keys("ros_joint/axes")) {
    RosJointAxis a;
    const std::string k = "ros_joint/axes/" + axis + "/";
    params.get(k + "joint", &a.joint);
    params.get(k + "command_topic", &a.command_topic);
    o.axes[axis] = a;
  }
  params.get("ros_joint/tolerance_deg", &o.tolerance_deg);
  params.get("ros_joint/settle_s", &o.settle_s);
  params.get("ros_joint/move_timeout_s", &o.move_timeout_s);
  params.get("ros_joint/joint_state_timeout_s", &o.joint_state_timeout_s);
  o.axis_map = read_axis_map(params, "ros_joint");
  validated(params, "ros_joint", o);
  return o;
}

std::any read_manual(const DriverParams& params, const GimbalDriverDefaults&) {
  ManualGimbalOptions o;
  params.get("manual/pose_tolerance_deg", &o.pose_tolerance_deg);
  params.get("manual/check_s", &o.check_s);
  int min_samples = static_cast<int>(o.min_samples);
  params.get("manual/min_samples", &min_samples);
  if (min_samples < 1)
    throw std::invalid_argument("parameter " + params.name("manual/min_samples") + " must be >= 1");
  o.min_samples = static_cast<std::size_t>(min_samples);
  params.get("manual/imu_topic", &o.imu_topic);
  o.axis_map = read_axis_map(params, "manual");
  validated(params, "manual", o);
  return o;
}

template <typename Driver, typename Options>
std::unique_ptr<GimbalDriver> make(const std::any& options) {
  return std::unique_ptr<GimbalDriver>(new Driver(std::any_cast<const Options&>(options)));
}

std::vector<GimbalDriverRow> build_table() {
  std::vector<GimbalDriverRow> t;
  t.push_back({"simulated", "a simulated gimbal with gimbal effects (no hardware)", "",
               read_simulated, make<SimulatedGimbalDriver, SimulatedGimbalOptions>});
  t.push_back({"grbl", "a two-axis stage on a GRBL 1.1 controller (serial)", "grbl_emulator",
               [](const DriverParams& p, const GimbalDriverDefaults& d) -> std::any {
                 return read_serial(p, d, "grbl", 115200, false);
               },
               make<GrblDriver, SerialGimbalOptions>});
  t.push_back({"smc100", "Newport SMC100 rotation stages, one address per axis (serial)",
               "smc100_emulator",
               [](const DriverParams& p, const GimbalDriverDefaults& d) -> std::any {
                 return read_serial(p, d, "smc100", 57600, true);
               },
               make<Smc100Driver, SerialGimbalOptions>});
  t.push_back({"ros_joint", "axes that are ROS joints (JointState in, Float64 command per axis)",
               "joint_controller_emulator", read_ros_joint, make<RosJointGimbal, RosJointOptions>});
  t.push_back({"manual", "an indexing head turned by hand, each pose checked by the IMU", "",
               read_manual, make<ManualGimbal, ManualGimbalOptions>});
  return t;
}

// A number that may be written as an integer.
void read_number_or_string(const DriverParams& params, const std::string& key, std::string* out) {
  params.get(key, out);
}

}  // namespace

AxisMap read_axis_map(const DriverParams& params, const std::string& driver) {
  AxisMap map;
  for (int p = 0; p < 3; ++p) {
    const std::string key = driver + "/phases/" + "xyz"[p];
    if (!params.has(key)) {
      throw std::invalid_argument("parameter " + params.name(key) +
                                  " is missing: the axis map of phase " + "xyz"[p] +
                                  " (see config/" + driver + "_gimbal.yaml)");
    }
    PhaseAxes& axes = map.phases[p];
    read_number_or_string(params, key + "/axis", &axes.axis);
    params.get(key + "/sign", &axes.sign);
    params.get(key + "/zero_deg", &axes.zero_deg);
    params.get(key + "/manual_remount", &axes.manual_remount);
    for (const std::string& held : params.keys(key + "/hold")) {
      double v = 0.0;
      params.get(key + "/hold/" + held, &v);
      axes.hold[held] = v;
    }
  }
  return map;
}

const std::vector<GimbalDriverRow>& gimbal_driver_table() {
  static const std::vector<GimbalDriverRow> table = build_table();
  return table;
}

const GimbalDriverRow* find_gimbal_driver(const std::string& name) {
  for (const GimbalDriverRow& row : gimbal_driver_table()) {
    if (row.name == name) return &row;
  }
  return nullptr;
}

std::string gimbal_driver_names() {
  std::string out;
  for (const GimbalDriverRow& row : gimbal_driver_table())
    out += (out.empty() ? "" : ", ") + row.name;
  return out;
}

}  // namespace accel_intrinsics
