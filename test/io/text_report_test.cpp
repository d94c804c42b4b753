// offline_fit's text report (io/text_report.h): the parameter table read back line by line
// equals the fit's numbers in the units it states (angles and their standard uncertainties in
// degrees, responsivities and offsets as fitted), each value rounded to its uncertainty (two
// significant digits of the uncertainty, the value to the same place); the noise-model line in
// words, without the parts that are zero.
#include "accel_intrinsics/io/text_report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <sstream>
#include <string>
#include <utility>

#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/constants.h"
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
  std::map<std::string, std::string> std_text;
  std::istringstream lines(out.str());
  for (std::string line; std::getline(lines, line);) {
    std::istringstream f(line);
    std::string name, pm, value_text, u_text;
    // (not the rows of S and P, "[ x +- u, ...]": checked below)
    if (f >> name >> value_text >> pm >> u_text && pm == "+-" && name != "[") {
      table[name] = {std::stod(value_text), std::stod(u_text)};
      std_text[name] = u_text;
      // The value has as many decimals as its uncertainty.
      const auto decimals = [](const std::string& t) {
        const std::size_t dot = t.find('.');
        return dot == std::string::npos ? 0 : static_cast<int>(t.size() - dot - 1);
      };
      EXPECT_EQ(decimals(value_text), decimals(u_text)) << line;
    }
  }
  // |printed - x| within half a step of the printed uncertainty's last digit; the uncertainty
  // has two significant digits (10..99 steps, 100 after rounding up).
  auto expect_rounded = [&](const std::string& name, double x, double u) {
    const std::string& t = std_text[name];
    const std::size_t dot = t.find('.');
    const double step =
        std::pow(10.0, -(dot == std::string::npos ? 0 : static_cast<int>(t.size() - dot - 1)));
    EXPECT_LE(std::abs(table[name].first - x), 0.5 * step * (1 + 1e-9)) << name << " " << x;
    EXPECT_LE(std::abs(table[name].second - u), 0.5 * step * (1 + 1e-9)) << name << " " << u;
    const double digits = table[name].second / step;
    EXPECT_GE(digits, 9.5) << name << " " << t;
    EXPECT_LE(digits, 100.5) << name << " " << t;
  };
  const char* angles[3] = {"theta_uv", "theta_vw", "theta_wu"};
  const char* axes[3] = {"u", "v", "w"};
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(table.count(angles[i])) << out.str();
    const double deg = core::rad_to_deg(fit.intrinsics.angles_rad(i));
    const double deg_std = core::rad_to_deg(fit.intrinsics.angles_std_rad(i));
    expect_rounded(angles[i], deg, deg_std);
    const std::string r = std::string("|") + axes[i] + "|";
    ASSERT_TRUE(table.count(r)) << out.str();
    expect_rounded(r, fit.intrinsics.responsivity(i), fit.intrinsics.responsivity_std(i));
    const std::string o = std::string("O_") + axes[i];
    ASSERT_TRUE(table.count(o)) << out.str();
    expect_rounded(o, fit.O(i), fit.O_std(i));
  }
  // The rows of P: each element rounded to its standard uncertainty.
  const std::size_t p_at = out.str().find("cross-sensitivity P");
  ASSERT_NE(p_at, std::string::npos) << out.str();
  std::istringstream p_rows(out.str().substr(p_at));
  std::string p_line;
  std::getline(p_rows, p_line);  // the heading
  for (int row = 0; row < 3; ++row) {
    ASSERT_TRUE(std::getline(p_rows, p_line));
    std::string text = p_line;
    for (char& ch : text)
      if (ch == '[' || ch == ']' || ch == ',') ch = ' ';
    std::istringstream f(text);
    for (int c = 0; c < 3; ++c) {
      std::string v, pm, u;
      ASSERT_TRUE(f >> v >> pm >> u) << p_line;
      EXPECT_EQ(pm, "+-") << p_line;
      const double step = std::pow(10.0, -static_cast<int>(u.size() - u.find('.') - 1));
      EXPECT_LE(std::abs(std::stod(v) - fit.cross_sensitivity(row, c)), 0.5 * step * (1 + 1e-9))
          << p_line;
      EXPECT_LE(std::abs(std::stod(u) - fit.cross_sensitivity_std(row, c)), 0.5 * step * (1 + 1e-9))
          << p_line;
    }
  }
  // No line prints more than 8 significant digits (the JSON has them all).
  EXPECT_EQ(out.str().find("0000000"), std::string::npos) << out.str();
}

TEST(TextReport, NoiseWordsLeaveOutWhatIsNotThere) {
  core::AxisNoiseModel rw;
  rw.white_std = 0.0051;  // per sample at 100 Hz: 5.1e-4 (m/s^2)/sqrt(Hz)
  rw.rw_density = 0.05312;
  rw.slow_scale_rel_var = 0.8649;  // relative std 0.93
  EXPECT_EQ(io::noise_axis_words("u", rw, 100.0, "m/s^2"),
            "u: white 0.00051 (m/s^2)/sqrt(Hz); random walk 0.053 (m/s^2)/sqrt(s) (relative std "
            "of its scale 0.93)");
  core::AxisNoiseModel gm;
  gm.gm_sigma = 0.0021;
  gm.gm_tau_s = 31.4;
  EXPECT_EQ(io::noise_axis_words("v", gm, 0.0, "counts"),
            "v: Gauss-Markov 0.0021 counts over 31 s");
  EXPECT_EQ(io::noise_axis_words("w", core::AxisNoiseModel{}, 100.0, "m/s^2"), "w: no slow part");
}

}  // namespace
}  // namespace accel_intrinsics
