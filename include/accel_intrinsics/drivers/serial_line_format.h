// One sample a line, as a microcontroller prints it over a serial port (docs/design.md section
// 15, "Bare MEMS parts"): the columns' meaning (`x,y,z`, `t,x,y,z`, `_` for a column to skip),
// the separator, and the parse of one line, which names why a line is refused. ROS-free.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace accel_intrinsics {

// Why a line was not a sample. Every refused line is counted by kind and never published.
enum class LineFault {
  None = 0,
  Binary,   // a byte that is neither printable ASCII nor a tab (line noise, a reset's junk)
  TooLong,  // longer than SerialLineFormat::max_line_chars
  Columns,  // not the configured number of columns (includes a line cut in half)
  Number,   // a column that is not a finite decimal number
  Partial,  // the first line after the port was opened (it may start mid-line)
  Clock,    // t not after the previous t, or far off the device-to-host clock fit
};
constexpr int kLineFaultKinds = 7;  // None ... Clock
// "binary", "too_long", "columns", "number", "partial", "clock" ("" for None).
const char* line_fault_name(LineFault fault);

struct SerialLineFormat {
  // Column roles, in line order: 't' device time (s), 'x', 'y', 'z' the three outputs, '_' skip.
  std::vector<char> roles = {'x', 'y', 'z'};
  // One character; a space or a tab means "any run of blanks" (and leading/trailing blanks are
  // ignored). With another separator, blanks around a column are ignored ("1.0, 2.0, 3.0").
  char separator = ',';
  std::size_t max_line_chars = 256;

  // "t,x,y,z" (names separated by commas, blanks ignored; `_` or `skip` for a column to
  // ignore). Throws std::invalid_argument naming what is wrong: x, y and z exactly once, t at
  // most once.
  static std::vector<char> parse_columns(const std::string& text);
  // From the parameter text: "," ";" " " "\t" (also "space", "tab", "whitespace"). Throws
  // std::invalid_argument.
  static char parse_separator(const std::string& text);
  bool has_time() const;
  // "t,x,y,z"
  std::string columns_text() const;
};

struct ParsedLine {
  std::array<double, 3> xyz{{0.0, 0.0, 0.0}};  // as printed, any unit
  double t_s = 0.0;                            // device time, when the format has a t column
};

// Parses one line (without its terminator). LineFault::None and *out filled, or the fault.
LineFault parse_sample_line(const std::string& line, const SerialLineFormat& format,
                            ParsedLine* out);

}  // namespace accel_intrinsics
