// Emulators of the GRBL 1.1 and Newport SMC100 controllers on a pseudo-terminal, for the driver
// tests and for trying the package without hardware (src/nodes/grbl_emulator.cpp,
// smc100_emulator.cpp). ROS-free. They answer in the device's grammar (grbl_driver.h,
// smc100_driver.h), move at a configured rate in wall-clock time, log every command received
// (one per line; the real-time bytes of GRBL as "?", "!", "~", "^X"), and inject faults at the
// (fault_after + 1)-th move command (GRBL: a G0 line; SMC100: a PA of any address, so a two-axis
// position counts twice):
//   no_reply  never answer anything again
//   garbage   answer that command (GRBL) or the next query (SMC100) with bytes outside the grammar
//   error     refuse the move (GRBL "error:<error_code>", SMC100 TE "G" displacement out of limits)
//   alarm     accept it and fail half way (GRBL "ALARM:<alarm_code>" and state Alarm; SMC100
//             following error, state DISABLE from MOVING)
//   vanish    close the pseudo-terminal (the port disappears, like an unplugged USB adapter)
#pragma once

#include <atomic>
#include <chrono>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace accel_intrinsics {

struct EmulatorOptions {
  double rate_deg_s = 180.0;      // speed of every axis, deg/s (wall clock)
  double home_s = 0.5;            // duration of a homing cycle, s
  bool needs_homing = false;      // GRBL: homing enabled (Alarm after reset until $H or $X);
                                  // SMC100: NOT REFERENCED at power-up (until OR)
  std::string fault = "none";     // none | no_reply | garbage | error | alarm | vanish
  int fault_after = 0;            // moves answered normally before the fault
  int error_code = 20;            // GRBL error:N for fault = error
  int alarm_code = 1;             // GRBL ALARM:N for fault = alarm
  std::vector<int> addresses{1};  // SMC100 controller addresses on the port
  std::string log_path;           // also append the command log to this file ("" = none)
  std::string link_path;          // symlink to the pseudo-terminal ("" = none)

  // Throws std::invalid_argument naming the field.
  void validate() const;
};

class DeviceEmulator {
 public:
  explicit DeviceEmulator(const EmulatorOptions& options);
  virtual ~DeviceEmulator();
  DeviceEmulator(const DeviceEmulator&) = delete;
  DeviceEmulator& operator=(const DeviceEmulator&) = delete;

  // The pseudo-terminal's device path (what a driver opens).
  const std::string& port() const { return slave_path_; }
  // Serves for up to timeout_s (handles input, motion, timed events). False once it vanished.
  bool step(double timeout_s);
  // Serves until `stop` is set or the device vanished.
  void run(const std::atomic<bool>& stop);
  // Every command received so far.
  std::vector<std::string> commands() const;
  bool vanished() const { return master_ < 0; }

 protected:
  using Clock = std::chrono::steady_clock;
  // Bytes from the host; by default split into lines (LF ends one, CR is ignored) for on_line.
  virtual void on_bytes(const std::string& bytes);
  // One line from the host, logged as a command before this is called.
  virtual void on_line(const std::string& line) = 0;
  // Adds a byte to the line being received; a LF hands it to on_line.
  void take_line_byte(char c);
  void discard_partial_line() { line_.clear(); }  // a reset drops what was half received
  // Timed behaviour (motion, homing, injected alarms).
  virtual void on_time() = 0;
  void reply(const std::string& text);  // raw bytes to the host (nothing when silenced)
  void log_command(const std::string& command);
  void vanish();
  double seconds_since_start() const;
  // Counts a move command and returns the fault injected at it ("none" for all but the
  // (fault_after + 1)-th). The faults that end the conversation (vanish, no_reply) are carried
  // out here; the device answers the others (garbage, error, alarm) in its own protocol.
  std::string fault_at_this_move();
  static bool ends_conversation(const std::string& fault) {
    return fault == "vanish" || fault == "no_reply";
  }

  EmulatorOptions options_;
  bool silent_ = false;  // no_reply fault injected

 private:
  int master_ = -1, slave_ = -1;
  std::string slave_path_;
  Clock::time_point start_;
  mutable std::mutex mutex_;
  std::vector<std::string> commands_;
  std::string line_;  // received since the last LF
  int moves_ = 0;     // move commands received (fault_at_this_move)
};

// An axis moving linearly at rate_deg_s.
struct EmulatedAxis {
  double from = 0.0, to = 0.0, t0 = 0.0, t1 = 0.0;
  double at(double t) const;
  bool moving(double t) const { return t < t1; }
  void go(double target, double t, double rate_deg_s);
  void halt(double t);
};

class GrblEmulator : public DeviceEmulator {
 public:
  explicit GrblEmulator(const EmulatorOptions& options);

 protected:
  void on_bytes(const std::string& bytes) override;  // real-time commands, then lines
  void on_time() override;
  void on_line(const std::string& line) override;

 private:
  void soft_reset();
  void status_report();
  void move(const std::string& line);
  bool running(double t) const;

  EmulatedAxis axes_[3];
  std::string state_ = "Idle";
  double homing_done_ = -1.0;  // reply "ok" to $H then
  double alarm_at_ = -1.0;     // injected alarm then
  int reports_ = 0;
};

class Smc100Emulator : public DeviceEmulator {
 public:
  explicit Smc100Emulator(const EmulatorOptions& options);

 protected:
  void on_time() override;
  void on_line(const std::string& line) override;

 private:
  struct Controller {
    int state = 0x0A;
    int errors = 0;
    char error = '@';  // what TE answers next ('@': no error)
    double target = 0.0;
    double homing_done = -1.0;
    double alarm_at = -1.0;
    EmulatedAxis axis;
  };
  std::map<int, Controller> controllers_;
  bool garbage_pending_ = false;
};

}  // namespace accel_intrinsics
