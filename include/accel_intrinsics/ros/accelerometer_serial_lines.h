// The accelerometer node's serial_lines source in ROS terms: its parameters (~serial_lines/...),
// its diagnostics and its log lines. The source itself is ROS-free (serial_lines_source.h).
#pragma once

#include <diagnostic_updater/DiagnosticStatusWrapper.h>
#include <ros/node_handle.h>

#include "accel_intrinsics/drivers/serial_lines_source.h"

namespace accel_intrinsics {

// Reads ~serial_lines/{port, baud, columns, separator, reconnect_interval_s, clock/...}; throws
// ParamError naming the parameter.
SerialLinesOptions load_serial_lines_options(const ros::NodeHandle& pnh);

// Fills the "serial_lines" diagnostic: ERROR while the port is lost or cannot be opened, WARN
// when connected but silent for 1 s or when the clock fit is warming up, OK otherwise; the
// counts of lines, samples and garbled lines by kind, reconnects, the clock fit.
void diagnose_serial_lines(const SerialLinesStatus& status, const SerialLinesOptions& options,
                           double now_s, diagnostic_updater::DiagnosticStatusWrapper* out);

// Logs what changed since `previous` (port opened, lost, back; new garbled lines, throttled).
void log_serial_lines(const SerialLinesStatus& previous, const SerialLinesStatus& now,
                      const SerialLinesOptions& options);

}  // namespace accel_intrinsics
