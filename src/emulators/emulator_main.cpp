// Command line of the device emulators.
#include "accel_intrinsics/emulators/emulator_main.h"

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstring>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "accel_intrinsics/emulators/emulators.h"

namespace accel_intrinsics {

namespace {

std::atomic<bool> g_stop{false};

void on_signal(int) {
  g_stop = true;
}

}  // namespace

int emulator_main(const char* kind, int argc, char** argv) {
  const std::string name = std::string(kind) + "_emulator";
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    if (i == 0 || std::strstr(argv[i], ":=") == nullptr) args.push_back(argv[i]);
  }
  EmulatorOptions o;
  const bool smc = std::string(kind) == "smc100";
  CLI::App app(smc ? "Newport SMC100 controllers on a pseudo-terminal"
                   : "A GRBL 1.1 controller on a pseudo-terminal");
  app.add_option("--link", o.link_path, "symlink to the pseudo-terminal (the port to configure)");
  app.add_option("--log", o.log_path, "write every command received to this file, one per line");
  app.add_option("--rate-deg-s", o.rate_deg_s, "speed of every axis, deg/s")->capture_default_str();
  app.add_option("--home-s", o.home_s, "duration of homing, s")->capture_default_str();
  app.add_flag("--needs-homing", o.needs_homing,
               smc ? "controllers start NOT REFERENCED (home with OR)"
                   : "homing enabled: Alarm after reset until $H or $X");
  app.add_option("--fault", o.fault, "none | no_reply | garbage | error | alarm | vanish")
      ->capture_default_str();
  app.add_option("--fault-after", o.fault_after, "moves answered normally before the fault")
      ->capture_default_str();
  app.add_option("--error-code", o.error_code, "GRBL error:N of --fault error")
      ->capture_default_str();
  app.add_option("--alarm-code", o.alarm_code, "GRBL ALARM:N of --fault alarm")
      ->capture_default_str();
  std::vector<int> addresses;
  if (smc) app.add_option("--address", addresses, "controller address 1..31 (repeat; default 1)");
  try {
    app.parse(static_cast<int>(args.size()), args.data());
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (!addresses.empty()) o.addresses = addresses;
  std::unique_ptr<DeviceEmulator> emulator;
  try {
    if (smc) {
      emulator.reset(new Smc100Emulator(o));
    } else {
      emulator.reset(new GrblEmulator(o));
    }
  } catch (const std::exception& e) {
    std::cerr << name << ": " << e.what() << std::endl;
    return 2;
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::cout << name << ": serving on " << emulator->port()
            << (o.link_path.empty() ? "" : " (linked from " + o.link_path + ")")
            << (o.fault == "none"
                    ? ""
                    : ", fault " + o.fault + " after " + std::to_string(o.fault_after) + " moves")
            << std::endl;
  emulator->run(g_stop);
  if (emulator->vanished() && !g_stop) {
    std::cout << name << ": vanished (injected fault)" << std::endl;
  }
  return 0;
}

}  // namespace accel_intrinsics
