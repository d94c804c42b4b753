// Parameters, diagnostics and logs of the accelerometer node's serial_lines source.
#include "accel_intrinsics/ros/accelerometer_serial_lines.h"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <ros/console.h>

#include <cmath>
#include <stdexcept>

#include "accel_intrinsics/ros/params.h"

namespace accel_intrinsics {

SerialLinesOptions load_serial_lines_options(const ros::NodeHandle& pnh) {
  SerialLinesOptions o;
  read_param(pnh, "serial_lines/port", &o.port);
  require(!o.port.empty(), pnh, "serial_lines/port",
          "must name the serial port of the microcontroller (e.g. /dev/ttyACM0)");
  read_param(pnh, "serial_lines/baud", &o.baud);
  std::string columns = "x,y,z";
  read_param(pnh, "serial_lines/columns", &columns);
  try {
    o.format.roles = SerialLineFormat::parse_columns(columns);
  } catch (const std::invalid_argument& e) {
    throw ParamError("parameter " + param_name(pnh, "serial_lines/columns") + ": " + e.what());
  }
  std::string separator = ",";
  read_param(pnh, "serial_lines/separator", &separator);
  try {
    o.format.separator = SerialLineFormat::parse_separator(separator);
  } catch (const std::invalid_argument& e) {
    throw ParamError("parameter " + param_name(pnh, "serial_lines/separator") + ": " + e.what());
  }
  read_param(pnh, "serial_lines/reconnect_interval_s", &o.reconnect_interval_s);
  read_param(pnh, "serial_lines/read_period_s", &o.read_period_s);
  read_param(pnh, "serial_lines/clock/bin_s", &o.clock.bin_s);
  read_param(pnh, "serial_lines/clock/window_s", &o.clock.window_s);
  read_param(pnh, "serial_lines/clock/warmup_s", &o.clock.warmup_s);
  try {
    o.validate();
  } catch (const std::invalid_argument& e) {
    throw ParamError("parameter " + pnh.getNamespace() + "/serial_lines/" + e.what());
  }
  return o;
}

void diagnose_serial_lines(const SerialLinesStatus& s, const SerialLinesOptions& options,
                           double now_s, diagnostic_updater::DiagnosticStatusWrapper* out) {
  using diagnostic_msgs::DiagnosticStatus;
  const double quiet_s = s.last_line_host_s < 0.0 ? -1.0 : now_s - s.last_line_host_s;
  if (s.state == SerialLinkState::Lost) {
    out->summaryf(DiagnosticStatus::ERROR, "%s lost (%s); reopening every %.3g s: %s",
                  options.port.c_str(), s.loss_error.c_str(), options.reconnect_interval_s,
                  s.last_error.c_str());
  } else if (s.state == SerialLinkState::Opening) {
    out->summaryf(DiagnosticStatus::ERROR, "%s cannot be opened: %s; retrying every %.3g s",
                  options.port.c_str(), s.last_error.c_str(), options.reconnect_interval_s);
  } else if (s.last_line_host_s < 0.0 || quiet_s > 1.0) {
    out->summaryf(DiagnosticStatus::WARN, "%s connected but silent (no line for %.1f s)",
                  options.port.c_str(),
                  std::max(0.0, now_s - std::max(s.last_line_host_s, s.since_s)));
  } else if (options.format.has_time() && !s.clock_ready) {
    out->summary(DiagnosticStatus::WARN, "device clock fit warming up (samples held)");
  } else {
    out->summaryf(DiagnosticStatus::OK, "reading %s", options.port.c_str());
  }
  out->add("port", options.port);
  out->add("state", link_state_name(s.state));
  out->add("in_state_s", now_s - s.since_s);
  out->add("columns", options.format.columns_text());
  out->add("lines", s.lines);
  out->add("samples", s.samples);
  out->add("garbled", s.garbled_total());
  for (int k = 1; k < kLineFaultKinds; ++k) {
    out->add(std::string("garbled_") + line_fault_name(static_cast<LineFault>(k)), s.garbled[k]);
  }
  out->add("last_garbled", s.last_garbled);
  out->add("connects", s.connects);
  out->add("losses", s.losses);
  out->add("open_failures", s.open_failures);
  out->add("overflow", s.overflow);
  out->add("last_error", s.last_error);
  out->add("loss_error", s.loss_error);
  if (options.format.has_time()) {
    out->add("clock_ready", s.clock_ready ? "true" : "false");
    out->add("clock_rate_ppm", (s.clock_rate - 1.0) * 1e6);
    out->add("clock_offset_s", s.clock_offset_s);
    out->add("clock_points", s.clock_points);
    out->add("clock_restarts", s.clock_restarts);
  }
}

void log_serial_lines(const SerialLinesStatus& previous, const SerialLinesStatus& now,
                      const SerialLinesOptions& options) {
  const char* port = options.port.c_str();
  if (now.losses > previous.losses) {
    ROS_ERROR("accelerometer: %s; reopening %s every %.3g s", now.loss_error.c_str(), port,
              options.reconnect_interval_s);
  }
  if (now.connects > previous.connects) {
    if (now.connects == 1) {
      ROS_INFO(
          "accelerometer: reading %s at %d baud, columns %s, separator '%c'%s", port, options.baud,
          options.format.columns_text().c_str(), options.format.separator,
          options.format.has_time() ? " (stamps from the device's t)" : " (stamps at reception)");
    } else {
      ROS_WARN("accelerometer: serial port %s back (open %llu, after %llu failed attempts)", port,
               static_cast<unsigned long long>(now.connects),
               static_cast<unsigned long long>(now.open_failures));
    }
  }
  if (now.open_failures > previous.open_failures && now.connects == previous.connects) {
    ROS_WARN_THROTTLE(10.0, "accelerometer: %s; retrying every %.3g s", now.last_error.c_str(),
                      options.reconnect_interval_s);
  }
  // The first line after each open is dropped as partial by design: not worth a warning.
  const int partial = static_cast<int>(LineFault::Partial);
  if (now.garbled_total() - now.garbled[partial] >
      previous.garbled_total() - previous.garbled[partial]) {
    ROS_WARN_THROTTLE(10.0, "accelerometer: %llu garbled line(s) dropped so far, last: '%s'",
                      static_cast<unsigned long long>(now.garbled_total()),
                      now.last_garbled.c_str());
  }
  if (now.clock_restarts > previous.clock_restarts) {
    ROS_WARN(
        "accelerometer: the device's clock jumped (reset or wrapped counter): clock fit "
        "restarted");
  }
}

}  // namespace accel_intrinsics
