#include "accel_intrinsics/ros/compare_results.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <iomanip>
#include <ostream>

#include "accel_intrinsics/core/analysis/comparison.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/comparison_document.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/ros/offline_fit.h"
#include "accel_intrinsics/ros/scripts.h"

namespace accel_intrinsics {
namespace {

constexpr char kProgram[] = "compare_results";

struct BadInput {
  std::string message;
};

void print_table(const core::Comparison& c, std::ostream& out) {
  out << "comparison of " << c.results.size() << " results (g = " << c.local_gravity
      << " m/s^2, expanded uncertainties, k = " << c.coverage_factor << ")\n";
  for (std::size_t i = 0; i < c.results.size(); ++i)
    out << "  [" << i + 1 << "] " << c.results[i] << "\n";
  for (const core::ParameterComparison& p : c.parameters) {
    out << std::left << std::setw(16) << p.name << std::right;
    for (std::size_t i = 0; i < p.values.size(); ++i)
      out << "  [" << i + 1 << "] " << std::setprecision(8) << p.values[i] << " +- "
          << std::setprecision(2) << p.expanded[i];
    if (c.results.size() >= 3)
      out << "  ref " << std::setprecision(8) << p.reference << " +- " << std::setprecision(2)
          << p.reference_expanded;
    out << "  E_n";
    for (double e : p.E_n)
      out << " " << std::fixed << std::setprecision(2) << e << std::defaultfloat;
    bool ok = true;
    for (double e : p.E_n) ok = ok && std::abs(e) <= 1.0;
    out << (ok ? "" : "  <-- |E_n| > 1") << "\n";
  }
  out << (c.consistent ? "consistent: every |E_n| <= 1\n" : "NOT consistent: some |E_n| > 1\n");
}

int run(const CompareResultsArguments& args, std::ostream& out, std::ostream& err) {
  if (args.files.size() < 2) throw BadInput{"give at least two result files"};
  std::vector<core::ComparedResult> inputs;
  try {
    for (const std::string& f : args.files)
      inputs.push_back(io::compared_result(io::read_result_file(f), f, args.type_a_only));
  } catch (const io::IoError& e) {
    throw BadInput{as_one_line(e.what())};
  } catch (const core::ComparisonError& e) {
    throw BadInput{as_one_line(e.what())};
  }
  core::Comparison c;
  try {
    c = core::compare(inputs);
  } catch (const core::ComparisonError& e) {
    throw BadInput{as_one_line(e.what())};
  }
  const std::string json = io::comparison_json_text(c, args.type_a_only);
  const bool json_to_stdout = args.json_out == "-";
  if (!args.json_out.empty() && !json_to_stdout) io::write_file_atomically(args.json_out, json);
  if (!args.plot_out.empty()) {
    const std::string tmp = args.plot_out + ".json.tmp." + std::to_string(::getpid());
    io::write_file_atomically(tmp, json);
    const int status = run_package_script("compare_results_plot", {"--out", args.plot_out, tmp});
    std::remove(tmp.c_str());
    if (status != 0)
      throw BadInput{"--plot: " + package_script("compare_results_plot") + " failed (exit status " +
                     std::to_string(status) + "); it needs /usr/bin/python3 with matplotlib"};
  }
  print_table(c, json_to_stdout ? err : out);
  if (json_to_stdout) out << json << std::flush;
  return c.consistent ? kCompareConsistent : kCompareInconsistent;
}

}  // namespace

int run_compare_results(const CompareResultsArguments& args, std::ostream& out, std::ostream& err) {
  try {
    return run(args, out, err);
  } catch (const BadInput& b) {
    err << kProgram << ": error: " << b.message << std::endl;
  } catch (const std::exception& e) {
    err << kProgram << ": error: " << as_one_line(e.what()) << std::endl;
  }
  return kCompareBadInput;
}

}  // namespace accel_intrinsics
