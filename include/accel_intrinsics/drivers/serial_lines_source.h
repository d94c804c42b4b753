// The serial_lines accelerometer source (docs/design.md section 15, "Bare MEMS parts"): a
// microcontroller prints one sample a line over a serial port; a reader thread receives the
// lines, parses them (serial_line_format.h), stamps them (the host clock at reception, or the
// device's t mapped to host time by DeviceClockFit) and hands them to poll() (and says so through
// an optional callback, so a consumer need not poll on a timer). With a t column it reads the port
// every read_period_s, the lines that came meanwhile in one go: at 1 kHz a few hundred wake-ups a
// second instead of one per line. Garbled lines are counted by kind and dropped. A lost port is
// closed and reopened every reconnect_interval_s until it is back. ROS-free: the host clock is
// injected.
#pragma once

#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "accel_intrinsics/drivers/accelerometer_source.h"
#include "accel_intrinsics/drivers/device_clock_fit.h"
#include "accel_intrinsics/drivers/serial_line_format.h"

namespace accel_intrinsics {

struct SerialLinesOptions {
  std::string port;  // e.g. /dev/ttyACM0 (a USB CDC device ignores the baud)
  int baud = 115200;
  SerialLineFormat format;
  double reconnect_interval_s = 1.0;  // between attempts to open a lost or absent port
  // With a t column: the port is read at most this often, the lines that came meanwhile
  // together (the stamps come from t; the clock fit's envelope is the lines read as soon as they
  // came). 0: each line as it comes (always so without a t column: stamps at reception). s.
  double read_period_s = 0.005;
  DeviceClockFitOptions clock;       // the device-time fit (with a t column)
  std::size_t max_pending = 100000;  // samples held for poll() (older ones dropped beyond)

  void validate() const;  // throws std::invalid_argument naming the field
};

enum class SerialLinkState { Opening, Connected, Lost };
const char* link_state_name(SerialLinkState state);  // "opening", "connected", "lost"

struct SerialLinesStatus {
  SerialLinkState state = SerialLinkState::Opening;
  std::string last_error;     // the port's own words (cannot open / lost), "" when none
  std::string loss_error;     // why the port was last lost ("" before any loss)
  std::uint64_t lines = 0;    // lines received (samples + garbled)
  std::uint64_t samples = 0;  // samples stamped and handed on
  std::array<std::uint64_t, kLineFaultKinds> garbled{};  // by LineFault (index 0 unused)
  std::string last_garbled;         // the last refused line, printable (\xNN for other bytes)
  std::uint64_t connects = 0;       // successful opens
  std::uint64_t losses = 0;         // times the port was lost after opening
  std::uint64_t open_failures = 0;  // failed attempts to open
  std::uint64_t overflow = 0;       // samples dropped because poll() did not take them
  double last_line_host_s = -1.0;   // host time of the newest line; < 0 before any
  double since_s = 0.0;             // host time of the last state change
  // The device clock (t column only).
  bool clock_ready = false;
  double clock_offset_s = 0.0, clock_rate = 1.0;
  std::size_t clock_points = 0, clock_restarts = 0;

  std::uint64_t garbled_total() const;
};

class SerialLinesAccelerometer : public AccelerometerSource {
 public:
  using HostClock = std::function<double()>;  // seconds, the clock of the published stamps
  // Called on the reader thread (no lock held) each time it has stamped new samples for poll():
  // a consumer can take them at once instead of polling on a timer.
  using SamplesReady = std::function<void()>;

  // Starts the reader thread, which opens the port (and keeps trying when it cannot).
  SerialLinesAccelerometer(const SerialLinesOptions& options, HostClock host_clock,
                           SamplesReady on_samples = {});
  ~SerialLinesAccelerometer() override;  // stops the reader and closes the port

  std::string name() const override { return "serial_lines"; }
  // Every sample stamped so far (now_s is not needed: lines are stamped as they arrive).
  void poll(double now_s, std::vector<core::ImuSample>* out) override;
  SerialLinesStatus status() const;
  const SerialLinesOptions& options() const { return options_; }

 private:
  void run();
  void handle_line(const std::string& line, double host_s);  // with mutex_ held
  void stamp_held();                                         // with mutex_ held
  void push(const core::ImuSample& sample);                  // with mutex_ held
  void set_state(SerialLinkState state, const std::string& error, double host_s);

  SerialLinesOptions options_;
  HostClock clock_;
  SamplesReady on_samples_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::atomic<bool> stop_{false};
  SerialLinesStatus status_;
  DeviceClockFit fit_;
  bool first_line_ = true;  // the first line after an open may start mid-line
  struct Held {
    double device_s;
    core::ImuSample sample;
  };
  std::vector<Held> held_;             // received before the clock fit was ready
  std::deque<core::ImuSample> ready_;  // stamped, for poll()
  std::thread thread_;
};

}  // namespace accel_intrinsics
