// offline_fit --residuals-csv (docs/offline_and_bags.md, docs/finding_the_missing_effect.md): the
// CSV that scripts/plot_residuals reads, checked against a position table the test writes from the
// equations of docs/design.md section 1 and against the fit's own JSON (vectors, offsets, reduced
// chi-square), so the CSV's model is the fitted device and its z-scores are the fit's.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "../support/source_dir.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;

namespace {

struct Dir {
  Dir() {
    char templ[] = "/tmp/offline_fit_residuals_XXXXXX";
    path = ::mkdtemp(templ);
  }
  ~Dir() { std::filesystem::remove_all(path); }
  std::string path;
};

struct ToolResult {
  int status = -1;
  std::string out, err;
};

ToolResult run_tool(const std::vector<std::string>& args) {
  ai::OfflineFitArguments a;
  int status = 0;
  std::ostringstream pout, perr;
  ToolResult r;
  if (!ai::parse_offline_fit_arguments(args, &a, &status, pout, perr)) {
    r.status = status;
    r.err = perr.str();
    return r;
  }
  std::ostringstream out, err;
  r.status = ai::run_offline_fit(a, out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

// Specific force of docs/design.md section 1 (unit g).
Eigen::Vector3d direction(char phase, double a) {
  if (phase == 'x') return {0.0, std::sin(a), std::cos(a)};
  if (phase == 'y') return {std::sin(a), 0.0, std::cos(a)};
  return {std::sin(a), std::cos(a), 0.0};
}

constexpr int kSteps = 8;
constexpr double kG = 9.80665;
constexpr double kStd = 0.01;  // sample std of each dwell, m/s^2
constexpr int kN = 100;        // samples per dwell: standard error 0.001 m/s^2

// A table from a device of the test's own, each mean off the model by a fixed pattern of up to
// 1.5 standard errors that the model cannot absorb, so that the residuals are not zero and the
// reduced chi-square is known only through the fit.
std::string write_table(const std::string& path) {
  Eigen::Matrix3d S;
  S << 1.012, 0.004, -0.003, -0.005, 0.987, 0.006, 0.002, -0.008, 1.003;
  const Eigen::Vector3d O(0.05, -0.03, 0.08);
  std::ofstream f(path);
  f << "phase,step,angle_rad,t_start,t_end,n,mean_u,mean_v,mean_w,std_u,std_v,std_w\n";
  f.precision(12);
  double t = 10.0;
  int k = 0;
  for (char phase : {'x', 'y', 'z'}) {
    ++k;
    for (int n = 0; n < kSteps; ++n, t += 3.0) {
      const double a = 2.0 * M_PI * n / kSteps;
      Eigen::Vector3d mean = S * (kG * direction(phase, a)) + O;
      // Period 4 in the step (the angle's second harmonic, which S and O cannot follow).
      for (int s = 0; s < 3; ++s) mean(s) += (((n + s + k) % 4) - 1.5) * kStd / std::sqrt(kN);
      f << phase << ',' << n << ',' << a << ',' << t << ',' << t + 2.0 << ',' << kN << ','
        << mean(0) << ',' << mean(1) << ',' << mean(2) << ',' << kStd << ',' << kStd << ',' << kStd
        << '\n';
    }
  }
  return path;
}

std::vector<std::map<std::string, std::string>> read_csv(const std::string& path,
                                                         std::string* header) {
  std::ifstream f(path);
  std::getline(f, *header);
  std::vector<std::string> names;
  std::stringstream hs(*header);
  for (std::string c; std::getline(hs, c, ',');) names.push_back(c);
  std::vector<std::map<std::string, std::string>> rows;
  for (std::string line; std::getline(f, line);) {
    std::stringstream ls(line);
    std::map<std::string, std::string> row;
    std::size_t i = 0;
    for (std::string c; std::getline(ls, c, ',') && i < names.size(); ++i) row[names[i]] = c;
    rows.push_back(row);
  }
  return rows;
}

}  // namespace

TEST(OfflineFitResiduals, CsvHoldsTheFittedModelAndTheFitsZScores) {
  Dir dir;
  const std::string table = write_table(dir.path + "/table.csv");
  const std::string csv = dir.path + "/residuals.csv", json = dir.path + "/result.json";
  const ToolResult r = run_tool({"--csv", table, "--json", json, "--residuals-csv", csv});
  ASSERT_EQ(r.status, 0) << r.err;
  std::string header;
  const auto rows = read_csv(csv, &header);
  // The columns plot_residuals reads (scripts/plot_residuals, read_csv).
  EXPECT_EQ(header,
            "phase,step,angle_rad,time_s,approach,accelerometer,measured,sigma,model_before,"
            "residual_before,z_before,model_after,residual_after,z_after");
  ASSERT_EQ(rows.size(), 3u * kSteps * 3u);

  nlohmann::json doc;
  std::ifstream(json) >> doc;
  const double g = doc["local_gravity"].get<double>();
  std::map<std::string, Eigen::Vector3d> vec;
  for (const char* s : {"u", "v", "w"}) {
    const auto& v = doc["vectors"][s];
    vec[s] = Eigen::Vector3d(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
  }
  double chi2 = 0.0;
  for (const auto& row : rows) {
    const std::string s = row.at("accelerometer");
    const char phase = row.at("phase")[0];
    const double a = std::stod(row.at("angle_rad"));
    const double measured = std::stod(row.at("measured"));
    const double model = std::stod(row.at("model_before"));
    const double sigma = std::stod(row.at("sigma"));
    // The model column is the JSON's fitted device at this dwell's orientation.
    const double expected = g * vec[s].dot(direction(phase, a)) + doc["offset"][s].get<double>();
    EXPECT_NEAR(model, expected, 1e-9) << phase << " " << a << " " << s;
    EXPECT_NEAR(sigma, kStd / std::sqrt(kN), 1e-12);
    EXPECT_NEAR(std::stod(row.at("residual_before")), measured - model, 1e-9);
    EXPECT_NEAR(std::stod(row.at("z_before")), (measured - model) / sigma, 1e-6);
    // Without --analyze "after" is the same fit.
    EXPECT_EQ(row.at("model_after"), row.at("model_before"));
    chi2 += std::pow(std::stod(row.at("z_before")), 2);
  }
  // The z-scores are the fit's: their squares sum to its chi-square (joint: 12 parameters).
  const double dof = 3.0 * kSteps * 3.0 - 12.0;
  EXPECT_NEAR(chi2 / dof, doc["reduced_chi2"].get<double>(),
              1e-6 * doc["reduced_chi2"].get<double>());
  EXPECT_GT(chi2 / dof, 0.5);  // the pattern written into the table is there
}

TEST(OfflineFitResiduals, AnalyzeGivesTheRefitAsAfter) {
  Dir dir;
  const std::string table = write_table(dir.path + "/table.csv");
  const std::string csv = dir.path + "/residuals.csv";
  const ToolResult r = run_tool({"--csv", table, "--analyze", "--residuals-csv", csv});
  ASSERT_EQ(r.status, 0) << r.err;
  std::string header;
  const auto rows = read_csv(csv, &header);
  ASSERT_EQ(rows.size(), 3u * kSteps * 3u);
  for (const auto& row : rows) {
    EXPECT_NEAR(std::stod(row.at("residual_after")),
                std::stod(row.at("measured")) - std::stod(row.at("model_after")), 1e-9);
  }
}

TEST(OfflineFitResiduals, HandTumbleIsRefusedWithAReasonAndNoFile) {
  Dir dir;
  const std::string csv = dir.path + "/residuals.csv";
  const ToolResult r = run_tool(
      {"--samples", ai::test_support::source_dir() + "/test/data/imu_tk_xsens/xsens_acc.mat",
       "--output-unit", "counts", "--residuals-csv", csv});
  EXPECT_EQ(r.status, ai::kOfflineFitBadCommandLine) << r.err;
  EXPECT_NE(r.err.find("--residuals-csv"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(csv));
}
