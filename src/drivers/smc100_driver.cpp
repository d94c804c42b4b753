// Newport SMC100 gimbal driver: one controller address per axis on one serial port.
#include "accel_intrinsics/drivers/smc100_driver.h"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <thread>

namespace accel_intrinsics {

namespace {

using Clock = std::chrono::steady_clock;

// The positioner error flags of TS (4 hex digits), as the manual names them.
std::string positioner_errors(int flags) {
  static const struct {
    int bit;
    const char* text;
  } kFlags[] = {{0x0200, "80 W output power exceeded"},
                {0x0100, "DC voltage too low"},
                {0x0080, "wrong ESP stage"},
                {0x0040, "homing time out"},
                {0x0020, "following error"},
                {0x0010, "short circuit detection"},
                {0x0008, "RMS current limit"},
                {0x0004, "peak current limit"},
                {0x0002, "positive end of run"},
                {0x0001, "negative end of run"}};
  std::string out;
  for (const auto& f : kFlags) {
    if (flags & f.bit) out += (out.empty() ? "" : ", ") + std::string(f.text);
  }
  return out;
}

}  // namespace

std::string smc100_state_text(int state) {
  switch (state) {
    case 0x0A: return "NOT REFERENCED from RESET";
    case 0x0B: return "NOT REFERENCED from HOMING";
    case 0x0C: return "NOT REFERENCED from CONFIGURATION";
    case 0x0D: return "NOT REFERENCED from DISABLE";
    case 0x0E: return "NOT REFERENCED from READY";
    case 0x0F: return "NOT REFERENCED from MOVING";
    case 0x10: return "NOT REFERENCED ESP stage error";
    case 0x11: return "NOT REFERENCED from JOGGING";
    case 0x14: return "CONFIGURATION";
    case 0x1E: return "HOMING commanded from RS-232-C";
    case 0x1F: return "HOMING commanded by SMC-RC";
    case 0x28: return "MOVING";
    case 0x32: return "READY from HOMING";
    case 0x33: return "READY from MOVING";
    case 0x34: return "READY from DISABLE";
    case 0x35: return "READY from JOGGING";
    case 0x3C: return "DISABLE from READY";
    case 0x3D: return "DISABLE from MOVING";
    case 0x3E: return "DISABLE from JOGGING";
    case 0x46: return "JOGGING from READY";
    case 0x47: return "JOGGING from DISABLE";
    default: return "";
  }
}

// The TE letters of Newport's SMC100CC/PP manual ('@': no error).
std::string smc100_error_text(char code) {
  switch (code) {
    case '@': return "no error";
    case 'A': return "unknown message code or floating point controller address";
    case 'B': return "controller address not correct";
    case 'C': return "parameter missing or out of range";
    case 'D': return "command not allowed";
    case 'E': return "home sequence already started";
    case 'F': return "ESP stage name unknown";
    case 'G': return "displacement out of limits";
    case 'H': return "command not allowed in NOT REFERENCED state";
    case 'I': return "command not allowed in CONFIGURATION state";
    case 'J': return "command not allowed in DISABLE state";
    case 'K': return "command not allowed in READY state";
    case 'L': return "command not allowed in HOMING state";
    case 'M': return "command not allowed in MOVING state";
    case 'N': return "current position out of software limit";
    case 'S': return "communication time out";
    case 'U': return "error during EEPROM access";
    case 'V': return "error during command execution";
    case 'W': return "command not allowed for PP version";
    case 'X': return "command not allowed for CC version";
    default: return "";
  }
}

bool smc100_is_ready(int state) {
  return state >= 0x32 && state <= 0x35;
}
bool smc100_is_moving(int state) {
  return state == 0x28 || state == 0x1E || state == 0x1F || state == 0x46 || state == 0x47;
}
bool smc100_not_referenced(int state) {
  return state >= 0x0A && state <= 0x11;
}

Smc100Driver::Smc100Driver(const SerialGimbalOptions& options) : SerialGimbalDriver(options) {
  std::vector<std::string> known;
  for (int a = 1; a <= 31; ++a) known.push_back(std::to_string(a));
  try {
    options_.axis_map.validate(known);
  } catch (const std::invalid_argument& e) {
    throw GimbalFault(std::string("smc100: ") + e.what() + " (axes are controller addresses)");
  }
  addresses_ = options_.axis_map.axes();
  start_device();
}

std::string Smc100Driver::query(const std::string& address, const std::string& command) {
  const std::string sent = address + command + "?";
  write(sent + "\r\n");
  const std::string reply = expect_line("'" + sent + "'");
  const std::string echo = address + command;
  if (reply.compare(0, echo.size(), echo) != 0 || reply.size() == echo.size()) {
    throw GimbalFault("smc100: unexpected reply '" + printable(reply) + "' to '" + sent + "'");
  }
  return reply.substr(echo.size());
}

void Smc100Driver::command(const std::string& address, const std::string& command) {
  write(address + command + "\r\n");
  const std::string error = query(address, "TE");
  if (error.size() != 1) {
    throw GimbalFault("smc100: unexpected reply '" + address + "TE" + printable(error) + "' to '" +
                      address + "TE?'");
  }
  if (error[0] != '@') {  // '@': no error
    const std::string text = smc100_error_text(error[0]);
    throw GimbalFault("smc100: address " + address + " refused '" + address + command + "': '" +
                      address + "TE" + error + "'" + (text.empty() ? "" : " (" + text + ")"));
  }
}

int Smc100Driver::state_of(const std::string& address, int* errors, std::string* reply) {
  const std::string value = query(address, "TS");
  *reply = address + "TS" + value;
  char* end = nullptr;
  const long code = value.size() == 6 ? std::strtol(value.c_str(), &end, 16) : -1;
  if (value.size() != 6 || end != value.c_str() + 6) {
    throw GimbalFault("smc100: unexpected reply '" + printable(*reply) + "' to '" + address +
                      "TS?'");
  }
  *errors = static_cast<int>(code >> 8);
  return static_cast<int>(code & 0xff);
}

void Smc100Driver::initialize() {
  for (const std::string& a : addresses_) {
    int errors = 0;
    std::string reply;
    int state = state_of(a, &errors, &reply);
    const bool disabled = state == 0x14 || (state >= 0x3C && state <= 0x3E);
    if ((disabled || errors != 0) && options_.home_at_start) {
      // After a fault (a following error disables the motor): reset the controller (RS), which
      // reboots it NOT REFERENCED, then home it below. It may not answer while it reboots.
      write(a + "RS\r\n");
      const Clock::time_point start = Clock::now();
      for (;;) {
        std::this_thread::sleep_for(std::chrono::duration<double>(options_.poll_interval_s));
        try {
          state = state_of(a, &errors, &reply);
          if (smc100_not_referenced(state)) break;
        } catch (const GimbalFault&) {
          // still rebooting
        }
        if (std::chrono::duration<double>(Clock::now() - start).count() > options_.home_timeout_s) {
          throw GimbalFault("smc100: address " + a +
                            " did not come back NOT REFERENCED after "
                            "the reset (RS) within home_timeout_s ('" +
                            reply + "')");
        }
      }
    }
    if (smc100_not_referenced(state)) {
      if (!options_.home_at_start) {
        throw GimbalFault("smc100: address " + a + " is " + smc100_state_text(state) + " ('" +
                          reply + "'): set home_at_start: true to home it (OR)");
      }
      command(a, "OR");
      const Clock::time_point start = Clock::now();
      for (;;) {
        state = state_of(a, &errors, &reply);
        if (smc100_is_ready(state)) break;
        if (state != 0x1E && state != 0x1F) {
          throw GimbalFault("smc100: address " + a + " homing failed: '" + reply + "' (" +
                            smc100_state_text(state) + ")");
        }
        if (std::chrono::duration<double>(Clock::now() - start).count() > options_.home_timeout_s) {
          throw GimbalFault("smc100: address " + a + " still homing after home_timeout_s = " +
                            std::to_string(options_.home_timeout_s) + " s ('" + reply + "')");
        }
        std::this_thread::sleep_for(std::chrono::duration<double>(options_.poll_interval_s));
      }
    } else if (!smc100_is_ready(state)) {
      throw GimbalFault("smc100: address " + a + " is " + smc100_state_text(state) + " ('" + reply +
                        "'), not READY: enable it or leave that state first");
    }
  }
}

void Smc100Driver::send_move(const std::map<std::string, double>& positions_deg) {
  char value[48];
  for (const auto& p : positions_deg) {
    std::snprintf(value, sizeof value, "PA%.4f", p.second);
    command(p.first, value);
  }
}

DeviceStatus Smc100Driver::poll_status() {
  DeviceStatus out;
  out.at_rest = true;
  std::ostringstream text;
  for (const std::string& a : addresses_) {
    int errors = 0;
    std::string reply;
    const int state = state_of(a, &errors, &reply);
    const std::string position = query(a, "TP");
    char* end = nullptr;
    const double deg = std::strtod(position.c_str(), &end);
    if (end != position.c_str() + position.size()) {
      throw GimbalFault("smc100: unexpected reply '" + a + "TP" + printable(position) + "' to '" +
                        a + "TP?'");
    }
    out.position[a] = deg;
    text << (text.tellp() > 0 ? " " : "") << reply << " " << a << "TP" << position;
    if (errors != 0) {
      throw GimbalFault("smc100: address " + a + " reports a positioner error: '" + reply + "' (" +
                        positioner_errors(errors) + "; state " + smc100_state_text(state) + ")");
    }
    if (smc100_not_referenced(state) || state == 0x14 || (state >= 0x3C && state <= 0x3E)) {
      throw GimbalFault("smc100: address " + a + " left READY: '" + reply + "' (" +
                        smc100_state_text(state) + ")");
    }
    if (!smc100_is_ready(state)) out.at_rest = false;
    if (!smc100_is_ready(state) && !smc100_is_moving(state) && smc100_state_text(state).empty()) {
      throw GimbalFault("smc100: address " + a + " reports an unknown state '" + reply + "'");
    }
  }
  out.text = text.str();
  return out;
}

void Smc100Driver::send_stop() {
  for (const std::string& a : addresses_) write(a + "ST\r\n");
}

}  // namespace accel_intrinsics
