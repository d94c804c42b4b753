// compare_results: the command line of the comparison tool (include/accel_intrinsics/ros/
// compare_results.h).
#include "accel_intrinsics/ros/compare_results.h"

#include <CLI/CLI.hpp>
#include <iostream>

#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;

int main(int argc, char** argv) {
  CLI::App app{
      "Compares calibration results of one accelerometer (E_n; reference value and degrees "
      "of equivalence for three or more) with their expanded uncertainties."};
  app.footer("Exit status: 0 consistent (every |E_n| <= 1); 1 not consistent; 2 bad input.");
  ai::CompareResultsArguments args;
  app.add_option("results", args.files, "result files (offline_fit --json, node YAML)")->required();
  app.add_option("--json", args.json_out, "write the comparison as JSON ('-': stdout)");
  app.add_option("--plot", args.plot_out, "plot each parameter's values with their U (PNG)");
  app.add_flag("--type-a-only", args.type_a_only,
               "use U = 2 x the type-A uncertainties (results without uncertainty_budget)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "compare_results: error: " << ai::as_one_line(e.what()) << " (see --help)"
              << std::endl;
    return ai::kCompareBadInput;
  }
  return ai::run_compare_results(args, std::cout, std::cerr);
}
