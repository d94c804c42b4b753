// GRBL 1.1 and SMC100 emulators on a pseudo-terminal.
#include "accel_intrinsics/emulators/emulators.h"

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace accel_intrinsics {

namespace {

std::string fmt(const char* format, double v) {
  char b[64];
  std::snprintf(b, sizeof b, format, v);
  return b;
}

const char kGarbage[] = "\x07#~q\xfe\xff@!\r\n";

}  // namespace

void EmulatorOptions::validate() const {
  if (!(rate_deg_s > 0.0) || !std::isfinite(rate_deg_s))
    throw std::invalid_argument("rate_deg_s must be > 0");
  if (!(home_s >= 0.0) || !std::isfinite(home_s))
    throw std::invalid_argument("home_s must be >= 0");
  static const char* const kFaults[] = {"none", "no_reply", "garbage", "error", "alarm", "vanish"};
  if (std::find_if(std::begin(kFaults), std::end(kFaults),
                   [&](const char* f) { return fault == f; }) == std::end(kFaults)) {
    throw std::invalid_argument(
        "fault must be none, no_reply, garbage, error, alarm or vanish (got '" + fault + "')");
  }
  if (fault_after < 0) throw std::invalid_argument("fault_after must be >= 0");
  if (addresses.empty()) throw std::invalid_argument("addresses must not be empty");
  for (int a : addresses) {
    if (a < 1 || a > 31) throw std::invalid_argument("addresses must lie in 1..31");
  }
}

DeviceEmulator::DeviceEmulator(const EmulatorOptions& options) : options_(options) {
  options_.validate();
  char name[256] = {0};
  if (openpty(&master_, &slave_, name, nullptr, nullptr) != 0) {
    throw std::runtime_error(std::string("cannot open a pseudo-terminal: ") + std::strerror(errno));
  }
  slave_path_ = name;
  // Raw on the slave (no echo, no line editing) before any host opens it; the slave stays open
  // here so that the master side never sees a hang-up between hosts.
  termios tio{};
  tcgetattr(slave_, &tio);
  cfmakeraw(&tio);
  tcsetattr(slave_, TCSANOW, &tio);
  fcntl(master_, F_SETFL, fcntl(master_, F_GETFL) | O_NONBLOCK);
  fcntl(master_, F_SETFD, FD_CLOEXEC);
  fcntl(slave_, F_SETFD, FD_CLOEXEC);
  for (const std::string& path : {options_.link_path, options_.log_path}) {
    const std::filesystem::path parent = std::filesystem::path(path).parent_path();
    std::error_code ignored;
    if (!path.empty() && !parent.empty()) std::filesystem::create_directories(parent, ignored);
  }
  if (!options_.link_path.empty()) {
    ::unlink(options_.link_path.c_str());
    if (::symlink(slave_path_.c_str(), options_.link_path.c_str()) != 0) {
      throw std::runtime_error("cannot link " + options_.link_path + " to " + slave_path_ + ": " +
                               std::strerror(errno));
    }
  }
  if (!options_.log_path.empty()) {
    std::ofstream truncate(options_.log_path, std::ios::trunc);  // a fresh log per emulator
  }
  start_ = Clock::now();
}

DeviceEmulator::~DeviceEmulator() {
  vanish();
}

std::string DeviceEmulator::fault_at_this_move() {
  if (options_.fault == "none" || moves_++ != options_.fault_after) return "none";
  if (options_.fault == "vanish") vanish();
  if (options_.fault == "no_reply") silent_ = true;
  return options_.fault;
}

void DeviceEmulator::vanish() {
  if (master_ >= 0) ::close(master_);
  if (slave_ >= 0) ::close(slave_);
  master_ = slave_ = -1;
  if (!options_.link_path.empty()) ::unlink(options_.link_path.c_str());
}

double DeviceEmulator::seconds_since_start() const {
  return std::chrono::duration<double>(Clock::now() - start_).count();
}

void DeviceEmulator::reply(const std::string& text) {
  if (silent_ || master_ < 0) return;
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(master_, text.data() + done, text.size() - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
    } else if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
      pollfd p{master_, POLLOUT, 0};
      ::poll(&p, 1, 100);
    } else {
      return;
    }
  }
}

void DeviceEmulator::on_bytes(const std::string& bytes) {
  for (const char c : bytes) {
    take_line_byte(c);
    if (vanished()) return;
  }
}

void DeviceEmulator::take_line_byte(char c) {
  if (c == '\n') {
    const std::string line = line_;
    line_.clear();
    log_command(line);
    on_line(line);
  } else if (c != '\r') {
    line_ += c;
  }
}

void DeviceEmulator::log_command(const std::string& command) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    commands_.push_back(command);
  }
  if (!options_.log_path.empty()) {
    std::ofstream out(options_.log_path, std::ios::app);
    out << command << "\n";
  }
}

std::vector<std::string> DeviceEmulator::commands() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return commands_;
}

bool DeviceEmulator::step(double timeout_s) {
  if (master_ < 0) return false;
  pollfd p{master_, POLLIN, 0};
  const int ready = ::poll(&p, 1, static_cast<int>(timeout_s * 1000.0));
  if (ready > 0 && (p.revents & POLLIN)) {
    char buffer[512];
    const ssize_t n = ::read(master_, buffer, sizeof buffer);
    if (n > 0) on_bytes(std::string(buffer, static_cast<std::size_t>(n)));
  }
  if (master_ >= 0) on_time();
  return master_ >= 0;
}

void DeviceEmulator::run(const std::atomic<bool>& stop) {
  while (!stop.load() && step(0.005)) {
  }
}

double EmulatedAxis::at(double t) const {
  if (t >= t1 || t1 <= t0) return to;
  if (t <= t0) return from;
  return from + (to - from) * (t - t0) / (t1 - t0);
}

void EmulatedAxis::go(double target, double t, double rate_deg_s) {
  from = at(t);
  to = target;
  t0 = t;
  t1 = t + std::abs(to - from) / rate_deg_s;
}

void EmulatedAxis::halt(double t) {
  from = to = at(t);
  t0 = t1 = t;
}

// --- GRBL -------------------------------------------------------------------------------------

GrblEmulator::GrblEmulator(const EmulatorOptions& options) : DeviceEmulator(options) {
  if (options_.needs_homing) state_ = "Alarm";
}

bool GrblEmulator::running(double t) const {
  for (const EmulatedAxis& a : axes_) {
    if (a.moving(t)) return true;
  }
  return false;
}

void GrblEmulator::soft_reset() {
  const double t = seconds_since_start();
  if (state_ == "Run") {
    for (EmulatedAxis& a : axes_) a.halt(t);
    state_ = "Alarm";  // ALARM:3, reset while in motion
    reply("ALARM:3\r\n");
  } else if (state_ != "Alarm") {
    for (EmulatedAxis& a : axes_) a.halt(t);
    state_ = options_.needs_homing && state_ == "Home" ? "Alarm" : "Idle";
  }
  discard_partial_line();
  homing_done_ = alarm_at_ = -1.0;
  reply("\r\nGrbl 1.1h ['$' for help]\r\n");
  if (state_ == "Alarm") reply("[MSG:'$H'|'$X' to unlock]\r\n");
}

void GrblEmulator::status_report() {
  const double t = seconds_since_start();
  std::string text = "<" + state_ + "|MPos:";
  for (int i = 0; i < 3; ++i) text += (i ? "," : "") + fmt("%.3f", axes_[i].at(t));
  text += "|FS:0,0";
  if (reports_++ % 10 == 0) text += "|WCO:0.000,0.000,0.000";
  reply(text + ">\r\n");
}

void GrblEmulator::on_bytes(const std::string& bytes) {
  for (const char c : bytes) {
    if (c == '?') {
      log_command("?");
      status_report();
    } else if (c == '\x18') {
      log_command("^X");
      soft_reset();
    } else if (c == '!') {
      log_command("!");
      if (state_ == "Run") {
        const double t = seconds_since_start();
        for (EmulatedAxis& a : axes_) a.halt(t);
        state_ = "Hold:0";
      }
    } else if (c == '~') {
      log_command("~");
      if (state_ == "Hold:0") state_ = "Idle";
    } else {
      take_line_byte(c);
      if (vanished()) return;
    }
  }
}

void GrblEmulator::on_line(const std::string& line) {
  if (line.empty()) {
    reply("ok\r\n");
  } else if (line == "$H") {
    if (!options_.needs_homing) {
      reply("error:5\r\n");  // homing not enabled
      return;
    }
    state_ = "Home";
    for (EmulatedAxis& a : axes_) a.halt(seconds_since_start());
    homing_done_ = seconds_since_start() + options_.home_s;
  } else if (line == "$X") {
    if (state_ == "Alarm") {
      state_ = "Idle";
      reply("[MSG:Caution: Unlocked]\r\n");
    }
    reply("ok\r\n");
  } else if (line[0] == '$') {
    reply("error:3\r\n");
  } else {
    move(line);
  }
}

void GrblEmulator::move(const std::string& line) {
  // Words: a letter and a number, optionally separated by spaces.
  std::map<char, double> targets;
  bool g0 = false;
  std::size_t i = 0;
  while (i < line.size()) {
    if (line[i] == ' ') {
      ++i;
      continue;
    }
    const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(line[i])));
    if (!std::isalpha(static_cast<unsigned char>(letter))) {
      reply("error:1\r\n");
      return;
    }
    char* end = nullptr;
    const double value = std::strtod(line.c_str() + i + 1, &end);
    if (end == line.c_str() + i + 1) {
      reply("error:2\r\n");
      return;
    }
    i = static_cast<std::size_t>(end - line.c_str());
    if (letter == 'G') {
      if (value == 0.0)
        g0 = true;
      else if (value != 21.0 && value != 90.0) {
        reply("error:20\r\n");
        return;
      }
    } else if (letter == 'X' || letter == 'Y' || letter == 'Z') {
      targets[letter] = value;
    } else {
      reply("error:20\r\n");
      return;
    }
  }
  if (state_ == "Alarm") {
    reply("error:9\r\n");
    return;
  }
  if (!g0 || targets.empty()) {
    reply("ok\r\n");
    return;
  }
  const std::string fault = fault_at_this_move();
  if (ends_conversation(fault)) return;
  if (fault == "garbage") {
    reply(kGarbage);
    return;
  }
  if (fault == "error") {
    reply("error:" + std::to_string(options_.error_code) + "\r\n");
    return;
  }
  const double t = seconds_since_start();
  double longest = 0.0;
  for (const auto& target : targets) {
    EmulatedAxis& a = axes_[target.first - 'X'];
    a.go(target.second, t, options_.rate_deg_s);
    longest = std::max(longest, a.t1 - t);
  }
  state_ = "Run";
  if (fault == "alarm") alarm_at_ = t + 0.5 * longest;
  reply("ok\r\n");
}

void GrblEmulator::on_time() {
  const double t = seconds_since_start();
  if (homing_done_ >= 0.0 && t >= homing_done_) {
    homing_done_ = -1.0;
    for (EmulatedAxis& a : axes_) a = EmulatedAxis();
    state_ = "Idle";
    reply("ok\r\n");
  }
  if (alarm_at_ >= 0.0 && t >= alarm_at_) {
    alarm_at_ = -1.0;
    for (EmulatedAxis& a : axes_) a.halt(t);
    state_ = "Alarm";
    reply("ALARM:" + std::to_string(options_.alarm_code) + "\r\n[MSG:Reset to continue]\r\n");
  }
  if (state_ == "Run" && !running(t)) state_ = "Idle";
}

// --- SMC100 -----------------------------------------------------------------------------------

Smc100Emulator::Smc100Emulator(const EmulatorOptions& options) : DeviceEmulator(options) {
  for (int a : options_.addresses) {
    Controller c;
    c.state = options_.needs_homing ? 0x0A : 0x32;
    controllers_[a] = c;
  }
}

void Smc100Emulator::on_line(const std::string& received) {
  // The manual: spaces are ignored anywhere, and commands are not case-sensitive.
  std::string line;
  for (char ch : received) {
    if (ch != ' ') line += static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  }
  std::size_t i = 0;
  while (i < line.size() && std::isdigit(static_cast<unsigned char>(line[i]))) ++i;
  if (i == 0 || line.size() < i + 2) return;  // not addressed: nobody answers
  const int address = std::atoi(line.substr(0, i).c_str());
  const auto it = controllers_.find(address);
  if (it == controllers_.end()) return;  // no controller at that address
  Controller& c = it->second;
  const std::string prefix = line.substr(0, i);
  const std::string command = line.substr(i, 2);
  std::string arg = line.substr(i + 2);
  const bool query = arg == "?";
  if (query) arg.clear();
  const double t = seconds_since_start();
  auto answer = [&](const std::string& text) {
    if (garbage_pending_) {
      garbage_pending_ = false;
      reply(kGarbage);
      return;
    }
    reply(prefix + command + text + "\r\n");
  };
  if (command == "TS" && arg.empty()) {
    char value[16];
    std::snprintf(value, sizeof value, "%04X%02X", c.errors & 0xffff, c.state & 0xff);
    answer(value);
  } else if (command == "TP" && arg.empty()) {
    answer(fmt("%.6f", c.axis.at(t)));
  } else if (command == "TE" && arg.empty()) {
    answer(std::string(1, c.error));
    c.error = '@';
  } else if (command == "PA" && query) {
    answer(fmt("%.6f", c.target));
  } else if (command == "PA") {
    char* end = nullptr;
    const double value = std::strtod(arg.c_str(), &end);
    if (arg.empty() || end != arg.c_str() + arg.size()) {
      c.error = 'C';  // parameter missing or out of range
      return;
    }
    if (c.state >= 0x0A && c.state <= 0x11) {
      c.error = 'H';
      return;
    }
    if (c.state >= 0x3C && c.state <= 0x3E) {
      c.error = 'J';
      return;
    }
    const std::string fault = fault_at_this_move();
    if (ends_conversation(fault)) return;
    if (fault == "garbage") garbage_pending_ = true;
    if (fault == "error") {
      c.error = 'G';  // displacement out of limits
      return;
    }
    c.target = value;
    c.axis.go(value, t, options_.rate_deg_s);
    c.state = 0x28;
    if (fault == "alarm") c.alarm_at = t + 0.5 * (c.axis.t1 - t);
  } else if (command == "OR" && arg.empty()) {
    if (c.state >= 0x0A && c.state <= 0x11) {
      c.state = 0x1E;
      c.homing_done = t + options_.home_s;
    } else {
      // Already homing: E; otherwise "not allowed in <state>": CONFIGURATION I, DISABLE J,
      // READY K, MOVING M.
      c.error = c.state == 0x1E || c.state == 0x1F   ? 'E'
                : c.state == 0x14                    ? 'I'
                : c.state >= 0x3C && c.state <= 0x3E ? 'J'
                : c.state == 0x28                    ? 'M'
                                                     : 'K';
    }
  } else if (command == "RS" && arg.empty()) {
    c.axis.halt(t);
    c.state = 0x0A;
    c.errors = 0;
  } else if (command == "ST" && arg.empty()) {
    c.axis.halt(t);
    if (c.state == 0x28) c.state = 0x33;
  } else {
    c.error = 'A';  // unknown message code
  }
}

void Smc100Emulator::on_time() {
  const double t = seconds_since_start();
  for (auto& entry : controllers_) {
    Controller& c = entry.second;
    if (c.homing_done >= 0.0 && t >= c.homing_done) {
      c.homing_done = -1.0;
      c.axis = EmulatedAxis();
      c.state = 0x32;
    }
    if (c.alarm_at >= 0.0 && t >= c.alarm_at) {
      c.alarm_at = -1.0;
      c.axis.halt(t);
      c.errors = 0x0020;  // following error
      c.state = 0x3D;     // DISABLE from MOVING
    }
    if (c.state == 0x28 && !c.axis.moving(t)) c.state = 0x33;
  }
}

}  // namespace accel_intrinsics
