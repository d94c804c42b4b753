// calibration/dwell (accel_intrinsics/Dwell, docs/design.md section 17): a row of the position
// table as the message says it, and offline_fit reading a bag that holds the topic beside the
// run (as record.launch records it) exactly as the same bag without it: the topic is ignored as
// any other.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "../support/bag_writer.h"
#include "../support/test_files.h"
#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/ros/dwell_message.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

namespace {

using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

constexpr double kG = 9.80665;
constexpr double kPi = 3.14159265358979323846;

TEST(DwellMessage, CarriesTheRowAsTheTableHasIt) {
  core::DwellRecord row;
  row.phase = core::Phase::Y;
  row.step = 7;
  row.angle_rad = 1.25;
  row.t_start_s = 100.5;
  row.t_end_s = 102.5;
  row.n = 2000;
  row.mean = Eigen::Vector3d(9.7, -0.2, 1.5);
  row.std = Eigen::Vector3d(0.011, 0.012, 0.013);
  const ai::Dwell m = ai::to_dwell_msg(row, 19, "dut");
  EXPECT_EQ(m.phase, ai::Dwell::PHASE_Y);
  EXPECT_EQ(m.step, 7u);
  EXPECT_EQ(m.index, 19u);
  EXPECT_EQ(m.angle, 1.25);
  EXPECT_EQ(m.t_start, 100.5);
  EXPECT_EQ(m.t_end, 102.5);
  EXPECT_EQ(m.header.stamp.toSec(), 102.5);
  EXPECT_EQ(m.header.frame_id, "dut");
  EXPECT_EQ(m.n, 2000u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(m.mean[i], row.mean(i));
    EXPECT_EQ(m.std[i], row.std(i));
  }
  EXPECT_TRUE(std::isnan(m.temperature));
  row.temperature_c = 23.5;
  EXPECT_EQ(ai::to_dwell_msg(row, 0, "").temperature, 23.5);
  row.orientation_unknown = true;  // a rest of a hand tumble
  EXPECT_EQ(ai::to_dwell_msg(row, 0, "").phase, ai::Dwell::PHASE_UNKNOWN);
}

// 3 phases x 6 steps written from eq. (4) by hand; with_dwells adds the calibration/dwell message
// of each dwell (its hand-computed mean) at its end, as the node publishes it.
void write_run(const std::string& path, bool with_dwells) {
  ai::test_support::BagWriter bag(path);
  Eigen::Matrix3d S;
  S << 1.01, 0.02, -0.01, 0.0, 0.99, 0.03, 0.01, -0.02, 1.02;
  const Eigen::Vector3d O(0.1, -0.2, 0.05);
  double t = 50.0;
  std::uint32_t index = 0;
  for (int phase = 0; phase < 3; ++phase) {
    for (std::uint32_t step = 0; step < 6; ++step, ++index) {
      const double a = 2.0 * kPi * step / 6.0;
      Eigen::Vector3d f;
      if (phase == 0) f = Eigen::Vector3d(0, std::sin(a), std::cos(a));
      if (phase == 1) f = Eigen::Vector3d(std::sin(a), 0, std::cos(a));
      if (phase == 2) f = Eigen::Vector3d(std::sin(a), std::cos(a), 0);
      const Eigen::Vector3d R = S * (kG * f) + O;
      bag.command(t, phase, step, 6, a, ai::GimbalCommand::MOVING);
      bag.command(t + 0.5, phase, step, 6, a, ai::GimbalCommand::SETTLED);
      for (int i = 0; i < 5; ++i)
        bag.sample(t + 0.5 + 0.1 * i, R + Eigen::Vector3d::Constant(0.01 * (i - 2)));
      if (with_dwells) {
        core::DwellRecord row;
        row.phase = static_cast<core::Phase>(phase);
        row.step = step;
        row.angle_rad = a;
        row.t_start_s = t + 0.5;
        row.t_end_s = t + 1.0;
        row.n = 5;
        row.mean = R;
        bag.write("/calibration/dwell", t + 1.0, ai::to_dwell_msg(row, index, "dut"));
      }
      t += 1.0;
    }
  }
  bag.command(t, 2, 5, 6, 2.0 * kPi * 5 / 6.0, ai::GimbalCommand::DONE);
}

int run(const std::string& bag, const std::string& csv, const std::string& json, std::string* err) {
  ai::OfflineFitArguments args;
  args.bags = {bag};
  args.csv_out = csv;
  args.json_out = json;
  std::ostringstream out, e;
  const int status = ai::run_offline_fit(args, out, e);
  *err = e.str();
  return status;
}

TEST(DwellTopic, OfflineFitIgnoresItAsAnyOtherTopic) {
  TempDir dir;
  write_run(dir.file("plain.bag"), false);
  write_run(dir.file("with_dwells.bag"), true);
  std::string err_plain, err_dwells;
  ASSERT_EQ(run(dir.file("plain.bag"), dir.file("plain.csv"), dir.file("plain.json"), &err_plain),
            0)
      << err_plain;
  ASSERT_EQ(run(dir.file("with_dwells.bag"), dir.file("dwells.csv"), dir.file("dwells.json"),
                &err_dwells),
            0)
      << err_dwells;
  EXPECT_EQ(err_dwells, err_plain);
  EXPECT_EQ(read_file(dir.file("dwells.csv")), read_file(dir.file("plain.csv")));
  const std::string table = read_file(dir.file("plain.csv"));
  EXPECT_EQ(std::count(table.begin(), table.end(), '\n'), 19);  // header + 18 dwells
  // The results differ only where they name their input file.
  nlohmann::json a = nlohmann::json::parse(read_file(dir.file("plain.json")));
  nlohmann::json b = nlohmann::json::parse(read_file(dir.file("dwells.json")));
  ASSERT_TRUE(a.contains("input"));
  a.erase("input");
  b.erase("input");
  EXPECT_EQ(a.dump(), b.dump());
}

}  // namespace
