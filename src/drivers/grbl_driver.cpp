// GRBL 1.1 gimbal driver: send-response line protocol, "?" status polling, alarms.
#include "accel_intrinsics/drivers/grbl_driver.h"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace accel_intrinsics {

namespace {

using Clock = std::chrono::steady_clock;

bool starts_with(const std::string& s, const std::string& prefix) {
  return s.compare(0, prefix.size(), prefix) == 0;
}

bool parse_numbers(const std::string& text, std::vector<double>* out) {
  out->clear();
  std::stringstream s(text);
  std::string item;
  while (std::getline(s, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size()) return false;
    out->push_back(v);
  }
  return !out->empty();
}

int code_after_colon(const std::string& line) {
  const std::size_t colon = line.find(':');
  return colon == std::string::npos ? -1 : std::atoi(line.c_str() + colon + 1);
}

std::string with_text(const std::string& line, const std::string& text) {
  return "'" + printable(line) + "'" + (text.empty() ? "" : " (" + text + ")");
}

}  // namespace

std::string grbl_error_text(int code) {
  switch (code) {
    case 1: return "G-code words consist of a letter and a value. Letter was not found.";
    case 2: return "Numeric value format is not valid or missing an expected value.";
    case 3: return "Grbl '$' system command was not recognized or supported.";
    case 4: return "Negative value received for an expected positive value.";
    case 5: return "Homing cycle is not enabled via settings.";
    case 8: return "Grbl '$' command cannot be used unless Grbl is IDLE.";
    case 9: return "G-code locked out during alarm or jog state";
    case 11: return "Max characters per line exceeded.";
    case 13: return "Safety door detected as opened and door state initiated.";
    case 15: return "Jog target exceeds machine travel.";
    case 20: return "Unsupported or invalid g-code command found in block.";
    case 22: return "Feed rate has not yet been set or is undefined.";
    case 33: return "The motion command has an invalid target.";
    default: return "";
  }
}

std::string grbl_alarm_text(int code) {
  switch (code) {
    case 1: return "Hard limit triggered. Machine position is likely lost.";
    case 2: return "G-code motion target exceeds machine travel.";
    case 3: return "Reset while in motion. Grbl cannot guarantee position.";
    case 4: return "Probe fail.";
    case 5: return "Probe fail.";
    case 6: return "Homing fail. Reset during active homing cycle.";
    case 7: return "Homing fail. Safety door was opened during active homing cycle.";
    case 8: return "Homing fail. Cycle failed to clear limit switch when pulling off.";
    case 9: return "Homing fail. Could not find limit switch within search distance.";
    default: return "";
  }
}

bool parse_grbl_status(const std::string& line, GrblStatus* status) {
  if (line.size() < 3 || line.front() != '<' || line.back() != '>') return false;
  GrblStatus out;
  std::stringstream s(line.substr(1, line.size() - 2));
  std::string field;
  bool first = true;
  while (std::getline(s, field, '|')) {
    if (first) {
      out.state = field.substr(0, field.find(':'));
      out.full_state = field;
      first = false;
      continue;
    }
    if (starts_with(field, "MPos:") && !parse_numbers(field.substr(5), &out.mpos)) return false;
    if (starts_with(field, "WPos:") && !parse_numbers(field.substr(5), &out.wpos)) return false;
    if (starts_with(field, "WCO:") && !parse_numbers(field.substr(4), &out.wco)) return false;
  }
  static const char* const kStates[] = {"Idle", "Run",   "Hold", "Jog",  "Alarm",
                                        "Door", "Check", "Home", "Sleep"};
  bool known = false;
  for (const char* k : kStates) known = known || out.state == k;
  if (!known || (out.mpos.empty() && out.wpos.empty())) return false;
  *status = out;
  return true;
}

GrblDriver::GrblDriver(const SerialGimbalOptions& options) : SerialGimbalDriver(options) {
  try {
    options_.axis_map.validate(axis_names());
  } catch (const std::invalid_argument& e) {
    throw GimbalFault(std::string("grbl: ") + e.what());
  }
  start_device();
}

bool GrblDriver::handle_push(const std::string& line, const std::string& context) {
  if (line.empty() || starts_with(line, "[") || starts_with(line, ">")) return true;  // feedback
  if (starts_with(line, "ALARM:")) {
    const int code = code_after_colon(line);
    throw GimbalFault("grbl: alarm " + with_text(line, grbl_alarm_text(code)) + " " + context);
  }
  if (starts_with(line, "Grbl ")) {
    if (!moves_sent_) return true;  // a late banner of the reset at start
    throw GimbalFault("grbl: the controller reset itself (" + with_text(line, "") + ") " + context +
                      ": the stage position is lost");
  }
  return false;
}

void GrblDriver::command(const std::string& line, double timeout_s) {
  write(line + "\n");
  const std::string context = "after '" + line + "'";
  const Clock::time_point start = Clock::now();
  if (timeout_s < 0.0) timeout_s = options_.reply_timeout_s;
  for (;;) {
    const double left = timeout_s - std::chrono::duration<double>(Clock::now() - start).count();
    const std::string reply = expect_line("'" + line + "'", left > 0.0 ? left : 0.0);
    if (reply == "ok") return;
    if (starts_with(reply, "error:")) {
      throw GimbalFault("grbl: '" + line + "' answered " +
                        with_text(reply, grbl_error_text(code_after_colon(reply))));
    }
    GrblStatus ignored;
    if (parse_grbl_status(reply, &ignored)) continue;
    if (!handle_push(reply, context)) {
      throw GimbalFault("grbl: unexpected reply '" + printable(reply) + "' to '" + line + "'");
    }
  }
}

void GrblDriver::reset_and_wait_banner() {
  port_.discard_input();
  write(std::string(1, '\x18'));
  const Clock::time_point start = Clock::now();
  for (;;) {
    const double left =
        options_.reply_timeout_s - std::chrono::duration<double>(Clock::now() - start).count();
    const std::string line = expect_line("the soft reset (0x18)", left > 0.0 ? left : 0.0);
    if (starts_with(line, "Grbl ")) return;
    // Anything before the banner is what was in flight when the reset came.
  }
}

DeviceStatus GrblDriver::query(GrblStatus* raw) {
  write("?");
  std::string report;
  const Clock::time_point start = Clock::now();
  for (;;) {
    const double left =
        options_.reply_timeout_s - std::chrono::duration<double>(Clock::now() - start).count();
    const std::string line = expect_line("the status query '?'", left > 0.0 ? left : 0.0);
    if (parse_grbl_status(line, raw)) {
      report = line;
      break;
    }
    if (line == "ok") continue;  // a late acknowledgement
    if (starts_with(line, "error:")) {
      throw GimbalFault("grbl: " + with_text(line, grbl_error_text(code_after_colon(line))) +
                        " while waiting for the status");
    }
    if (!handle_push(line, "during the status query")) {
      throw GimbalFault("grbl: unexpected reply '" + printable(line) + "' to the status query '?'");
    }
  }
  if (!raw->wco.empty()) wco_ = raw->wco;
  std::vector<double> work = raw->wpos;
  if (work.empty()) {
    work = raw->mpos;
    for (std::size_t i = 0; i < work.size() && i < wco_.size(); ++i) work[i] -= wco_[i];
  }
  DeviceStatus out;
  out.at_rest = raw->state == "Idle";
  out.text = printable(report);  // the report as GRBL sent it
  const std::vector<std::string> names = axis_names();
  for (std::size_t i = 0; i < work.size() && i < names.size(); ++i)
    out.position[names[i]] = work[i];
  return out;
}

DeviceStatus GrblDriver::poll_status() {
  GrblStatus raw;
  DeviceStatus status = query(&raw);
  if (raw.state == "Alarm") {
    throw GimbalFault("grbl: the controller is in alarm '" + status.text + "'" +
                      ": reset it, home it ($H) or unlock it ($X)");
  }
  if (raw.state == "Check" || raw.state == "Sleep") {
    throw GimbalFault("grbl: the controller is in state " + raw.state + " and does not move");
  }
  return status;
}

void GrblDriver::initialize() {
  if (options_.reset_at_start) reset_and_wait_banner();
  GrblStatus raw;
  query(&raw);
  if (options_.home_at_start) {
    command("$H", options_.home_timeout_s);
  } else if (raw.state == "Alarm") {
    if (!options_.unlock_at_start) {
      throw GimbalFault(
          "grbl: the controller is in alarm at start (homing enabled, not homed): set "
          "home_at_start: true to home it ($H), or unlock_at_start: true to unlock it ($X)");
    }
    command("$X");
  }
}

void GrblDriver::send_move(const std::map<std::string, double>& positions_deg) {
  std::ostringstream line;
  line << "G21 G90 G0";
  char value[48];
  for (const auto& p : positions_deg) {
    std::snprintf(value, sizeof value, " %s%.4f", p.first.c_str(), p.second);
    line << value;
  }
  moves_sent_ = true;
  command(line.str());
}

void GrblDriver::send_stop() {
  // Feed hold, wait for the hold to complete (position kept), then a soft reset flushes the
  // planner; a reset in motion would cost the position (ALARM:3).
  write("!");
  const Clock::time_point start = Clock::now();
  while (std::chrono::duration<double>(Clock::now() - start).count() < options_.reply_timeout_s) {
    GrblStatus raw;
    query(&raw);
    if (raw.state == "Idle" || raw.state == "Alarm") return;
    if (raw.full_state == "Hold:0") break;  // hold complete ("Hold:1": still decelerating)
  }
  reset_and_wait_banner();
}

}  // namespace accel_intrinsics
