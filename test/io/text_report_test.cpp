// offline_fit's text report (io/text_report.h): the parameter table read back line by line
// equals the fit's numbers in the units it states (angles and their standard uncertainties in
// degrees, responsivities and offsets as fitted).
#include "accel_intrinsics/io/text_report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <sstream>
#include <string>
#include <utility>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace {

TEST(TextReport, ParameterTableStatesTheFitInItsUnits) {
  core::SimulationOptions sim;
  sim.truth.S << 1.02, 0.015, -0.02, 0.018, 0.97, 0.012, -0.011, 0.021, 1.03;
  sim.truth.O << 0.12, -0.08, 0.2;
  sim.seed = 4;
  const core::FitResult fit = core::fit(core::simulate_position_table(sim));
  std::ostringstream out;
  io::write_fit_report(out, fit, io::ResultContext{});
  // "  NAME   VALUE  +- STD UNIT"
  std::map<std::string, std::pair<double, double>> table;
  std::istringstream lines(out.str());
  for (std::string line; std::getline(lines, line);) {
    std::istringstream f(line);
    std::string name, pm;
    double value = 0.0, std_value = 0.0;
    if (f >> name >> value >> pm >> std_value && pm == "+-") table[name] = {value, std_value};
  }
  const char* angles[3] = {"theta_uv", "theta_vw", "theta_wu"};
  const char* axes[3] = {"u", "v", "w"};
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(table.count(angles[i])) << out.str();
    const double deg = core::rad_to_deg(fit.intrinsics.angles_rad(i));
    const double deg_std = core::rad_to_deg(fit.intrinsics.angles_std_rad(i));
    EXPECT_NEAR(table[angles[i]].first, deg, 1e-9 * deg) << angles[i];
    EXPECT_NEAR(table[angles[i]].second, deg_std, 5e-3 * deg_std) << angles[i];  // 3 digits
    const std::string r = std::string("|") + axes[i] + "|";
    ASSERT_TRUE(table.count(r)) << out.str();
    EXPECT_NEAR(table[r].first, fit.intrinsics.responsivity(i), 1e-10) << r;
    EXPECT_NEAR(table[r].second, fit.intrinsics.responsivity_std(i),
                5e-3 * fit.intrinsics.responsivity_std(i)) << r;
    const std::string o = std::string("O_") + axes[i];
    ASSERT_TRUE(table.count(o)) << out.str();
    EXPECT_NEAR(table[o].first, fit.O(i), 1e-10) << o;
    EXPECT_NEAR(table[o].second, fit.O_std(i), 5e-3 * fit.O_std(i)) << o;
  }
}

}  // namespace
}  // namespace accel_intrinsics
