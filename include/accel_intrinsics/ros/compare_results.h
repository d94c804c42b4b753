// compare_results as a library (src/nodes/compare_results.cpp is its command line; tests call
// run_compare_results in process):
//
//   compare_results A.json B.json [C.json ...] [--json OUT] [--plot OUT.png] [--type-a-only]
//
// Reads result files (offline_fit --json, the node's YAML), compares the nine intrinsic parameters
// (core/comparison.h: E_n for two, reference value and degrees of equivalence for three or more)
// with the expanded uncertainties of each result's uncertainty_budget, prints a table and writes
// the comparison JSON (io/comparison_document.h) and a plot (scripts/compare_results_plot).
// Exit 0 when consistent (every |E_n| <= 1), 1 when not, 2 on bad input (a file unreadable, no
// uncertainties, different g, a bad command line), with one line on stderr.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

namespace accel_intrinsics {

enum CompareResultsStatus : int {
  kCompareConsistent = 0,
  kCompareInconsistent = 1,
  kCompareBadInput = 2,
};

struct CompareResultsArguments {
  std::vector<std::string> files;
  std::string json_out;  // "-": standard output
  std::string plot_out;
  bool type_a_only = false;
};

int run_compare_results(const CompareResultsArguments& args, std::ostream& out, std::ostream& err);

}  // namespace accel_intrinsics
