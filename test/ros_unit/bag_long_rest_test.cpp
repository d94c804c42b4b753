// offline_fit's long rest from a bag in the one read (issue 38; docs/noise.md "offline_fit"): the
// assembler's release observers feed a core::LongRestRecorder (BagInputOptions::long_rest) as the
// live run does. The bag is written here by hand: a first dwell of 30 s at 1 kHz (gravity plus a
// white noise and a slow ramp, from the equations), then short dwells, messages written in an
// order that is not their stamps' (a recorder's transport delays). The recorder's noise model is
// the one noise_model_of_run gives on the samples written (the model offline_fit took from a
// second read until now), with and without a settle discard; a long rest that is not the first
// dwell is not claimed by the recorder (offline_fit then reads the bag again).
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "../support/bag_writer.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/noise/rest_accumulator.h"
#include "accel_intrinsics/ros/bag_input.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

namespace {

constexpr double kRateHz = 1000.0;

struct Written {
  std::vector<core::GimbalEvent> commands;
  std::vector<core::ImuSample> samples;  // in stamp order
};

// Dwell lengths: `dwells_s` in order, 0.5 s moves before each; phase x, 8 steps; DONE at the end.
// Messages are written in the order of stamp plus a delay of 0 to 20 ms.
Written write_bag(const std::string& path, const std::vector<double>& dwells_s) {
  Written w;
  double t = 100.0;
  for (std::size_t step = 0; step < dwells_s.size(); ++step) {
    core::GimbalEvent e;
    e.phase = core::Phase::X;
    e.steps = 8;
    e.step = static_cast<std::uint32_t>(step);
    e.angle_rad = 2.0 * M_PI * static_cast<double>(step) / 8.0;
    e.state = core::GimbalState::Moving;
    e.stamp_s = t;
    w.commands.push_back(e);
    e.state = core::GimbalState::Settled;
    e.stamp_s = t + 0.5;
    w.commands.push_back(e);
    t += 0.5 + dwells_s[step];
  }
  core::GimbalEvent done = w.commands.back();
  done.state = core::GimbalState::Done;
  done.stamp_s = t;
  w.commands.push_back(done);

  std::mt19937_64 rng(3838);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::uniform_real_distribution<double> delay(0.0, 0.02);
  const auto n = static_cast<std::size_t>(std::llround((t - 100.0) * kRateHz));
  for (std::size_t i = 0; i < n; ++i) {
    const double stamp = 100.0 + static_cast<double>(i) / kRateHz;
    std::size_t c = 0;
    while (c + 1 < w.commands.size() && w.commands[c + 1].stamp_s <= stamp) ++c;
    const double angle = w.commands[c].angle_rad;
    const double ramp = 1e-4 * (stamp - 100.0);  // a slow bias on u
    w.samples.push_back(
        {stamp, Eigen::Vector3d(ramp + noise(rng), 9.81 * std::sin(angle) + noise(rng),
                                9.81 * std::cos(angle) + noise(rng))});
  }
  struct Message {
    double receive_s;
    bool command;
    std::size_t index;
  };
  std::vector<Message> order;
  for (std::size_t i = 0; i < w.commands.size(); ++i)
    order.push_back({w.commands[i].stamp_s + delay(rng), true, i});
  for (std::size_t i = 0; i < w.samples.size(); ++i)
    order.push_back({w.samples[i].stamp_s + delay(rng), false, i});
  std::stable_sort(order.begin(), order.end(),
                   [](const Message& a, const Message& b) { return a.receive_s < b.receive_s; });
  ai::test_support::BagWriter bag(path);
  for (const Message& m : order) {
    if (m.command)
      bag.command(w.commands[m.index], m.receive_s);
    else
      bag.sample(w.samples[m.index], m.receive_s);
  }
  bag.close();
  return w;
}

std::string temp_bag(const std::string& name) {
  const char* dir = std::getenv("TMPDIR");
  return std::string(dir ? dir : "/tmp") + "/bag_long_rest_" + std::to_string(::getpid()) + "_" +
         name + ".bag";
}

// The model offline_fit took until issue 38's second pass: noise_model_of_run on every sample.
std::optional<core::NoiseModel> from_all_samples(const core::PositionTable& table,
                                                 const Written& w) {
  std::vector<double> stamps;
  std::vector<Eigen::Vector3d> outputs;
  for (const core::ImuSample& s : w.samples) {
    stamps.push_back(s.stamp_s);
    outputs.push_back(s.outputs);
  }
  return core::noise_model_of_run(table, stamps, outputs);
}

void expect_same_model(const core::NoiseModel& a, const core::NoiseModel& b) {
  EXPECT_EQ(a.rest_samples, b.rest_samples);
  EXPECT_EQ(a.rate_hz, b.rate_hz);
  EXPECT_EQ(a.source, b.source);
  EXPECT_EQ(a.rest_t_start_s, b.rest_t_start_s);
  EXPECT_EQ(a.rest_t_end_s, b.rest_t_end_s);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(a.axes[k].white_std, b.axes[k].white_std) << k;
    EXPECT_EQ(a.axes[k].gm_sigma, b.axes[k].gm_sigma) << k;
    EXPECT_EQ(a.axes[k].gm_tau_s, b.axes[k].gm_tau_s) << k;
    EXPECT_EQ(a.axes[k].rw_density, b.axes[k].rw_density) << k;
  }
  ASSERT_EQ(a.rest_blocks.size(), b.rest_blocks.size());
  for (std::size_t i = 0; i < a.rest_blocks.size(); ++i) {
    EXPECT_EQ(a.rest_blocks[i].n, b.rest_blocks[i].n) << i;
    EXPECT_EQ(a.rest_blocks[i].mean, b.rest_blocks[i].mean) << i;
    EXPECT_EQ(a.rest_blocks[i].t_start_s, b.rest_blocks[i].t_start_s) << i;
  }
}

class BagLongRest : public ::testing::TestWithParam<double> {};

TEST_P(BagLongRest, FirstDwellIsAccumulatedInTheOneRead) {
  const double settle_discard_s = GetParam();
  const std::string path = temp_bag("first");
  const Written w = write_bag(path, {30.0, 1.5, 1.5, 1.5, 1.5, 1.5});
  ai::BagInputOptions options;
  options.assembler.settle_discard_s = settle_discard_s;
  core::LongRestRecorder recorder(settle_discard_s);
  options.long_rest = &recorder;
  const ai::BagRun run = ai::read_bag(path, options);
  std::remove(path.c_str());
  ASSERT_EQ(run.table.rows.size(), 6u);
  ASSERT_TRUE(recorder.holds_long_rest(run.table, 0.0));
  const std::optional<core::NoiseModel> streamed = recorder.noise_model(run.table, 0.0);
  const std::optional<core::NoiseModel> batch = from_all_samples(run.table, w);
  ASSERT_TRUE(streamed.has_value());
  ASSERT_TRUE(batch.has_value());
  expect_same_model(*streamed, *batch);
  // Every sample of the rest, counted here from the stamps written: [SETTLED + discard, MOVING].
  const double t0 = w.commands[1].stamp_s + settle_discard_s, t1 = w.commands[2].stamp_s;
  const auto in_rest = std::count_if(w.samples.begin(), w.samples.end(), [&](const auto& s) {
    return s.stamp_s >= t0 && s.stamp_s <= t1;
  });
  EXPECT_EQ(streamed->rest_samples, static_cast<std::size_t>(in_rest));
  // The ramp is in the blocks: the last block's u mean is about 1e-4 x its middle time.
  const core::DwellRecord& last = streamed->rest_blocks.back();
  EXPECT_NEAR(last.mean(0), 1e-4 * (0.5 * (last.t_start_s + last.t_end_s) - 100.0), 2e-3);
}

INSTANTIATE_TEST_SUITE_P(SettleDiscard, BagLongRest, ::testing::Values(0.0, 0.2));

TEST(BagLongRest, ALaterLongRestIsNotClaimed) {
  const std::string path = temp_bag("later");
  const Written w = write_bag(path, {1.5, 1.5, 30.0, 1.5, 1.5, 1.5});
  ai::BagInputOptions options;
  core::LongRestRecorder recorder;
  options.long_rest = &recorder;
  const ai::BagRun run = ai::read_bag(path, options);
  std::remove(path.c_str());
  ASSERT_TRUE(core::find_long_rest(run.table).has_value());
  EXPECT_FALSE(recorder.holds_long_rest(run.table, 0.0));
  EXPECT_FALSE(recorder.noise_model(run.table, 0.0).has_value());
  // The samples read again give it (offline_fit's second read).
  EXPECT_TRUE(from_all_samples(run.table, w).has_value());
}

}  // namespace
