// export_calibration: the command line (include/accel_intrinsics/ros/export_calibration.h).
#include "accel_intrinsics/ros/export_calibration.h"

#include <CLI/CLI.hpp>
#include <iostream>

#include "accel_intrinsics/io/exporters.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;

int main(int argc, char** argv) {
  CLI::App app{
      "Writes a saved calibration result (offline_fit JSON or the calibration node's "
      "intrinsics.yaml) in the file format of another tool."};
  ai::ExportCalibrationArguments args;
  app.add_option("--result", args.result, "result file (JSON or YAML)")->required();
  app.add_option("--format", args.format, "one of: " + ai::io::export_format_list())->required();
  app.add_option("--out", args.out, "file to write")->required();
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << ai::kExportCalibrationProgram << ": error: " << ai::as_one_line(e.what())
              << " (see --help)" << std::endl;
    return 2;
  }
  return ai::run_export_calibration(args, std::cerr);
}
