// offline_fit with a DUT temperature topic (docs/design.md section 10): a bag written here by hand
// (test_support::BagWriter, not from our simulator) holds gimbal commands, IMU samples and
// sensor_msgs/Temperature readings; offline_fit must put the mean reading of each dwell into the
// position table's temperature_c column, computed here independently from the readings written.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/Temperature.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "../support/bag_writer.h"
#include "../support/test_files.h"
#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/ros/bag_input.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

namespace {

using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

constexpr double kG = 9.80665;
constexpr double kPi = 3.14159265358979323846;
constexpr std::size_t kTemperature = core::channel_index(core::Channel::Temperature);

std::string first_line(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

struct HandDwell {
  double settled = 0.0, end = 0.0;
  std::vector<double> readings;  // temperatures stamped inside [settled, end)
};

// 3 phases x 6 steps. Per position: MOVING at t, a temperature reading while moving (not in any
// dwell), SETTLED at t + 0.5, samples at t + 0.5 .. t + 0.9, temperature readings at t + 0.55 and
// t + 0.85 (and a third at t + 0.7 every other dwell), next MOVING at t + 1.0.
// The temperature climbs by 0.3 K per position with a wiggle; the readings differ per dwell.
std::vector<HandDwell> write_run(const std::string& path, bool with_temperature,
                                 const std::string& temperature_topic = "/imu/temperature") {
  ai::test_support::BagWriter bag(path);
  bag.receive_delay_s = 0.001;
  bag.temperature_topic = temperature_topic;
  Eigen::Matrix3d S;
  S << 1.01, 0.02, -0.01, 0.0, 0.99, 0.03, 0.01, -0.02, 1.02;
  const Eigen::Vector3d O(0.1, -0.2, 0.05);
  auto command = [&](double t, int phase, std::uint32_t step, double angle, std::uint8_t state) {
    bag.command(t, phase, step, 6, angle, state);
  };
  auto temperature = [&](double t, double celsius) {
    if (with_temperature) bag.temperature(t, celsius);
  };
  std::vector<HandDwell> dwells;
  double t = 50.0;
  int k = 0;
  for (int phase = 0; phase < 3; ++phase) {
    for (std::uint32_t step = 0; step < 6; ++step, ++k) {
      const double a = 2.0 * kPi * step / 6.0;
      Eigen::Vector3d f;
      if (phase == 0) f = Eigen::Vector3d(0, std::sin(a), std::cos(a));
      if (phase == 1) f = Eigen::Vector3d(std::sin(a), 0, std::cos(a));
      if (phase == 2) f = Eigen::Vector3d(std::sin(a), std::cos(a), 0);
      const Eigen::Vector3d R = S * (kG * f) + O;
      command(t, phase, step, a, ai::GimbalCommand::MOVING);
      temperature(t + 0.25, 99.0);  // while moving: in no dwell
      command(t + 0.5, phase, step, a, ai::GimbalCommand::SETTLED);
      HandDwell d;
      d.settled = t + 0.5;
      d.end = t + 1.0;
      for (int i = 0; i < 5; ++i) {
        bag.sample(t + 0.5 + 0.1 * i,
                   R + Eigen::Vector3d(0.01 * (i - 2), -0.01 * (i - 2), 0.005 * (i - 2)));
      }
      const double base = 21.0 + 0.3 * k + 0.1 * std::sin(k);
      std::vector<std::pair<double, double>> readings = {{t + 0.55, base}, {t + 0.85, base + 0.04}};
      if (k % 2 == 0) readings.push_back({t + 0.7, base - 0.07});
      for (const auto& r : readings) {
        temperature(r.first, r.second);
        d.readings.push_back(r.second);
      }
      dwells.push_back(d);
      t += 1.0;
    }
  }
  command(t, 2, 5, 2.0 * kPi * 5 / 6.0, ai::GimbalCommand::DONE);
  temperature(t + 0.2, 99.0);  // after DONE: in no dwell
  return dwells;
}

int run(const std::vector<std::string>& bags, const std::string& csv_out, std::string* err_text,
        const std::string& temperature_topic = "", const std::string& json_out = "",
        std::string* out_text = nullptr) {
  ai::OfflineFitArguments args;
  args.bags = bags;
  args.csv_out = csv_out;
  args.json_out = json_out;
  if (!temperature_topic.empty()) {
    args.channel_topics[kTemperature] = temperature_topic;
    args.channel_topic_given[kTemperature] = true;
  }
  std::ostringstream out, err;
  const int status = ai::run_offline_fit(args, out, err);
  *err_text = err.str();
  if (out_text) *out_text = out.str();
  return status;
}

TEST(OfflineFitTemperature, DwellMeansOfTheTemperatureTopicReachThePositionTable) {
  TempDir dir;
  const std::vector<HandDwell> dwells = write_run(dir.file("run.bag"), true);
  std::string err;
  std::string out;
  ASSERT_EQ(
      run({dir.file("run.bag")}, dir.file("table.csv"), &err, "", dir.file("result.json"), &out), 0)
      << err;
  EXPECT_EQ(first_line(dir.file("table.csv")),
            std::string(core::kPositionTableHeader) + ",temperature_c");
  // The result states T_ref (the mean of the dwell means) and the range.
  double sum = 0.0, lo = 1e9, hi = -1e9;
  for (const HandDwell& d : dwells) {
    double m = 0.0;
    for (double r : d.readings) m += r / d.readings.size();
    sum += m;
    lo = std::min(lo, m);
    hi = std::max(hi, m);
  }
  std::ifstream json_in(dir.file("result.json"));
  const nlohmann::json j = nlohmann::json::parse(json_in);
  ASSERT_TRUE(j.contains("temperature")) << j.dump();
  EXPECT_NEAR(j["temperature"]["reference_c"].get<double>(), sum / dwells.size(), 1e-9);
  EXPECT_NEAR(j["temperature"]["min_c"].get<double>(), lo, 1e-12);
  EXPECT_NEAR(j["temperature"]["max_c"].get<double>(), hi, 1e-12);
  EXPECT_EQ(j["temperature"]["dwells_with_temperature"].get<std::size_t>(), dwells.size());
  EXPECT_NE(out.find("S and O at T_ref"), std::string::npos) << out;
  const core::PositionTable table = core::read_position_table_file(dir.file("table.csv"));
  ASSERT_EQ(table.rows.size(), dwells.size());
  for (std::size_t i = 0; i < dwells.size(); ++i) {
    double sum = 0.0;
    for (double r : dwells[i].readings) sum += r;
    ASSERT_TRUE(table.rows[i].has_temperature()) << "row " << i;
    EXPECT_NEAR(table.rows[i].temperature_c, sum / dwells[i].readings.size(), 1e-12) << "row " << i;
    EXPECT_NEAR(table.rows[i].t_start_s, dwells[i].settled, 1e-9);
  }
}

// Both bag readers (the chunk scan and rosbag::View) give the same temperatures.
TEST(OfflineFitTemperature, ChunkScanAndRosbagViewAgree) {
  TempDir dir;
  const std::vector<HandDwell> dwells = write_run(dir.file("run.bag"), true);
  ai::BagInputOptions options;
  const ai::BagRun scan = ai::read_bag(dir.file("run.bag"), options);
  options.allow_chunk_scan = false;
  const ai::BagRun view = ai::read_bag(dir.file("run.bag"), options);
  EXPECT_EQ(scan.stats.reader, "chunk scan");
  EXPECT_EQ(view.stats.reader, "rosbag::View");
  EXPECT_EQ(scan.stats.channel_topics[kTemperature], "/imu/temperature");
  std::uint64_t written = 1;                                           // after DONE
  for (const HandDwell& d : dwells) written += d.readings.size() + 1;  // + 1 while moving
  EXPECT_EQ(scan.stats.channel_messages[kTemperature], written);
  EXPECT_EQ(view.stats.channel_messages[kTemperature], scan.stats.channel_messages[kTemperature]);
  ASSERT_EQ(scan.table.rows.size(), view.table.rows.size());
  for (std::size_t i = 0; i < scan.table.rows.size(); ++i)
    EXPECT_EQ(scan.table.rows[i].temperature_c, view.table.rows[i].temperature_c) << i;
  // Readings while moving and after DONE are in no dwell: counted as dropped.
  EXPECT_EQ(scan.stats.counters.channel_dropped[kTemperature], dwells.size() + 1);
}

TEST(OfflineFitTemperature, NamespacedTemperatureTopicIsFound) {
  TempDir dir;
  const std::vector<HandDwell> dwells =
      write_run(dir.file("run.bag"), true, "/stand1/imu/temperature");
  std::string err;
  ASSERT_EQ(run({dir.file("run.bag")}, dir.file("table.csv"), &err), 0) << err;
  const core::PositionTable table = core::read_position_table_file(dir.file("table.csv"));
  ASSERT_EQ(table.rows.size(), dwells.size());
  EXPECT_NEAR(table.rows[3].temperature_c, (dwells[3].readings[0] + dwells[3].readings[1]) / 2.0,
              1e-12);
}

TEST(OfflineFitTemperature, BagWithoutTemperatureStillFitsAndNamedTopicIsRequired) {
  TempDir dir;
  write_run(dir.file("run.bag"), false);
  std::string err;
  ASSERT_EQ(run({dir.file("run.bag")}, dir.file("table.csv"), &err), 0) << err;
  EXPECT_EQ(first_line(dir.file("table.csv")), core::kPositionTableHeader);
  const core::PositionTable table = core::read_position_table_file(dir.file("table.csv"));
  EXPECT_EQ(core::rows_with_temperature(table), 0u);
  ASSERT_EQ(run({dir.file("run.bag")}, "", &err, "", dir.file("plain.json")), 0) << err;
  std::ifstream json_in(dir.file("plain.json"));
  EXPECT_FALSE(nlohmann::json::parse(json_in).contains("temperature"));

  // Asked for by name: its absence is an error that names it.
  EXPECT_EQ(run({dir.file("run.bag")}, dir.file("t2.csv"), &err, "imu/temperature"), 1);
  EXPECT_NE(err.find("no temperature topic 'imu/temperature'"), std::string::npos) << err;
}

}  // namespace
