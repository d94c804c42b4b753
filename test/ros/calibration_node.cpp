// The calibration node alone (test/ros/calibration_node.test). The test owns /clock.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <diagnostic_msgs/DiagnosticStatus.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/Imu.h>
#include <std_srvs/Trigger.h>
#include <sys/wait.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "accel_intrinsics/GetIntrinsics.h"
#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "run_dirs.h"
#include "wait_for.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

namespace {

struct Expected {
  int phase;
  int step;
  double t_start, t_end;
  int n;
  Eigen::Vector3d mean, std;
};

class CalibrationNodeTest : public ::testing::Test {
 protected:
  // The status subscription goes first: its callbacks (on the spinner thread) write status_,
  // which the members' destruction would otherwise free under them (ThreadSanitizer).
  ~CalibrationNodeTest() override { status_sub_.shutdown(); }

  void SetUp() override {
    ros::NodeHandle pnh("~");
    ASSERT_TRUE(pnh.getParam("output_dir", output_dir_));
    ASSERT_TRUE(pnh.getParam("local_gravity", g_));
    ASSERT_TRUE(pnh.getParam("steps", steps_));
    ASSERT_TRUE(pnh.getParam("fit_tolerance", tolerance_));
    std::vector<double> S, O;
    ASSERT_TRUE(pnh.getParam("truth_S", S));
    ASSERT_TRUE(pnh.getParam("truth_O", O));
    ASSERT_EQ(S.size(), 9u);
    ASSERT_EQ(O.size(), 3u);
    for (int i = 0; i < 9; ++i) S_(i / 3, i % 3) = S[i];
    O_ = Eigen::Vector3d(O[0], O[1], O[2]);
    clock_pub_ = nh_.advertise<rosgraph_msgs::Clock>("/clock", 1, true);
    command_pub_ = nh_.advertise<ai::GimbalCommand>("gimbal/command", 1000);
    imu_pub_ = nh_.advertise<sensor_msgs::Imu>("imu/data_raw", 1000);
    status_sub_ = nh_.subscribe("calibration/status", 10, &CalibrationNodeTest::on_status, this);
    set_clock(50.0);
    get_ = nh_.serviceClient<ai::GetIntrinsics>("calibration/get_intrinsics");
    reset_ = nh_.serviceClient<std_srvs::Trigger>("calibration/reset");
    ASSERT_TRUE(get_.waitForExistence(ros::Duration(30.0)));
    ASSERT_TRUE(reset_.waitForExistence(ros::Duration(30.0)));
    const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(20.0);
    while ((command_pub_.getNumSubscribers() == 0 || imu_pub_.getNumSubscribers() == 0) &&
           ros::WallTime::now() < deadline) {
      ros::WallDuration(0.05).sleep();
    }
    ASSERT_GT(command_pub_.getNumSubscribers(), 0u);
    ASSERT_GT(imu_pub_.getNumSubscribers(), 0u);
  }

  void set_clock(double t) {
    rosgraph_msgs::Clock c;
    c.clock.fromSec(t);
    clock_pub_.publish(c);
  }

  void on_status(const diagnostic_msgs::DiagnosticStatus::ConstPtr& msg) {
    std::map<std::string, std::string> values;
    for (const auto& kv : msg->values) values[kv.key] = kv.value;
    values["(message)"] = msg->message;
    values["(level)"] = std::to_string(static_cast<int>(msg->level));
    std::lock_guard<std::mutex> lock(status_mutex_);
    status_ = values;
  }
  // A copy of the latest status (written by the spinner thread; ThreadSanitizer found the test
  // body reading the map unlocked while a callback replaced it).
  std::map<std::string, std::string> status() {
    std::lock_guard<std::mutex> lock(status_mutex_);
    return status_;
  }

  void command(double t, int phase, int step, std::uint8_t state) {
    ai::GimbalCommand c;
    c.header.stamp.fromSec(t);
    c.phase = static_cast<std::uint8_t>(phase);
    c.step = static_cast<std::uint32_t>(step);
    c.steps = static_cast<std::uint32_t>(steps_);
    c.angle = core::step_angle(step, steps_);
    c.state = state;
    command_pub_.publish(c);
  }

  void sample(double t, const Eigen::Vector3d& outputs) {
    sensor_msgs::Imu m;
    m.header.stamp.fromSec(t);
    m.header.frame_id = "dut";
    m.orientation_covariance[0] = -1;
    m.angular_velocity_covariance[0] = -1;
    m.linear_acceleration.x = outputs.x();
    m.linear_acceleration.y = outputs.y();
    m.linear_acceleration.z = outputs.z();
    imu_pub_.publish(m);
    ++samples_sent_;
  }

  // The node's count of IMU messages received, from its diagnostics (the "imu" status).
  void on_diagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg) {
    for (const auto& st : msg->status) {
      if (st.name.size() < 5 || st.name.compare(st.name.size() - 5, 5, ": imu") != 0) continue;
      for (const auto& kv : st.values) {
        if (kv.key != "received") continue;
        std::lock_guard<std::mutex> lock(status_mutex_);
        imu_received_ = std::stoll(kv.value);
      }
    }
  }
  long long imu_received() {
    std::lock_guard<std::mutex> lock(status_mutex_);
    return imu_received_;
  }

  Eigen::Vector3d truth_outputs(int phase, int step) const {
    const Eigen::Vector3d f = g_ * core::in_plane_direction(static_cast<core::Phase>(phase),
                                                            core::step_angle(step, steps_));
    return S_ * f + O_;
  }

  ai::GetIntrinsics::Response call_get() {
    ai::GetIntrinsics srv;
    EXPECT_TRUE(get_.call(srv));
    return srv.response;
  }

  ros::NodeHandle nh_;
  ros::Publisher clock_pub_, command_pub_, imu_pub_;
  ros::Subscriber status_sub_;
  ros::ServiceClient get_, reset_;
  std::mutex status_mutex_;
  std::map<std::string, std::string> status_;
  long long imu_received_ = -1;  // from the node's diagnostics; -1: none yet
  long long samples_sent_ = 0;
  std::string output_dir_;
  double g_ = 9.80665, tolerance_ = 1e-9;
  int steps_ = 3;
  Eigen::Matrix3d S_;
  Eigen::Vector3d O_;
};

// Splits a CSV line.
std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream s(line);
  std::string field;
  while (std::getline(s, field, ',')) out.push_back(field);
  return out;
}

}  // namespace

TEST_F(CalibrationNodeTest, AssignsDwellsByStampFitsAndResets) {
  const Eigen::Vector3d delta(0.01, 0.02, 0.03);
  const int dwell_samples = 10;
  std::vector<Expected> expected;
  int moving_samples = 0, before_samples = 0, after_samples = 0;

  // Samples before the first command: outside every dwell.
  for (int k = 0; k < 5; ++k, ++before_samples) sample(99.5 + 0.1 * k, truth_outputs(0, 0));
  double t = 100.0;
  for (int p = 0; p < 3; ++p) {
    // Phase z ends with the closing position: step == steps, at 2 pi.
    const int positions = p == 2 ? steps_ + 1 : steps_;
    for (int n = 0; n < positions; ++n) {
      command(t, p, n, ai::GimbalCommand::MOVING);
      // One sample exactly at the MOVING stamp and nine while moving: all dropped.
      for (int k = 0; k < 10; ++k, ++moving_samples) sample(t + 0.1 * k, Eigen::Vector3d(1, 2, 3));
      command(t + 1.0, p, n, ai::GimbalCommand::SETTLED);
      const Eigen::Vector3d mean = truth_outputs(p, n);
      // Ten samples from the SETTLED stamp on (inclusive), alternating +-delta: the dwell mean
      // is exact and the sample std is delta * sqrt(10 / 9).
      for (int k = 0; k < dwell_samples; ++k) {
        sample(t + 1.0 + 0.1 * k, mean + (k % 2 == 0 ? delta : Eigen::Vector3d(-delta)));
        if (p == 1 && n == 1 && k == 4) {
          Eigen::Vector3d nan_out = mean;  // a NaN sample inside a dwell
          nan_out.y() = std::nan("");
          sample(t + 1.45, nan_out);
        }
      }
      if (p == 2 && n == 0) sample(t + 1.5, Eigen::Vector3d(9, 9, 9));  // stamp went backwards
      expected.push_back(
          {p, n, t + 1.0, t + 2.0, dwell_samples, mean, delta * std::sqrt(10.0 / 9.0)});
      t += 2.0;
    }
  }
  command(t, 2, steps_, ai::GimbalCommand::DONE);
  for (int k = 0; k < 3; ++k, ++after_samples) sample(t + 0.1 * k, Eigen::Vector3d(7, 7, 7));
  // Out of protocol: a SETTLED after DONE; malformed: phase 7.
  command(t + 0.5, 0, 1, ai::GimbalCommand::SETTLED);
  {
    ai::GimbalCommand bad;
    bad.header.stamp.fromSec(t + 0.6);
    bad.phase = 7;
    bad.steps = 3;
    command_pub_.publish(bad);
    bad.header.stamp.fromSec(t + 0.7);  // malformed: beyond the closing position
    bad.phase = 0;
    bad.step = 4;
    bad.angle = core::step_angle(4, 3);
    bad.state = ai::GimbalCommand::SETTLED;
    command_pub_.publish(bad);
  }
  const double done_stamp = t;
  // Wait until everything has arrived: the two malformed commands, last on their topic, are
  // counted on arrival (calibration/status), and the IMU messages by the node's diagnostics.
  // Both are published on the node's timer: the clock moves on in small steps from 50 s, far
  // below every stamp sent, so nothing is released (the first sample, 99.5 s, waits until the
  // clock passes 159.5 s).
  {
    ros::Subscriber diagnostics = nh_.subscribe<diagnostic_msgs::DiagnosticArray>(
        "/diagnostics", 100,
        [this](const diagnostic_msgs::DiagnosticArray::ConstPtr& msg) { on_diagnostics(msg); });
    double clock = 50.0;
    EXPECT_TRUE(test_wait::wait_for(
        [&] {
          if (clock < 95.0) set_clock(clock += 0.1);
          return status()["commands_rejected"] == "2" && imu_received() == samples_sent_;
        },
        30.0,
        "every message sent to reach the node (commands_rejected 2, IMU messages received " +
            std::to_string(samples_sent_) + ")"))
        << "commands_rejected " << status()["commands_rejected"] << ", IMU received "
        << imu_received();
  }

  // Nothing is released yet: the service names what is missing.
  {
    const ai::GetIntrinsics::Response r = call_get();
    EXPECT_FALSE(r.success);
    EXPECT_NE(r.message.find("phase x"), std::string::npos) << r.message;
    EXPECT_NE(r.message.find("0 of 3"), std::string::npos) << r.message;
  }

  // Past DONE + reorder window: the node flushes and fits.
  set_clock(done_stamp + 60.0 + 1.0);
  ai::GetIntrinsics::Response result;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(20.0);
  while (ros::WallTime::now() < deadline) {
    result = call_get();
    if (result.success) break;
    ros::WallDuration(0.1).sleep();
  }
  ASSERT_TRUE(result.success) << result.message;
  const ai::IntrinsicResult& r = result.result;
  EXPECT_EQ(r.model, "joint");
  EXPECT_DOUBLE_EQ(r.local_gravity, g_);
  EXPECT_EQ(r.positions[0], 3u);
  EXPECT_EQ(r.positions[1], 3u);
  EXPECT_EQ(r.positions[2], 4u);  // with the closing position
  const double vec[3][3] = {{r.u.x, r.u.y, r.u.z}, {r.v.x, r.v.y, r.v.z}, {r.w.x, r.w.y, r.w.z}};
  for (int s = 0; s < 3; ++s) {
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(vec[s][c], S_(s, c), tolerance_) << "S(" << s << "," << c << ")";
    EXPECT_NEAR(r.offset[s], O_(s), tolerance_) << "O " << s;
    EXPECT_NEAR(r.responsivity[s], S_.row(s).norm(), tolerance_);
  }

  // The position table checkpoint: one row per dwell, exact assignment.
  std::ifstream csv(run_dirs::latest(output_dir_) + "/position_table.csv");
  ASSERT_TRUE(csv.good()) << output_dir_;
  std::string line;
  ASSERT_TRUE(std::getline(csv, line));
  EXPECT_EQ(line, "phase,step,angle_rad,t_start,t_end,n,mean_u,mean_v,mean_w,std_u,std_v,std_w");
  std::size_t row = 0;
  while (std::getline(csv, line)) {
    if (line.empty()) continue;
    ASSERT_LT(row, expected.size());
    const Expected& e = expected[row];
    const std::vector<std::string> f = split(line);
    ASSERT_EQ(f.size(), 12u) << line;
    EXPECT_EQ(f[0], std::string(1, "xyz"[e.phase])) << line;
    EXPECT_EQ(std::stoi(f[1]), e.step) << line;
    EXPECT_NEAR(std::stod(f[2]), core::step_angle(e.step, steps_), 1e-12) << line;  // 2 pi: closing
    EXPECT_NEAR(std::stod(f[3]), e.t_start, 1e-6) << line;
    EXPECT_NEAR(std::stod(f[4]), e.t_end, 1e-6) << line;
    EXPECT_EQ(std::stoi(f[5]), e.n) << "exact dwell assignment: " << line;
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(std::stod(f[6 + k]), e.mean(k), 1e-12) << line;
      EXPECT_NEAR(std::stod(f[9 + k]), e.std(k), 1e-12) << line;
    }
    ++row;
  }
  EXPECT_EQ(row, expected.size());
  std::ifstream yaml(run_dirs::latest(output_dir_) + "/intrinsics.yaml");
  EXPECT_TRUE(yaml.good());
  // The exports of the `exports` parameter: imu_calib's SM is P = S^-1 of the result.
  const YAML::Node calib = YAML::LoadFile(run_dirs::latest(output_dir_) + "/imu_calib.yaml");
  ASSERT_EQ(calib["SM"].size(), 9u);
  for (int i = 0; i < 9; ++i) {
    EXPECT_NEAR(calib["SM"][i].as<double>(), r.cross_sensitivity[i], 1e-12) << i;
  }
  std::ifstream px4(run_dirs::latest(output_dir_) + "/px4.params");
  std::stringstream px4_text;
  px4_text << px4.rdbuf();
  EXPECT_NE(px4_text.str().find("CAL_ACC0_XSCALE"), std::string::npos);
  EXPECT_NE(px4_text.str().find("largest error left over all orientations"), std::string::npos);

  // Counters on calibration/status (latched, republished with the result).
  const ros::WallTime status_deadline = ros::WallTime::now() + ros::WallDuration(10.0);
  std::map<std::string, std::string> st = status();
  while (st["state"] != "RESULT" && ros::WallTime::now() < status_deadline) {
    ros::WallDuration(0.05).sleep();
    st = status();
  }
  ASSERT_EQ(st["state"], "RESULT");
  EXPECT_EQ(std::stoi(st["samples_used"]), 10 * dwell_samples);
  EXPECT_EQ(std::stoi(st["dropped_outside_dwell"]),
            before_samples + moving_samples + after_samples);
  EXPECT_EQ(std::stoi(st["dropped_non_finite"]), 1);
  EXPECT_EQ(std::stoi(st["dropped_backwards"]), 1);
  EXPECT_EQ(std::stoi(st["dropped_late"]), 0);
  EXPECT_EQ(std::stoi(st["commands_out_of_order"]), 1);
  EXPECT_EQ(std::stoi(st["commands_rejected"]), 2);
  EXPECT_EQ(std::stoi(st["dwells_x"]), 3);
  EXPECT_EQ(std::stoi(st["dwells_y"]), 3);
  EXPECT_EQ(std::stoi(st["dwells_z"]), 4);

  // Reset: the result is gone and the service says what is missing again.
  std_srvs::Trigger reset;
  ASSERT_TRUE(reset_.call(reset));
  EXPECT_TRUE(reset.response.success);
  const ai::GetIntrinsics::Response after = call_get();
  EXPECT_FALSE(after.success);
  EXPECT_NE(after.message.find("phase x"), std::string::npos) << after.message;
}

// A run whose fit fails the quality gate (|w| = 0.3 of the true device: outside the plausible
// [0.5, 2] for outputs in m/s^2): the result is published and written for inspection, but the
// service answers success false naming the gate, no export is written, and the status says so.
TEST_F(CalibrationNodeTest, AResultFailingTheQualityGateIsNoCalibration) {
  std_srvs::Trigger reset;
  ASSERT_TRUE(reset_.call(reset));
  // The run after the reset writes into a directory of its own: no file of an earlier run there.
  S_.row(2) *= 0.3;
  const Eigen::Vector3d delta(0.01, 0.02, 0.03);
  double t = 1000.0;
  set_clock(t - 10.0);
  for (int p = 0; p < 3; ++p) {
    const int positions = p == 2 ? steps_ + 1 : steps_;
    for (int n = 0; n < positions; ++n) {
      command(t, p, n, ai::GimbalCommand::MOVING);
      command(t + 1.0, p, n, ai::GimbalCommand::SETTLED);
      const Eigen::Vector3d mean = truth_outputs(p, n);
      for (int k = 0; k < 10; ++k)
        sample(t + 1.0 + 0.1 * k, mean + (k % 2 == 0 ? delta : Eigen::Vector3d(-delta)));
      t += 2.0;
    }
  }
  command(t, 2, steps_, ai::GimbalCommand::DONE);
  // The commands arrive in order on their topic: once the node says DONE was received, every
  // command of the run is in (the samples went out before them). Waited for, not slept.
  {
    const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(60.0);
    std::string message;
    while (ros::WallTime::now() < deadline) {
      message = call_get().message;
      if (message.find("DONE received") != std::string::npos) break;
      ros::WallDuration(0.05).sleep();
    }
    ASSERT_NE(message.find("DONE received"), std::string::npos) << message;
  }
  // Past DONE + reorder window: the node flushes and fits. Wait for the fit's answer (the
  // service names what is missing until then), with a generous bound.
  set_clock(t + 60.0 + 1.0);
  ai::GetIntrinsics::Response r;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(60.0);
  while (ros::WallTime::now() < deadline) {
    r = call_get();
    if (r.message.find("quality gate") != std::string::npos) break;
    ros::WallDuration(0.05).sleep();
  }
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message.find("the result fails the quality gate"), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("responsivity |w|"), std::string::npos) << r.message;
  EXPECT_FALSE(r.result.quality_pass);
  EXPECT_NEAR(r.result.responsivity[2], S_.row(2).norm(), 1e-6);
  // The result file is there, marked failing; the exports are not.
  const YAML::Node written = YAML::LoadFile(run_dirs::latest(output_dir_) + "/intrinsics.yaml");
  EXPECT_FALSE(written["quality"]["pass"].as<bool>());
  for (const char* name : {"imu_calib.yaml", "px4.params"}) {
    std::ifstream f(run_dirs::latest(output_dir_) + "/" + name);
    EXPECT_FALSE(f.good()) << name << " written for a result that fails the gate";
  }
  // The status: the run is over, and its result is no calibration.
  const ros::WallTime status_deadline = ros::WallTime::now() + ros::WallDuration(30.0);
  std::map<std::string, std::string> st = status();
  while ((st["state"] != "RESULT" || st["(message)"].find("quality gate") == std::string::npos) &&
         ros::WallTime::now() < status_deadline) {
    ros::WallDuration(0.05).sleep();
    st = status();
  }
  EXPECT_EQ(st["state"], "RESULT");
  EXPECT_NE(st["(message)"].find("result fails the quality gate"), std::string::npos)
      << st["(message)"];
  EXPECT_EQ(st["(level)"],
            std::to_string(static_cast<int>(diagnostic_msgs::DiagnosticStatus::ERROR)));
  ASSERT_TRUE(reset_.call(reset));
}

TEST(NodeParams, RefuseToStartNamingTheParameter) {
  // Each node with one bad private parameter: exit status 2 and the parameter's full name.
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"calibration __name:=bad_calibration _local_gravity:=3.0", "/bad_calibration/local_gravity"},
      {"calibration __name:=bad_model _model:=quadratic", "/bad_model/model"},
      {"calibration __name:=bad_exports _output_dir:=/tmp _exports:=[matlab]",
       "/bad_exports/exports"},
      {"gimbal_controller __name:=bad_gimbal _steps:=2", "/bad_gimbal/steps"},
      {"gimbal_controller __name:=bad_dwell _dwell_s:=-1.0", "/bad_dwell/dwell_s"},
      {"accelerometer __name:=bad_rate _rate_hz:=-5.0", "/bad_rate/rate_hz"},
      {"sim_clock __name:=bad_clock _time_scale:=0.0", "/bad_clock/time_scale"},
  };
  for (const auto& c : cases) {
    FILE* pipe = popen(("rosrun accel_intrinsics " + c.first + " 2>&1").c_str(), "r");
    ASSERT_NE(pipe, nullptr);
    std::string output;
    char buffer[512];
    while (fgets(buffer, sizeof(buffer), pipe)) output += buffer;
    const int status = pclose(pipe);
    EXPECT_TRUE(WIFEXITED(status)) << c.first;
    EXPECT_EQ(WEXITSTATUS(status), 2) << c.first << "\n" << output;
    EXPECT_NE(output.find(c.second), std::string::npos) << c.first << "\n" << output;
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "calibration_node_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
