// Parsing of the serial_lines accelerometer's lines (serial_line_format.h).
#include "accel_intrinsics/drivers/serial_line_format.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <stdexcept>

namespace accel_intrinsics {

namespace {

bool blank(char c) {
  return c == ' ' || c == '\t';
}

std::string trimmed(const std::string& s) {
  std::size_t a = 0, b = s.size();
  while (a < b && blank(s[a])) ++a;
  while (b > a && blank(s[b - 1])) --b;
  return s.substr(a, b - a);
}

// A finite decimal number filling [first, last): "-1.5", "+2", "3e-4" (from_chars: locale-free,
// no allocation; a leading '+' is accepted as C's printf may write one).
bool parse_number(const char* first, const char* last, double* value) {
  if (first < last && *first == '+') ++first;
  if (first == last) return false;
  const std::from_chars_result r = std::from_chars(first, last, *value);
  return r.ec == std::errc() && r.ptr == last && std::isfinite(*value);
}

}  // namespace

const char* line_fault_name(LineFault fault) {
  switch (fault) {
    case LineFault::Binary: return "binary";
    case LineFault::TooLong: return "too_long";
    case LineFault::Columns: return "columns";
    case LineFault::Number: return "number";
    case LineFault::Partial: return "partial";
    case LineFault::Clock: return "clock";
    default: return "";
  }
}

std::vector<char> SerialLineFormat::parse_columns(const std::string& text) {
  std::vector<char> roles;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = text.find(',', start);
    const std::string name =
        trimmed(text.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (name == "t" || name == "x" || name == "y" || name == "z") {
      roles.push_back(name[0]);
    } else if (name == "_" || name == "skip") {
      roles.push_back('_');
    } else {
      throw std::invalid_argument("columns '" + text + "': unknown column '" + name +
                                  "' (known: t, x, y, z, _ to skip a column)");
    }
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  for (const char axis : {'x', 'y', 'z'}) {
    if (std::count(roles.begin(), roles.end(), axis) != 1) {
      throw std::invalid_argument("columns '" + text + "': needs " + std::string(1, axis) +
                                  " exactly once");
    }
  }
  if (std::count(roles.begin(), roles.end(), 't') > 1) {
    throw std::invalid_argument("columns '" + text + "': t at most once");
  }
  return roles;
}

char SerialLineFormat::parse_separator(const std::string& text) {
  if (text == "space" || text == "whitespace" || text == " ") return ' ';
  if (text == "tab" || text == "\t") return '\t';
  if (text.size() == 1 && text[0] > 0x20 && text[0] < 0x7f && text[0] != '.' && text[0] != '-' &&
      text[0] != '+' && !(text[0] >= '0' && text[0] <= '9') && text[0] != 'e' && text[0] != 'E') {
    return text[0];
  }
  throw std::invalid_argument("separator '" + text +
                              "': one character that cannot be part of a number (',' ';' ' ' "
                              "'\\t'; or space, tab, whitespace)");
}

bool SerialLineFormat::has_time() const {
  return std::find(roles.begin(), roles.end(), 't') != roles.end();
}

std::string SerialLineFormat::columns_text() const {
  std::string out;
  for (const char r : roles) {
    if (!out.empty()) out += ',';
    out += r;
  }
  return out;
}

LineFault parse_sample_line(const std::string& line, const SerialLineFormat& format,
                            ParsedLine* out) {
  if (line.size() > format.max_line_chars) return LineFault::TooLong;
  for (const char c : line) {
    const unsigned char u = static_cast<unsigned char>(c);
    if ((u < 0x20 && c != '\t') || u > 0x7e) return LineFault::Binary;
  }
  const bool by_blanks = blank(format.separator);
  const char* p = line.data();
  const char* const end = p + line.size();
  std::size_t column = 0;
  ParsedLine parsed;
  if (by_blanks) {
    while (p < end && blank(*p)) ++p;
  }
  while (p < end || (!by_blanks && column > 0)) {
    const char* field_end = p;
    if (by_blanks) {
      while (field_end < end && !blank(*field_end)) ++field_end;
    } else {
      while (field_end < end && *field_end != format.separator) ++field_end;
    }
    if (column >= format.roles.size()) return LineFault::Columns;
    const char* a = p;
    const char* b = field_end;
    while (a < b && blank(*a)) ++a;
    while (b > a && blank(b[-1])) --b;
    const char role = format.roles[column++];
    double value = 0.0;
    if (role != '_' && !parse_number(a, b, &value)) return LineFault::Number;
    switch (role) {
      case 't': parsed.t_s = value; break;
      case 'x': parsed.xyz[0] = value; break;
      case 'y': parsed.xyz[1] = value; break;
      case 'z': parsed.xyz[2] = value; break;
      default: break;
    }
    if (field_end == end) break;
    p = field_end + 1;  // past the separator
    if (by_blanks) {
      while (p < end && blank(*p)) ++p;
    }
  }
  if (column != format.roles.size()) return LineFault::Columns;
  *out = parsed;
  return LineFault::None;
}

}  // namespace accel_intrinsics
