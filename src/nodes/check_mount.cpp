// check_mount: the command line (include/accel_intrinsics/ros/check_mount.h).
#include "accel_intrinsics/ros/check_mount.h"

#include <CLI/CLI.hpp>
#include <iostream>

namespace ai = accel_intrinsics;

int main(int argc, char** argv) {
  CLI::App app{
      "Judges a mount check's six poses (stdin: PHASE ANGLE_DEG N MEAN_U MEAN_V MEAN_W) "
      "against docs/design.md section 1; exit 0 correct, 4 a mistake named, 1 not run."};
  ai::CheckMountArguments args;
  app.add_option("--gravity", args.gravity, "local gravity, m/s^2")->capture_default_str();
  app.add_option("--output-unit", args.output_unit,
                 "unit of the outputs (the calibration's "
                 "output_unit)")
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "check_mount: error: " << e.what() << std::endl;
    return ai::kMountCouldNotRun;
  }
  return ai::run_check_mount(std::cin, args, std::cout, std::cerr);
}
