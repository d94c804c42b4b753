// replay_through_node.test: replay.launch against a bag written here from simulate_recording;
// the calibration node under `rosbag play --clock` gives offline_fit's result to the last digit.
// noise_model_replay.test (slow_bias): the run begins with a 60 s rest and every sample carries a
// Gauss-Markov bias generated here from its recursion (not the simulator's slow-bias code): both
// sides estimate the noise model from the rest and fit with it, to the same digits.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "../support/bag_writer.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/ros/conversions.h"
#include "offline_compare.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;
namespace oc = offline_compare;

namespace {

// A run as the stand would record it: stamps from t = 1000 s, bag time = stamp, and `tail_s` of
// samples after DONE (a recorder keeps running until the result is out; 0: the bag ends at DONE,
// and so does the clock of the replay).
// A first-order Gauss-Markov bias per axis, from its exact discretization:
// b(k+1) = phi b(k) + sigma sqrt(1 - phi^2) w(k), phi = exp(-dt / tau), b(0) ~ N(0, sigma^2).
void add_gauss_markov_bias(core::Recording* rec, double sigma, double tau_s, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> w(0.0, 1.0);
  Eigen::Vector3d b(sigma * w(rng), sigma * w(rng), sigma * w(rng));
  double t_prev = rec->samples.front().stamp_s;
  for (core::ImuSample& s : rec->samples) {
    const double phi = std::exp(-(s.stamp_s - t_prev) / tau_s);
    for (int k = 0; k < 3; ++k) b(k) = phi * b(k) + sigma * std::sqrt(1.0 - phi * phi) * w(rng);
    t_prev = s.stamp_s;
    s.outputs += b;
  }
}

void write_simulated_bag(const std::string& path, double tail_s, bool slow_bias) {
  core::SimulationOptions sim;
  sim.truth.S << 1.015, 0.012, -0.004, 0.002, 0.985, 0.018, -0.008, 0.011, 1.003;
  sim.truth.O = Eigen::Vector3d(0.04, -0.02, 0.09);
  sim.protocol.steps_per_phase = 6;
  sim.protocol.dwell_s = 1.0;
  sim.protocol.move_s = 0.5;
  sim.protocol.phase_change_s = 2.0;
  sim.seed = 11;
  if (slow_bias) sim.protocol.initial_rest_s = 60.0;
  core::Recording rec = core::simulate_recording(sim);
  if (slow_bias) add_gauss_markov_bias(&rec, 0.003, 10.0, 12);
  const double done = rec.commands.back().stamp_s;
  while (!rec.samples.empty() && rec.samples.back().stamp_s > done) rec.samples.pop_back();
  const core::ImuSample last = rec.samples.back();
  for (double t = done + 0.01; t < done + tail_s; t += 0.01) {
    core::ImuSample s = last;
    s.stamp_s = t;
    rec.samples.push_back(s);
  }
  ai::test_support::BagWriter bag(path);
  bag.stamp_offset_s = 1000.0;
  bag.recording(rec);
}

}  // namespace

TEST(ReplayThroughNode, ReplayLaunchGivesOfflineResult) {
  ros::NodeHandle pnh("~");
  std::string bag, temp_dir;
  // The node's reorder window (simulated s): wide enough that no message of the replay arrives
  // after it on a loaded machine (at `rate`, window / rate of wall time). offline_fit reads the
  // bag in stamp order, so any window that drops nothing gives its result.
  double rate = 2.0, timeout_s = 150.0, tail_s = 3.0, window_s = 5.0;
  bool slow_bias = false;
  if (!pnh.getParam("bag", bag)) {
    // A directory of this run's own: parallel or repeated runs never share a bag.
    const char* tmp = std::getenv("TMPDIR");
    std::string templ =
        std::string(tmp && *tmp ? tmp : "/tmp") + "/accel_intrinsics_replay_through_node_XXXXXX";
    ASSERT_NE(::mkdtemp(&templ[0]), nullptr) << templ << ": " << std::strerror(errno);
    temp_dir = templ;
    bag = temp_dir + "/run.bag";
  }
  pnh.getParam("rate", rate);
  pnh.getParam("timeout_s", timeout_s);
  pnh.getParam("tail_after_done_s", tail_s);
  pnh.getParam("reorder_window_s", window_s);
  pnh.getParam("slow_bias", slow_bias);
  write_simulated_bag(bag, tail_s, slow_bias);

  const oc::ToolRun r = oc::run_offline_fit({"--bag", bag, "--json", bag + ".json"}, bag + ".err");
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(oc::read_file(bag + ".json"));
  ASSERT_EQ(j["complete"], true) << j["warnings"].dump();
  // With the slow bias the rest gives a noise model that is not white (the fit below used it).
  EXPECT_EQ(j["noise_model"].is_object(), slow_bias) << j["noise_model"].dump();

  // roslaunch replay.launch on this test's master, in its own process group.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::setpgid(0, 0);
    const std::string bag_arg = "bag:=" + bag;
    const std::string rate_arg = "rate:=" + std::to_string(rate);
    const std::string window_arg = "reorder_window_s:=" + std::to_string(window_s);
    ::execlp("roslaunch", "roslaunch", "accel_intrinsics", "replay.launch", bag_arg.c_str(),
             rate_arg.c_str(), window_arg.c_str(), "output:=log", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  accel_intrinsics::IntrinsicResult online;
  std::string message;
  const bool ok = oc::wait_for_result("/calibration/get_intrinsics", timeout_s, &online, &message);
  ::kill(-child, SIGINT);
  int status = 0;
  for (int i = 0; i < 100 && ::waitpid(child, &status, WNOHANG) == 0; ++i)
    ros::WallDuration(0.1).sleep();
  if (::waitpid(child, &status, WNOHANG) == 0) {
    ::kill(-child, SIGKILL);
    ::waitpid(child, &status, 0);
  }
  ASSERT_TRUE(ok) << "no result from the replay: " << message;
  oc::expect_equal(online, j);
  // Passed: remove the directory (kept on failure, to look at).
  if (!temp_dir.empty() && !HasFailure() && std::getenv("KEEP_TEST_FILES") == nullptr) {
    std::system(("rm -rf '" + temp_dir + "'").c_str());
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "replay_through_node_test");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
