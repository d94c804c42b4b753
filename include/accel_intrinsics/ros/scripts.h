// The package's python scripts (scripts/), run by the C++ tools: offline_fit --report runs
// certificate_report, compare_results --plot runs compare_results_plot, each with
// /usr/bin/python3 (matplotlib from Debian).
#pragma once

#include <string>
#include <vector>

namespace accel_intrinsics {

// $ACCEL_INTRINSICS_SCRIPTS/NAME, else NAME next to the running executable (installed, or the
// devel-space wrapper catkin puts there), else the package source's scripts/NAME.
std::string package_script(const std::string& name);

// Runs /usr/bin/python3 package_script(name) args... and waits; returns its exit status (-1 when
// it could not run or was killed). stdout and stderr are inherited.
int run_package_script(const std::string& name, const std::vector<std::string>& args);

}  // namespace accel_intrinsics
