// offline_fit on the known-orientation examples of docs/ (6-position flip and 24-position
// tumble, outputs in counts), written by tools/make_orientation_examples.py with numpy: the
// fitted responsivities and offsets equal the truth in the files' comments within 4 sigma, in
// counts per m/s^2 (the three angles and the nine vector components too), and the result
// states its output unit.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "../support/source_dir.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;
using json = nlohmann::json;

namespace {

struct Truth {
  double counts_per_ms2 = 0.0;
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  Eigen::Vector3d O = Eigen::Vector3d::Zero();
};

// The "# truth:" comment lines of an example.
Truth read_truth(const std::string& path) {
  std::ifstream in(path);
  Truth t;
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("# truth: counts_per_ms2=", 0) == 0) {
      t.counts_per_ms2 = std::stod(line.substr(24));
    } else if (line.rfind("# truth: S_", 0) == 0) {
      const int s = std::string("uvw").find(line[11]);
      std::istringstream fields(line.substr(13));
      std::string x;
      for (int c = 0; c < 3; ++c) {
        std::getline(fields, x, c < 2 ? ',' : ' ');
        t.S(s, c) = std::stod(x);
      }
      t.O(s) = std::stod(line.substr(line.find("=", line.find(" O_")) + 1));
    }
  }
  return t;
}

json fit_example(const std::string& name) {
  const std::string csv = accel_intrinsics::test_support::source_dir() + "/docs/examples/" + name;
  char templ[] = "/tmp/known_orientations_XXXXXX";
  const std::string dir = ::mkdtemp(templ);
  ai::OfflineFitArguments args;
  args.csv = csv;
  args.output_unit = "counts";
  args.json_out = dir + "/result.json";
  std::ostringstream out, err;
  const int status = ai::run_offline_fit(args, out, err);
  EXPECT_EQ(status, 0) << err.str();
  std::ifstream in(args.json_out);
  json j = json::parse(in);
  std::remove(args.json_out.c_str());
  ::rmdir(dir.c_str());
  return j;
}

void expect_truth(const std::string& name) {
  const Truth t =
      read_truth(accel_intrinsics::test_support::source_dir() + "/docs/examples/" + name);
  ASSERT_GT(t.counts_per_ms2, 0.0);
  const json j = fit_example(name);
  EXPECT_EQ(j["output_unit"], "counts");
  EXPECT_TRUE(j["quality"]["pass"].get<bool>()) << j["quality"].dump();
  const char* names[] = {"u", "v", "w"};
  for (int s = 0; s < 3; ++s) {
    const double r = j["responsivity"][names[s]], sd = j["responsivity_std"][names[s]];
    EXPECT_NEAR(r, t.counts_per_ms2 * t.S.row(s).norm(), 4 * sd) << name << " " << names[s];
    const double o = j["offset"][names[s]], osd = j["offset_std"][names[s]];
    EXPECT_NEAR(o, t.counts_per_ms2 * t.O(s), 4 * osd) << name << " " << names[s];
    EXPECT_GT(sd, 0.0);
  }
  const auto angle = [&](int a, int b) {
    return std::acos(t.S.row(a).normalized().dot(t.S.row(b).normalized())) * 180.0 / M_PI;
  };
  EXPECT_NEAR(j["angles_deg"]["uv"].get<double>(), angle(0, 1),
              4 * j["angles_std_deg"]["uv"].get<double>());
  EXPECT_NEAR(j["angles_deg"]["vw"].get<double>(), angle(1, 2),
              4 * j["angles_std_deg"]["vw"].get<double>());
  EXPECT_NEAR(j["angles_deg"]["wu"].get<double>(), angle(2, 0),
              4 * j["angles_std_deg"]["wu"].get<double>());
  // The vectors (rows of S, counts per m/s^2), component by component.
  for (int s = 0; s < 3; ++s) {
    for (int c = 0; c < 3; ++c) {
      const double v = j["vectors"][names[s]][c], sd = j["vectors_std"][names[s]][c];
      EXPECT_GT(sd, 0.0) << name << " " << names[s] << c;
      EXPECT_NEAR(v, t.counts_per_ms2 * t.S(s, c), 4 * sd) << name << " " << names[s] << c;
    }
  }
}

TEST(KnownOrientations, SixPositionFlipExample) {
  expect_truth("six_position.csv");
}

TEST(KnownOrientations, TumbleOf24Example) {
  expect_truth("tumble24.csv");
}

TEST(KnownOrientations, CountsWithoutOutputUnitFailTheQualityGate) {
  ai::OfflineFitArguments args;
  args.csv = accel_intrinsics::test_support::source_dir() + "/docs/examples/six_position.csv";
  std::ostringstream out, err;
  EXPECT_EQ(ai::run_offline_fit(args, out, err), ai::kOfflineFitQualityFailed);
  EXPECT_NE(err.str().find("output_unit"), std::string::npos) << err.str();
}

}  // namespace
