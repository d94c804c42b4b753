// offline_fit on bags made the way real recordings go wrong (docs/design.md section 5): IMU stamps
// on another clock or epoch, duplicated and reordered messages, another frame_id, a run split
// over several bags, an IMU topic under another name, gaps, outputs in other units. Each ends
// in the clean run's result or one line that says what is wrong and how to fix it.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <stdlib.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "../support/bag_writer.h"
#include "../support/test_files.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/ros/conversions.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;
using json = nlohmann::json;

namespace {

using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

core::SimulationOptions stand() {
  core::SimulationOptions sim;
  sim.truth.S << 1.02, 0.01, -0.005, 0.003, 0.98, 0.02, -0.01, 0.015, 1.005;
  sim.truth.O = Eigen::Vector3d(0.05, -0.03, 0.12);
  sim.protocol.steps_per_phase = 8;
  sim.protocol.dwell_s = 1.5;
  sim.rate_hz = 200.0;
  sim.seed = 17;
  return sim;
}

// One message as a recorder would store it: topic, receive time, payload.
struct Message {
  double receive_s;
  bool is_command;
  core::GimbalEvent command;
  core::ImuSample sample;
};

struct BagRecipe {
  double imu_clock_offset_s = 0.0;  // added to IMU stamps (the device's clock)
  int duplicate_every = 0;          // every k-th IMU message written twice
  double receive_jitter_s = 0.0;    // IMU receive times jittered: bag order != stamp order
  std::string imu_topic = "/imu/data_raw";
  std::string frame_id = "dut";
  double gap_begin_s = -1.0, gap_end_s = -1.0;  // IMU silent (stamps, run time)
  double output_scale = 1.0;                    // outputs in other units
};

std::vector<Message> messages(const core::Recording& rec, const BagRecipe& r) {
  std::vector<Message> out;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(0.0, r.receive_jitter_s);
  for (const core::GimbalEvent& c : rec.commands) {
    core::GimbalEvent e = c;
    e.stamp_s += 1000.0;
    out.push_back({e.stamp_s + 0.001, true, e, {}});
  }
  int k = 0;
  for (const core::ImuSample& s : rec.samples) {
    if (s.stamp_s >= r.gap_begin_s && s.stamp_s < r.gap_end_s) continue;
    core::ImuSample shifted = s;
    shifted.stamp_s += 1000.0 + r.imu_clock_offset_s;
    shifted.outputs *= r.output_scale;
    const double receive =
        s.stamp_s + 1000.0 + 0.002 + (r.receive_jitter_s > 0 ? jitter(rng) : 0.0);
    out.push_back({receive, false, {}, shifted});
    if (r.duplicate_every > 0 && ++k % r.duplicate_every == 0) {
      out.push_back({receive + 0.003, false, {}, shifted});
    }
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const Message& a, const Message& b) { return a.receive_s < b.receive_s; });
  return out;
}

// Writes `msgs` into `files` bags split by receive time (rosbag record --split).
void write_bags(const std::vector<std::string>& files, const std::vector<Message>& msgs,
                const BagRecipe& r) {
  const double t0 = msgs.front().receive_s, t1 = msgs.back().receive_s;
  std::vector<std::unique_ptr<ai::test_support::BagWriter>> bags;
  for (const std::string& f : files) {
    bags.emplace_back(new ai::test_support::BagWriter(f));
    bags.back()->imu_topic = r.imu_topic;
    bags.back()->frame_id = r.frame_id;
  }
  for (const Message& m : msgs) {
    auto i = static_cast<std::size_t>((m.receive_s - t0) / (t1 - t0 + 1e-9) * files.size());
    i = std::min(i, files.size() - 1);
    if (m.is_command) {
      bags[i]->command(m.command, m.receive_s);
    } else {
      bags[i]->sample(m.sample, m.receive_s);
    }
  }
  for (auto& b : bags) b->close();
}

struct ToolResult {
  int status = 0;
  std::string out, err;
  json result;
};

ToolResult offline_fit(std::vector<std::string> bags, const std::string& json_path,
                       double imu_time_offset = 0.0, bool offset_given = false) {
  ai::OfflineFitArguments args;
  args.bags = std::move(bags);
  args.json_out = json_path;
  args.imu_time_offset_s = imu_time_offset;
  args.imu_time_offset_given = offset_given;
  std::ostringstream out, err;
  ToolResult r;
  r.status = ai::run_offline_fit(args, out, err);
  r.out = out.str();
  r.err = err.str();
  std::ifstream in(json_path);
  if (in) r.result = json::parse(in);
  return r;
}

// The clean run, once.
const json& clean_result() {
  static json result = [] {
    TempDir dir;
    const core::Recording rec = core::simulate_recording(stand());
    write_bags({dir.file("clean.bag")}, messages(rec, {}), {});
    const ToolResult r = offline_fit({dir.file("clean.bag")}, dir.file("clean.json"));
    EXPECT_EQ(r.status, 0) << r.err;
    return r.result;
  }();
  return result;
}

json fit_part(json j) {
  for (const char* k : {"input", "complete", "warnings"}) j.erase(k);
  return j;
}

ToolResult run_recipe(const BagRecipe& recipe, const TempDir& dir, double offset = 0.0,
                      bool given = false) {
  const core::Recording rec = core::simulate_recording(stand());
  write_bags({dir.file("run.bag")}, messages(rec, recipe), recipe);
  return offline_fit({dir.file("run.bag")}, dir.file("run.json"), offset, given);
}

void expect_one_error_line(const ToolResult& r, const std::string& needle) {
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find("offline_fit: error: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << "expected '" << needle << "' in " << r.err;
}

// The value after "pass --imu-time-offset" in a message (NaN when absent).
double offset_named(const std::string& err) {
  const std::string key = "pass --imu-time-offset ";
  const std::size_t at = err.find(key);
  return at == std::string::npos ? std::nan("") : std::stod(err.substr(at + key.size()));
}

TEST(MessyBags, ImuClockFiveSecondsLateIsNamedAndFixedByTheOption) {
  TempDir dir;
  BagRecipe recipe;
  recipe.imu_clock_offset_s = 5.0;
  const ToolResult r = run_recipe(recipe, dir);
  EXPECT_EQ(r.status, ai::kOfflineFitBadInput);
  expect_one_error_line(r, "s later than the gimbal's");
  EXPECT_NEAR(offset_named(r.err), -5.0, 0.05) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir.file("run.json")));

  TempDir fixed_dir;
  const ToolResult fixed = run_recipe(recipe, fixed_dir, -5.0, true);
  ASSERT_EQ(fixed.status, 0) << fixed.err;
  EXPECT_EQ(fit_part(fixed.result), fit_part(clean_result()));
  EXPECT_EQ(fixed.result["input"]["imu_time_offset_s"], -5.0);
}

TEST(MessyBags, ImuOnAnotherEpochIsNamed) {
  TempDir dir;
  BagRecipe recipe;
  recipe.imu_clock_offset_s = 1.7e9;  // device time since 1970, gimbal on a clock from 1000 s
  const ToolResult r = run_recipe(recipe, dir);
  EXPECT_EQ(r.status, ai::kOfflineFitBadInput);
  expect_one_error_line(r, "IMU stamps are 1700000000.0");
  EXPECT_NEAR(offset_named(r.err), -1.7e9, 0.05) << r.err;
}

TEST(MessyBags, WrongOffsetGivenNamesTheTotal) {
  TempDir dir;
  BagRecipe recipe;
  recipe.imu_clock_offset_s = 5.0;
  const ToolResult r = run_recipe(recipe, dir, -3.0, true);  // two seconds short
  EXPECT_EQ(r.status, ai::kOfflineFitBadInput);
  expect_one_error_line(r, "pass --imu-time-offset -5.0");
  EXPECT_NEAR(offset_named(r.err), -5.0, 0.05) << r.err;
}

TEST(MessyBags, DuplicatedReorderedMessagesAndAnotherFrameGiveTheCleanResult) {
  TempDir dir;
  BagRecipe recipe;
  recipe.duplicate_every = 7;
  recipe.receive_jitter_s = 0.05;
  recipe.frame_id = "imu_link";
  const ToolResult r = run_recipe(recipe, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(fit_part(r.result), fit_part(clean_result()));
  const std::uint64_t dups = r.result["input"]["duplicates"];
  EXPECT_GT(dups, 100u);
  EXPECT_EQ(r.result["input"]["dropped_late"], 0);
  EXPECT_NE(r.result["warnings"].dump().find("duplicated IMU messages"), std::string::npos);
}

TEST(MessyBags, RunSplitOverSeveralBagsEqualsOneBag) {
  TempDir dir;
  std::filesystem::create_directory(dir.file("split"));
  const core::Recording rec = core::simulate_recording(stand());
  BagRecipe recipe;
  recipe.receive_jitter_s = 0.05;  // messages cross the file boundaries out of stamp order
  const std::vector<std::string> files = {dir.file("split/run_2.bag"), dir.file("split/run_10.bag"),
                                          dir.file("split/run_0.bag")};
  write_bags(files, messages(rec, recipe), recipe);
  const ToolResult repeated = offline_fit(files, dir.file("a.json"));
  ASSERT_EQ(repeated.status, 0) << repeated.err;
  EXPECT_EQ(fit_part(repeated.result), fit_part(clean_result()));
  EXPECT_EQ(repeated.result["input"]["files"], 3);
  const ToolResult directory = offline_fit({dir.file("split")}, dir.file("b.json"));
  ASSERT_EQ(directory.status, 0) << directory.err;
  EXPECT_EQ(fit_part(directory.result), fit_part(clean_result()));

  std::filesystem::create_directory(dir.file("empty"));
  const ToolResult empty = offline_fit({dir.file("empty")}, dir.file("c.json"));
  EXPECT_EQ(empty.status, ai::kOfflineFitBadInput);
  expect_one_error_line(empty, "holds no *.bag files");
}

TEST(MessyBags, ImuTopicUnderAnotherNameIsFoundByTypeAndSaid) {
  TempDir dir;
  BagRecipe recipe;
  recipe.imu_topic = "/xsens/imu/data";
  const ToolResult r = run_recipe(recipe, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(fit_part(r.result), fit_part(clean_result()));
  EXPECT_NE(r.err.find("using /xsens/imu/data, the only sensor_msgs/Imu topic"), std::string::npos)
      << r.err;
}

TEST(MessyBags, GapsCostSamplesNotTheResult) {
  TempDir dir;
  BagRecipe recipe;
  recipe.gap_begin_s = 20.0;  // the IMU driver stalls for 0.7 s inside a dwell
  recipe.gap_end_s = 20.7;
  const ToolResult r = run_recipe(recipe, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  const json& clean = clean_result();
  EXPECT_LT(r.result["input"]["samples_used"].get<std::uint64_t>(),
            clean["input"]["samples_used"].get<std::uint64_t>());
  for (const char* s : {"u", "v", "w"}) {
    const double sigma = clean["responsivity_std"][s];
    EXPECT_NEAR(r.result["responsivity"][s].get<double>(), clean["responsivity"][s].get<double>(),
                2 * sigma);
  }
  EXPECT_TRUE(r.result["quality"]["pass"].get<bool>());
}

TEST(MessyBags, OutputsInCentimetresFailTheQualityGateWithExitThree) {
  TempDir dir;
  BagRecipe recipe;
  recipe.output_scale = 100.0;
  const ToolResult r = run_recipe(recipe, dir);
  EXPECT_EQ(r.status, ai::kOfflineFitQualityFailed) << r.err;
  ASSERT_TRUE(std::filesystem::exists(dir.file("run.json")));  // written anyway, marked
  EXPECT_FALSE(r.result["quality"]["pass"].get<bool>());
  EXPECT_NE(r.result["quality"]["reasons"].dump().find("output_unit"), std::string::npos);
  EXPECT_NE(r.err.find("fails the quality gate"), std::string::npos) << r.err;
  EXPECT_TRUE(clean_result()["quality"]["pass"].get<bool>());
  EXPECT_TRUE(clean_result()["quality"]["reasons"].empty());
}

}  // namespace
