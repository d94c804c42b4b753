// Timing lag from bags of the simulated stand (test/ros/timing_lag_on_stand.test).
#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>

#include <map>
#include <memory>

#include "../support/bag_writer.h"
#include "accel_intrinsics/GimbalCommand.h"
#include "offline_compare.h"
#include "stand_checks.h"

namespace {

// Writes one rig's gimbal commands and IMU messages into a bag as they arrive, as
// `rosbag record` would (receipt time as the bag time; offline_fit reads header stamps).
class RigRecorder {
 public:
  RigRecorder(ros::NodeHandle& nh, const std::string& ns, const std::string& path)
      : ns_(ns), bag_(path) {
    command_sub_ = nh.subscribe<accel_intrinsics::GimbalCommand>(
        stand_checks::join_ns(ns, "gimbal/command"), 1000,
        [this](const accel_intrinsics::GimbalCommand::ConstPtr& msg) {
          bag_.write(stand_checks::join_ns(ns_, "gimbal/command"), bag_time(msg->header.stamp),
                     *msg);
          if (msg->state == accel_intrinsics::GimbalCommand::DONE) done_ = true;
        });
    imu_sub_ = nh.subscribe<sensor_msgs::Imu>(
        stand_checks::join_ns(ns, "imu/data_raw"), 20000,
        [this](const sensor_msgs::Imu::ConstPtr& msg) {
          bag_.write(stand_checks::join_ns(ns_, "imu/data_raw"), bag_time(msg->header.stamp), *msg);
          ++imu_messages_;
        });
  }
  void close() {
    command_sub_.shutdown();
    imu_sub_.shutdown();
    bag_.close();
  }
  bool done() const { return done_; }
  std::size_t imu_messages() const { return imu_messages_; }

 private:
  // A bag refuses time zero (before the first /clock message): then the header stamp.
  static ros::Time bag_time(const ros::Time& stamp) {
    const ros::Time now = ros::Time::now();
    return now.isZero() ? (stamp.isZero() ? ros::TIME_MIN : stamp) : now;
  }

  std::string ns_;
  accel_intrinsics::test_support::BagWriter bag_;
  ros::Subscriber command_sub_, imu_sub_;
  bool done_ = false;
  std::size_t imu_messages_ = 0;
};

}  // namespace

TEST(TimingLagOnStand, EstimatedWithinFourSigmaOfTheTruthInBothRigs) {
  ros::NodeHandle nh, pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  std::vector<std::string> namespaces;
  std::vector<double> true_lag_s;
  double timeout_s = 300.0;
  std::string output_dir;
  ASSERT_TRUE(pnh.getParam("namespaces", namespaces));
  ASSERT_TRUE(pnh.getParam("true_lag_s", true_lag_s));
  ASSERT_EQ(namespaces.size(), true_lag_s.size());
  pnh.getParam("timeout_s", timeout_s);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  ASSERT_EQ(stand_checks::run("mkdir -p '" + output_dir + "'").exit_code, 0);

  // Recorders first (the controllers wait for supervise's start, so nothing is missed).
  std::vector<std::unique_ptr<RigRecorder>> recorders;
  for (const std::string& ns : namespaces) {
    recorders.emplace_back(new RigRecorder(nh, ns, output_dir + "/" + ns + ".bag"));
  }
  for (const std::string& ns : namespaces) {
    ASSERT_TRUE(ros::service::waitForService(
        stand_checks::join_ns(ns, "calibration/get_intrinsics"), ros::Duration(60.0)));
  }
  ros::AsyncSpinner spinner(1);  // one thread: the bag writes never run concurrently
  spinner.start();
  stand_checks::supervise_and_check(namespaces, limits, timeout_s, output_dir + "/supervise.json");
  const ros::WallTime drain_until = ros::WallTime::now() + ros::WallDuration(2.0);
  while (ros::WallTime::now() < drain_until) ros::WallDuration(0.05).sleep();
  spinner.stop();
  for (auto& recorder : recorders) {
    EXPECT_TRUE(recorder->done());
    EXPECT_GT(recorder->imu_messages(), 1000u);
    recorder->close();
  }

  for (std::size_t i = 0; i < namespaces.size(); ++i) {
    const std::string& ns = namespaces[i];
    SCOPED_TRACE("rig " + ns);
    const std::string bag = output_dir + "/" + ns + ".bag";
    const std::string json_path = output_dir + "/" + ns + "_offline.json";
    const offline_compare::ToolRun run = offline_compare::run_offline_fit(
        {"--bag", bag, "--imu-topic", stand_checks::join_ns(ns, "imu/data_raw"), "--command-topic",
         stand_checks::join_ns(ns, "gimbal/command"), "--analyze", "--json", json_path},
        output_dir + "/" + ns + "_offline.err");
    ASSERT_EQ(run.status, 0) << run.err;
    const nlohmann::json j = nlohmann::json::parse(offline_compare::read_file(json_path));
    ASSERT_TRUE(j.contains("timing_lag")) << j.dump(2);
    const nlohmann::json& lag = j["timing_lag"];
    ASSERT_TRUE(lag["ok"].get<bool>()) << lag.dump(2);
    const double value = lag["value"].get<double>();
    const double std_s = lag["std"].get<double>();
    std::printf("rig %s: timing lag %.4f +- %.4f ms (truth %.4f ms), threshold %.4f ms\n",
                ns.c_str(), 1e3 * value, 1e3 * std_s, 1e3 * true_lag_s[i],
                1e3 * lag["detection_threshold"].get<double>());
    EXPECT_GT(std_s, 0.0);
    // The run is not bit-reproducible (the simulated clock's steps follow wall time, which moves
    // the commands against the seeded noise), so the bound must hold for any draw: 4 sigma
    // fails once in 16000 runs; a bias of the motion model would show at once (the lag is
    // 22 sigma; a stand gimbal off the estimator's profile gave no estimate at all).
    EXPECT_LE(std::abs(value - true_lag_s[i]), 4.0 * std_s) << lag.dump(2);
    bool named = false;
    for (const auto& e : j["effects"]) named = named || e["name"] == "timing_lag";
    if (true_lag_s[i] > 0.0) {
      // Several times the detection threshold: it must be named, as an effect of the run.
      EXPECT_GT(true_lag_s[i], 3.0 * lag["detection_threshold"].get<double>()) << lag.dump(2);
      EXPECT_TRUE(lag["detected"].get<bool>()) << lag.dump(2);
      EXPECT_TRUE(named) << j["effects"].dump(2);
    }
    // Without a lag the test at alpha = 5 % may still fire in 5 % of runs (that false-alarm rate
    // is checked by Monte Carlo in raw_stream_analysis_test); the 4 sigma bound above is what
    // this run must meet.
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "timing_lag_on_stand");
  return RUN_ALL_TESTS();
}
