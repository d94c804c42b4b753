// GRBL 1.1 gimbal driver (docs/design.md section 10), from GRBL's own interface documentation:
//  - lines end in "\n"; every line is answered "ok" or "error:N" (send-response: one line in
//    flight at a time);
//  - moves: "G21 G90 G0 X<deg> Y<deg>" (absolute, rapid; one GRBL "mm" is one degree of the
//    stage: steps/mm set to steps/deg in GRBL's $100..$102);
//  - status: the real-time "?" (no line end) answered "<Idle|MPos:x,y,z|FS:0,0|WCO:...>" with
//    the state Idle, Run, Hold:n, Jog, Alarm, Door:n, Check, Home or Sleep; positions are MPos or
//    WPos, WPos = MPos - WCO (the last WCO reported);
//  - push messages "ALARM:N", "[MSG:...]", and the banner "Grbl 1.1h ['$' for help]" after a
//    reset; soft reset is the byte 0x18, "$H" homes, "$X" unlocks an alarm, "!" is feed hold.
// Axis names: X, Y, Z (A, B, C on builds with more axes).
#pragma once

#include <string>
#include <vector>

#include "accel_intrinsics/drivers/serial_gimbal.h"

namespace accel_intrinsics {

// GRBL's own words for its codes (interface.md); "" for an unknown code.
std::string grbl_error_text(int code);
std::string grbl_alarm_text(int code);

// A parsed status report; false when `line` is not one.
struct GrblStatus {
  std::string state;       // "Idle", "Run", "Hold", "Alarm", ... (the part before ':')
  std::string full_state;  // with its substate: "Hold:0" (hold complete), "Door:1", ...
  std::vector<double> mpos, wpos, wco;  // as reported (empty when absent)
};
bool parse_grbl_status(const std::string& line, GrblStatus* status);

class GrblDriver : public SerialGimbalDriver {
 public:
  // Opens the port and initializes GRBL (reset, homing or unlock); throws GimbalFault.
  explicit GrblDriver(const SerialGimbalOptions& options);

  std::string name() const override { return "grbl"; }
  static std::vector<std::string> axis_names() { return {"X", "Y", "Z", "A", "B", "C"}; }

 protected:
  void initialize() override;
  void send_move(const std::map<std::string, double>& positions_deg) override;
  DeviceStatus poll_status() override;
  void send_stop() override;

 private:
  // Sends a line and waits for its "ok"; "error:N" or an alarm throws GimbalFault.
  void command(const std::string& line, double timeout_s = -1.0);
  // A status report (push messages in between are handled); no alarm check.
  DeviceStatus query(GrblStatus* raw);
  // A push message; throws on ALARM:N; false when the line is not one GRBL sends.
  bool handle_push(const std::string& line, const std::string& context);
  void reset_and_wait_banner();

  std::vector<double> wco_;
  bool moves_sent_ = false;
};

}  // namespace accel_intrinsics
