// noise_report in process: a CSV and a bag of simulated static samples with known white noise
// give N within 5 %; the JSON, kalibr YAML and PNG appear; bad input is one line and no file.
#include "accel_intrinsics/ros/noise_report.h"

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>

#include "../support/bag_writer.h"
#include "../support/test_files.h"

namespace ai = accel_intrinsics;
namespace fs = std::filesystem;

namespace {

using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

constexpr double kRate = 100.0;
const double kDensity[3] = {0.001, 0.0015, 0.002};  // (m/s^2)/sqrt(Hz), continuous-time

// White noise of known density on static outputs.
template <typename Sink>
void simulate(std::size_t n, Sink sink) {
  std::mt19937_64 rng(21);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    double v[3];
    for (int a = 0; a < 3; ++a)
      v[a] = (a == 2 ? 9.81 : 0.02) + kDensity[a] * std::sqrt(kRate) * normal(rng);
    sink(100.0 + i / kRate, v);
  }
}

TEST(NoiseReport, CsvGivesNAndWritesJsonKalibrAndPlot) {
  TempDir dir;
  const std::string csv = dir.file("samples.csv");
  {
    std::ofstream out(csv);
    out << "t,u,v,w\n";
    out.precision(17);
    simulate(60000, [&](double t, const double* v) {
      out << t << ',' << v[0] << ',' << v[1] << ',' << v[2] << '\n';
    });
  }
  ai::NoiseReportArguments args;
  args.csv = csv;
  args.json_out = dir.file("noise.json");
  args.kalibr_out = dir.file("imu.yaml");
  args.plot_out = dir.file("allan.png");
  std::ostringstream out, err;
  ASSERT_EQ(ai::run_noise_report(args, out, err), 0) << err.str();
  EXPECT_NE(out.str().find("u: N "), std::string::npos) << out.str();
  const nlohmann::json j = nlohmann::json::parse(read_file(args.json_out));
  const char* axes[3] = {"u", "v", "w"};
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(j["noise_density"][axes[a]].get<double>(), kDensity[a], 0.05 * kDensity[a])
        << axes[a];
    for (const char* key : {"noise_density_std", "bias_instability", "bias_instability_std",
                            "bias_instability_tau_s", "random_walk", "random_walk_std"}) {
      EXPECT_TRUE(j[key][axes[a]].is_number()) << key;
    }
  }
  EXPECT_NEAR(j["rate_hz"].get<double>(), kRate, 1e-6);
  EXPECT_NEAR(j["duration_s"].get<double>(), 59999 / kRate, 1e-6);
  EXPECT_EQ(j["allan"]["tau_s"].size(), j["allan"]["adev"]["u"].size());
  const YAML::Node kalibr = YAML::LoadFile(args.kalibr_out);
  EXPECT_NEAR(kalibr["accelerometer_noise_density"].as<double>(), kDensity[2], 0.05 * kDensity[2]);
  EXPECT_TRUE(kalibr["accelerometer_random_walk"]);
  EXPECT_NEAR(kalibr["update_rate"].as<double>(), kRate, 1e-3);
  const std::string png = read_file(args.plot_out);
  ASSERT_GT(png.size(), 1000u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
}

TEST(NoiseReport, BagGivesTheSameAsCsv) {
  TempDir dir;
  const std::string bag_path = dir.file("static.bag");
  const std::string csv = dir.file("samples.csv");
  {
    ai::test_support::BagWriter bag(bag_path);
    std::ofstream out(csv);
    out << "t,u,v,w\n";
    out.precision(17);
    simulate(20000, [&](double t, const double* v) {
      const sensor_msgs::Imu m = bag.sample(t, Eigen::Vector3d(v[0], v[1], v[2]));
      out << m.header.stamp.toSec() << ',' << v[0] << ',' << v[1] << ',' << v[2] << '\n';
    });
  }
  ai::NoiseReportArguments from_bag, from_csv;
  from_bag.bag = bag_path;
  from_bag.json_out = dir.file("bag.json");
  from_csv.csv = csv;
  from_csv.json_out = dir.file("csv.json");
  std::ostringstream out, err;
  ASSERT_EQ(ai::run_noise_report(from_bag, out, err), 0) << err.str();
  ASSERT_EQ(ai::run_noise_report(from_csv, out, err), 0) << err.str();
  const nlohmann::json a = nlohmann::json::parse(read_file(from_bag.json_out));
  const nlohmann::json b = nlohmann::json::parse(read_file(from_csv.json_out));
  for (const char* axis : {"u", "v", "w"}) {
    EXPECT_NEAR(a["noise_density"][axis].get<double>(), b["noise_density"][axis].get<double>(),
                1e-9 * b["noise_density"][axis].get<double>());
  }
}

TEST(NoiseReport, BadInputIsOneLineAndNoFile) {
  TempDir dir;
  std::ofstream(dir.file("bad.csv")) << "t,u,v,w\n0,1,2,3\n0.01,1,x,3\n";
  std::ofstream(dir.file("short.csv")) << "t,u,v,w\n0,1,2,3\n0.01,1,2,3\n";
  std::ofstream(dir.file("header.csv")) << "time,x,y,z\n0,1,2,3\n";
  struct Case {
    std::string csv, bag, expected;
    int status;
  };
  const Case cases[] = {
      {dir.file("missing.csv"), "", "cannot read '" + dir.file("missing.csv") + "'", 1},
      {dir.file("bad.csv"), "", "line 3", 1},
      {dir.file("short.csv"), "", "at least 100 samples", 1},
      {dir.file("header.csv"), "", "header t,u,v,w", 1},
      {"", dir.file("missing.bag"), "missing.bag", 1},
      {dir.file("bad.csv"), dir.file("x.bag"), "exactly one of", 2},
  };
  for (const Case& c : cases) {
    ai::NoiseReportArguments args;
    args.csv = c.csv;
    args.bag = c.bag;
    args.json_out = dir.file("out.json");
    std::ostringstream out, err;
    EXPECT_EQ(ai::run_noise_report(args, out, err), c.status) << c.expected;
    const std::string message = err.str();
    EXPECT_EQ(std::count(message.begin(), message.end(), '\n'), 1) << message;
    EXPECT_EQ(err.str().rfind("noise_report: error: ", 0), 0u) << err.str();
    EXPECT_NE(err.str().find(c.expected), std::string::npos) << err.str();
    EXPECT_FALSE(fs::exists(args.json_out));
  }
}

}  // namespace
