// Device time to host time for a sensor that stamps its own samples (the serial_lines
// accelerometer's t column, docs/design.md section 15): host = offset + rate * device, fitted as
// samples arrive. ROS-free; times in seconds.
//
// The choice: a least-squares line through the LOWER ENVELOPE of the delays d = host - device,
// one point per bin of bin_s device seconds (the bin's smallest delay, at its own device time),
// over the last window_s. Why the envelope and not a plain least squares of every sample: the
// host sees each line at transport latency plus a jitter that is one-sided (a line is never
// received before it was sent) and heavy-tailed (a busy host reads a burst of lines late), so a
// mean of d is biased by the mean jitter and pulled by every stall, while the smallest delay in
// a bin of hundreds of lines lies within a few microseconds of the pure transport latency. The
// least squares through those minima then measures the device's clock rate (crystal drift,
// ~10-100 ppm, or a percent for an RC oscillator) and the window lets it follow a rate that
// changes with temperature. (A convex hull of all the points would bound the envelope more
// tightly but reacts to a single early outlier; the bin minima need none of that.)
// Until the points span rate_span_s the rate is taken as 1 and the offset as the smallest delay
// seen: a short span measures the rate badly.
#pragma once

#include <cstddef>
#include <deque>

namespace accel_intrinsics {

struct DeviceClockFitOptions {
  double bin_s = 0.25;          // device seconds per envelope point
  double window_s = 20.0;       // envelope points kept (device seconds)
  double rate_span_s = 2.0;     // the rate is fitted once the points span this long
  double warmup_s = 0.5;        // ready() after this long of device time
  double max_early_s = 0.05;    // a sample this much earlier than the fit says ...
  double max_late_s = 10.0;     // ... or this much later is an outlier ...
  int outliers_to_restart = 5;  // ... and this many in a row restart the fit (device reset)

  void validate() const;  // throws std::invalid_argument naming the field
};

class DeviceClockFit {
 public:
  enum class Added { Used, Outlier, Restarted };

  explicit DeviceClockFit(const DeviceClockFitOptions& options = {});

  // One sample: its device time and the host time it was received. Outlier: t not after the
  // previous sample's, or received max_early_s before or max_late_s after the fit's host time:
  // the sample should be dropped. Restarted: the fit began again from this sample after
  // outliers_to_restart outliers in a row.
  Added add(double device_s, double host_s);
  void reset();

  // Enough data (warmup_s of device time) to map times.
  bool ready() const;
  // The host time of device time device_s (extrapolated past the newest sample).
  double host_time(double device_s) const;
  double offset_s() const { return offset_s_; }  // host time at device time 0
  double rate() const { return rate_; }          // host seconds per device second
  std::size_t points() const { return points_.size() + (have_bin_ ? 1 : 0); }
  std::size_t restarts() const { return restarts_; }

 private:
  struct Point {
    double device_s, delay_s;
  };
  void refit();

  DeviceClockFitOptions options_;
  std::deque<Point> points_;  // closed bins' minima, oldest first
  Point bin_{0.0, 0.0};       // the open bin's minimum so far
  bool have_bin_ = false;
  double bin_start_s_ = 0.0;
  double first_device_s_ = 0.0, last_device_s_ = 0.0;
  bool any_ = false;
  int outliers_in_row_ = 0;
  std::size_t restarts_ = 0;
  double offset_s_ = 0.0, rate_ = 1.0;
};

}  // namespace accel_intrinsics
