// Newport SMC100CC / SMC100PP gimbal driver (docs/design.md section 10). One controller per axis,
// each with its RS-485 address 1..31 (the axis name in the axis map), all on one serial port.
// Commands are "<address><two letters>[value]" ended by "\r\n" (57600 baud, 8N1):
//   nnPA<deg>  move absolute (no reply; nnTE? tells whether it was accepted)
//   nnTS?      -> nnTSeeeess: positioner error flags eeee (hex) and controller state ss (hex):
//                 0A..11 NOT REFERENCED, 14 CONFIGURATION, 1E/1F HOMING, 28 MOVING,
//                 32..35 READY, 3C..3E DISABLE, 46/47 JOGGING
//   nnTP?      -> nnTP<position>
//   nnTE?      -> nnTE<letter>: the error of the last command, A = none
//   nnOR       home search (from NOT REFERENCED), nnRS reset, nnST stop
#pragma once

#include <string>
#include <vector>

#include "accel_intrinsics/drivers/serial_gimbal.h"

namespace accel_intrinsics {

// The controller state of a TS reply in the manual's words ("READY from MOVING"); "" if unknown.
std::string smc100_state_text(int state);
// The command error of a TE reply ('A' .. 'X'); "" if unknown.
std::string smc100_error_text(char code);
bool smc100_is_ready(int state);        // 32..35
bool smc100_is_moving(int state);       // 28, HOMING 1E/1F, JOGGING 46/47
bool smc100_not_referenced(int state);  // 0A..11

class Smc100Driver : public SerialGimbalDriver {
 public:
  // Opens the port and brings every controller to READY: with home_at_start a NOT REFERENCED
  // controller is homed (OR), and one that is DISABLEd or reports a positioner error (after a
  // fault: recover()) is reset (RS) and homed. Throws GimbalFault.
  explicit Smc100Driver(const SerialGimbalOptions& options);

  std::string name() const override { return "smc100"; }

 protected:
  void initialize() override;
  void send_move(const std::map<std::string, double>& positions_deg) override;
  DeviceStatus poll_status() override;
  void send_stop() override;

 private:
  // "<address><command>?" and its reply's value (after the echoed address and command).
  std::string query(const std::string& address, const std::string& command);
  // "<address><command>" (no reply) followed by TE: a command error throws GimbalFault.
  void command(const std::string& address, const std::string& command);
  // TS of one controller: state, error flags, the raw reply.
  int state_of(const std::string& address, int* errors, std::string* reply);

  std::vector<std::string> addresses_;
};

}  // namespace accel_intrinsics
