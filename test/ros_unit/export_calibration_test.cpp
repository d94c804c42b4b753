// offline_fit --export and export_calibration, in process: the files appear (all or nothing),
// their numbers are the result's, and bad input gives one clear line and no file.
#include "accel_intrinsics/ros/export_calibration.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "../support/test_files.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;
namespace fs = std::filesystem;

namespace {

using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

int lines(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

// A simulated position table as CSV.
std::string write_table(const TempDir& dir) {
  ai::core::SimulationOptions sim;
  sim.seed = 3;
  sim.truth.S << 1.01, 0.01, -0.02, 0.015, 0.98, 0.01, -0.01, 0.02, 1.02;
  sim.truth.O << 0.05, -0.03, 0.1;
  const std::string path = dir.file("table.csv");
  std::ofstream out(path);
  ai::core::write_position_table(out, ai::core::simulate_position_table(sim));
  return path;
}

// offline_fit's JSON result of write_table's table; empty (and a test failure) when it fails.
std::string fitted_result(const TempDir& dir) {
  ai::OfflineFitArguments fit;
  fit.csv = write_table(dir);
  fit.json_out = dir.file("result.json");
  std::ostringstream out, err;
  const int code = ai::run_offline_fit(fit, out, err);
  EXPECT_EQ(code, 0) << err.str();
  return code == 0 ? fit.json_out : std::string();
}

Eigen::Matrix3d rows_of(const nlohmann::json& j) {
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = j.at(r).at(c).get<double>();
  return m;
}

TEST(OfflineFitExport, WritesEveryRequestedFormatWithTheResultsNumbers) {
  TempDir dir;
  ai::OfflineFitArguments args;
  args.csv = write_table(dir);
  args.json_out = dir.file("result.json");
  args.exports = {"imu_calib=" + dir.file("calib.yaml"), "px4=" + dir.file("px4.params"),
                  "kalibr=" + dir.file("imu.yaml")};
  std::ostringstream out, err;
  ASSERT_EQ(ai::run_offline_fit(args, out, err), ai::kOfflineFitOk) << err.str();
  // px4 states its leftover error on stderr.
  EXPECT_NE(
      err.str().find("offline_fit: note: px4 export: largest error left over all orientations"),
      std::string::npos)
      << err.str();
  const nlohmann::json result = nlohmann::json::parse(read_file(args.json_out));
  const Eigen::Matrix3d P = rows_of(result.at("cross_sensitivity"));
  const YAML::Node calib = YAML::LoadFile(dir.file("calib.yaml"));
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(calib["SM"][i].as<double>(), P(i / 3, i % 3), 1e-12);
  EXPECT_NE(read_file(dir.file("calib.yaml")).find("offline_fit result of " + args.csv),
            std::string::npos);
  EXPECT_TRUE(YAML::LoadFile(dir.file("imu.yaml"))["imu0"]["accelerometers"]["M"]);
  EXPECT_NE(read_file(dir.file("px4.params")).find("CAL_ACC0_ZSCALE"), std::string::npos);
}

TEST(OfflineFitExport, BadSpecIsACommandLineErrorAndWritesNothing) {
  TempDir dir;
  const std::string table = write_table(dir);
  for (const std::string& spec : {std::string("matlab=") + dir.file("x"), std::string("px4"),
                                  "imu_calib=" + dir.file("result.json")}) {
    ai::OfflineFitArguments args;
    args.csv = table;
    args.json_out = dir.file("result.json");
    args.exports = {"imucal=" + dir.file("ok.json"), spec};
    std::ostringstream out, err;
    EXPECT_EQ(ai::run_offline_fit(args, out, err), ai::kOfflineFitBadCommandLine) << spec;
    EXPECT_EQ(lines(err.str()), 1) << err.str();
    EXPECT_EQ(err.str().rfind("offline_fit: error: ", 0), 0u) << err.str();
    EXPECT_EQ(static_cast<int>(dir.entries().size()), 1) << "only the table: " << spec;
  }
}

TEST(ExportCalibration, FromSavedResult) {
  TempDir dir;
  const std::string result_json = fitted_result(dir);
  ASSERT_FALSE(result_json.empty());

  ai::ExportCalibrationArguments args{result_json, "ardupilot", dir.file("a.param")};
  std::ostringstream err;
  EXPECT_EQ(ai::run_export_calibration(args, err), 0) << err.str();
  EXPECT_NE(err.str().find("export_calibration: note: ardupilot export: largest error"),
            std::string::npos);
  const std::string text = read_file(args.out);
  EXPECT_NE(text.find("INS_ACCSCAL_X,"), std::string::npos);
  EXPECT_NE(text.find("source result: " + result_json), std::string::npos);
}

TEST(ExportCalibration, RefusesAResultThatFailsTheQualityGate) {
  TempDir dir;
  const std::string result_json = fitted_result(dir);
  ASSERT_FALSE(result_json.empty());
  // The same result as a run that failed the gate would have stored it.
  nlohmann::json result = nlohmann::json::parse(read_file(result_json));
  result["quality"] = {{"pass", false}, {"reasons", {"reduced chi-square 812 is far above 1"}}};
  std::ofstream(dir.file("failed.json")) << result.dump(2);

  ai::ExportCalibrationArguments args{dir.file("failed.json"), "imu_calib", dir.file("calib.yaml")};
  std::ostringstream err;
  EXPECT_EQ(ai::run_export_calibration(args, err), 1);
  EXPECT_EQ(lines(err.str()), 1) << err.str();
  EXPECT_NE(err.str().find("fails the quality gate (reduced chi-square 812 is far above 1)"),
            std::string::npos)
      << err.str();
  EXPECT_FALSE(fs::exists(args.out));
}

TEST(ExportCalibration, BadInputIsOneLineAndNoFile) {
  TempDir dir;
  struct Case {
    ai::ExportCalibrationArguments args;
    std::string expected;
  };
  std::ofstream(dir.file("garbage.json")) << "{not json";
  const Case cases[] = {
      {{dir.file("missing.json"), "imu_calib", dir.file("out")},
       "cannot read '" + dir.file("missing.json") + "'"},
      {{dir.file("garbage.json"), "imu_calib", dir.file("out")}, dir.file("garbage.json")},
      {{dir.file("garbage.json"), "matlab", dir.file("out")}, "unknown export format 'matlab'"},
  };
  for (const Case& c : cases) {
    std::ostringstream err;
    EXPECT_EQ(ai::run_export_calibration(c.args, err), 1);
    EXPECT_EQ(lines(err.str()), 1) << err.str();
    EXPECT_NE(err.str().find("export_calibration: error: "), std::string::npos) << err.str();
    EXPECT_NE(err.str().find(c.expected), std::string::npos) << err.str();
    EXPECT_FALSE(fs::exists(dir.file("out")));
  }
}

}  // namespace
