// A newcomer's ros_control gimbal without hardware: see test/ros/ros_joint_emulator_stand.test.
#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <vector>

#include "stand_checks.h"

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// What the test hears of the emulator: JointState stamps and positions, and the commands.
struct Heard {
  std::mutex mutex;
  std::vector<double> stamps_s;
  std::map<std::string, std::vector<std::pair<double, double>>> positions_deg;  // (t, deg)
  double max_speed_deg_s = 0.0;
  std::map<std::string, std::vector<double>> commands_deg;  // per joint
};

}  // namespace

TEST(RosJointEmulatorStand, NewcomersRunPassesTheGate) {
  ros::NodeHandle nh, pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  double timeout_s = 240.0, max_speed_deg_s = 90.0, rate_hz = 50.0;
  int steps = 6;
  std::string output_dir;
  pnh.getParam("timeout_s", timeout_s);
  pnh.getParam("steps", steps);
  pnh.getParam("max_speed_deg_s", max_speed_deg_s);
  pnh.getParam("rate_hz", rate_hz);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));

  // The joints and their command topics, as the gimbal controller reads them (shipped config).
  std::map<std::string, std::string> joint_of_topic;
  for (const char* axis : {"X", "Y"}) {
    std::string joint, topic;
    const std::string key = std::string("/gimbal_controller/ros_joint/axes/") + axis;
    ASSERT_TRUE(ros::param::get(key + "/joint", joint)) << key;
    ASSERT_TRUE(ros::param::get(key + "/command_topic", topic)) << key;
    joint_of_topic[topic] = joint;
  }
  Heard heard;
  std::vector<ros::Subscriber> subs;
  subs.push_back(nh.subscribe<sensor_msgs::JointState>(
      "/joint_states", 1000, [&heard](const sensor_msgs::JointState::ConstPtr& msg) {
        std::lock_guard<std::mutex> lock(heard.mutex);
        heard.stamps_s.push_back(msg->header.stamp.toSec());
        for (std::size_t i = 0; i < msg->name.size() && i < msg->position.size(); ++i)
          heard.positions_deg[msg->name[i]].push_back(
              {msg->header.stamp.toSec(), msg->position[i] * kRadToDeg});
        for (std::size_t i = 0; i < msg->velocity.size(); ++i)
          heard.max_speed_deg_s =
              std::max(heard.max_speed_deg_s, std::abs(msg->velocity[i]) * kRadToDeg);
      }));
  for (const auto& t : joint_of_topic) {
    const std::string joint = t.second;
    subs.push_back(nh.subscribe<std_msgs::Float64>(
        "/" + t.first, 100, [&heard, joint](const std_msgs::Float64::ConstPtr& msg) {
          std::lock_guard<std::mutex> lock(heard.mutex);
          heard.commands_deg[joint].push_back(msg->data * kRadToDeg);
        }));
  }
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(90.0)));
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/start", ros::Duration(90.0)));

  // supervise exits 0 only at DONE with the quality gate passing.
  stand_checks::supervise_and_check({""}, limits, timeout_s, output_dir + "/supervise.json");
  const accel_intrinsics::GetIntrinsics::Response res = stand_checks::get_intrinsics("");
  ASSERT_TRUE(res.success) << res.message;
  EXPECT_TRUE(res.result.quality_pass);
  for (const std::string& reason : res.result.quality_reasons) ADD_FAILURE() << reason;
  stand_checks::Truth truth;
  ASSERT_TRUE(stand_checks::load_truth("", &truth));
  stand_checks::expect_matches_truth(res.result, truth, limits, "ros_joint emulator stand");
  for (int p = 0; p < 3; ++p) EXPECT_EQ(res.result.positions[p], static_cast<unsigned>(steps));

  std::lock_guard<std::mutex> lock(heard.mutex);
  // JointState at rate_hz of the stand's clock. The typical spacing is the period; the mean rate
  // may fall short of it, because a ros::Timer on a busy machine skips ticks it missed rather than
  // firing them late (CI once heard 39.7 Hz of 50: a loaded machine, not a wrong period).
  ASSERT_GT(heard.stamps_s.size(), 100u);
  std::vector<double> spacing_s;
  for (std::size_t i = 1; i < heard.stamps_s.size(); ++i)
    spacing_s.push_back(heard.stamps_s[i] - heard.stamps_s[i - 1]);
  std::nth_element(spacing_s.begin(), spacing_s.begin() + spacing_s.size() / 2, spacing_s.end());
  const double median_spacing_s = spacing_s[spacing_s.size() / 2];
  EXPECT_NEAR(median_spacing_s, 1.0 / rate_hz, 0.1 / rate_hz);
  const double span_s = heard.stamps_s.back() - heard.stamps_s.front();
  const double measured_hz = (heard.stamps_s.size() - 1) / span_s;
  EXPECT_GT(measured_hz, 0.5 * rate_hz) << "more than half the ticks skipped";
  EXPECT_LT(measured_hz, 1.1 * rate_hz);
  EXPECT_LE(heard.max_speed_deg_s, max_speed_deg_s * (1.0 + 1e-9));
  EXPECT_GT(heard.max_speed_deg_s, 0.5 * max_speed_deg_s) << "the large moves run at the limit";
  // Every joint that moved overshot at least one of its commands: the servo's ring, which the
  // driver must wait out (tolerance_deg, settle_s).
  for (const auto& c : heard.commands_deg) {
    const auto& track = heard.positions_deg[c.first];
    ASSERT_FALSE(track.empty()) << c.first;
    double lowest = track.front().second, highest = lowest;
    for (const auto& p : track) {
      lowest = std::min(lowest, p.second);
      highest = std::max(highest, p.second);
    }
    const double max_command = *std::max_element(c.second.begin(), c.second.end());
    if (max_command - lowest < 1.0) continue;  // this joint never moved up
    EXPECT_GT(highest, max_command + 0.05) << c.first << ": no overshoot past " << max_command;
    EXPECT_LT(highest, max_command + 10.0) << c.first << ": overshoot is not small";
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "ros_joint_emulator_stand_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
