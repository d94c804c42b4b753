// Serial gimbal drivers (docs/design.md section 10): the part common to the GRBL and SMC100
// backends.
//
// Axis map: each phase of the protocol names the stage axis that turns alpha, with a sign and a
// zero offset (stage position = zero_deg + sign * alpha in degrees), and where every other axis
// holds during the phase. A two-axis gimbal realizes all three phases this way; a one-axis stage
// turns the same axis in every phase and the DUT is remounted by hand before a phase marked
// manual_remount (the controller pauses and waits for gimbal_controller/continue).
//
// Settling: a move is settled when the device reports itself at rest (GRBL Idle, SMC100 READY)
// with every mapped axis within tolerance_deg of its target, continuously for settle_s on the
// node's clock. The orientation broadcast on tf is the one the device reports (its position
// read back through the axis map), not the commanded one.
//
// Faults: anything the device or the port does wrong (no reply, a reply that is not in the
// device's grammar, an error or alarm, the port gone) throws GimbalFault whose message quotes
// what the device said. The controller turns it into an abort of the run.
#pragma once

#include <chrono>
#include <deque>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "accel_intrinsics/drivers/gimbal_driver.h"
#include "accel_intrinsics/drivers/serial_port.h"

namespace accel_intrinsics {

struct PhaseAxes {
  std::string axis;                    // the axis that turns alpha ("X" for GRBL, "1" for SMC100)
  double sign = 1.0;                   // +1 or -1
  double zero_deg = 0.0;               // stage position at alpha = 0, deg
  std::map<std::string, double> hold;  // the other axes' positions during the phase, deg
  bool manual_remount = false;         // the operator remounts the DUT before this phase
};

struct AxisMap {
  PhaseAxes phases[3];  // x, y, z

  // Every axis the map uses (turned or held), sorted.
  std::vector<std::string> axes() const;
  // Stage positions (deg) of every axis for alpha in a phase.
  std::map<std::string, double> positions_deg(core::Phase phase, double alpha_rad) const;
  // alpha (rad) of a phase from the stage position of its axis.
  double alpha_rad(core::Phase phase, double axis_position_deg) const;
  // Throws std::invalid_argument naming the field ("phases.y.sign must be +1 or -1"); `known`:
  // the axis names the device has (empty: any).
  void validate(const std::vector<std::string>& known) const;
};

struct SerialGimbalOptions {
  std::string port;                // device path ("/dev/ttyUSB0", or the emulator's pty)
  int baud = 115200;               // GRBL: 115200; SMC100: 57600
  bool xon_xoff = false;           // software flow control (SMC100: on, as its open drivers use)
  double connect_timeout_s = 5.0;  // keep trying to open the port this long (wall clock), s
  double reply_timeout_s = 2.0;    // a command without its reply this long (wall clock): fault
  double poll_interval_s = 0.05;   // status polls at most this often (wall clock), s
  double tolerance_deg = 0.01;     // at the target: every axis within this, deg
  double settle_s = 0.5;           // at rest at the target this long before SETTLED (node clock), s
  bool home_at_start = false;      // home the stage when the driver starts (GRBL $H, SMC100 OR)
  double home_timeout_s = 120.0;   // homing must finish within this (wall clock), s
  bool unlock_at_start = false;    // GRBL: an alarm at start is unlocked with $X (no homing)
  bool reset_at_start = true;  // GRBL: soft reset (0x18) at start; SMC100: nothing (RS re-homes)
  AxisMap axis_map;

  // Throws std::invalid_argument naming the field.
  void validate() const;
};

// What a status poll found.
struct DeviceStatus {
  bool at_rest = false;                    // Idle / READY
  std::map<std::string, double> position;  // deg per axis
  std::string text;                        // the device's words (for messages)
};

class SerialGimbalDriver : public GimbalDriver {
 public:
  explicit SerialGimbalDriver(const SerialGimbalOptions& options);

  void move_to(const GimbalTarget& target, double t_s) override;
  bool settled(double t_s) const override;
  double settled_at(double t_s) const override;
  void stop(double t_s) override;
  GimbalTransforms orientation(double t_s) const override;
  void update(double t_s) override;
  void recover(double t_s) override;
  bool manual_remount(core::Phase phase) const override;
  std::string status_text() const override { return last_status_.text; }

  // The most recent status (for tests and diagnostics).
  const DeviceStatus& last_status() const { return last_status_; }

 protected:
  // Connects and brings the device to a state that accepts moves (reset, homing, unlock).
  // Called by the subclass constructor (after its own members exist).
  void start_device();
  virtual void initialize() = 0;
  // Sends an absolute move of every axis (deg); throws GimbalFault.
  virtual void send_move(const std::map<std::string, double>& positions_deg) = 0;
  // Polls state and positions; throws GimbalFault on an error or alarm.
  virtual DeviceStatus poll_status() = 0;
  // Stops motion; may throw (the caller ignores it: stopping is best effort).
  virtual void send_stop() = 0;
  // A line from the device within reply_timeout_s, or a GimbalFault "no reply ... to <what>".
  std::string expect_line(const std::string& what, double timeout_s = -1.0);
  // The port, with SerialError turned into GimbalFault.
  void write(const std::string& bytes);

  SerialGimbalOptions options_;
  SerialPort port_;

 private:
  bool at_target(const DeviceStatus& status) const;
  void poll(double t_s);
  // Appends the last polled position of the target phase's axis, stamped t_s, to the history.
  void record_position(double t_s);

  struct Sample {
    double t_s;
    core::Phase phase;  // the frame alpha is read in
    double alpha_rad;
  };
  GimbalTarget target_;
  std::map<std::string, double> target_positions_;
  bool moving_ = false;
  double at_rest_since_s_ = -1.0;  // < 0: not at rest at the target
  double settled_s_ = 0.0;
  DeviceStatus last_status_;
  std::deque<Sample> history_;  // reported alpha, with the phase of each poll
  std::chrono::steady_clock::time_point last_poll_{};
  bool polled_ = false;
};

}  // namespace accel_intrinsics
