// A ros_control gimbal: see test/ros/ros_joint_stand.test. Everything the gimbal controller
// talks to is written here from the equations: the joints (a damped second-order motion toward
// each std_msgs/Float64 command, with overshoot; sensor_msgs/JointState at 50 Hz) and the IMU
// (this test's own Rx(X) Rz(Y) of the joints' positions and its own device S, O, noise;
// sensor_msgs/Imu at 100 Hz). Not the package's simulator.
#include <diagnostic_msgs/DiagnosticStatus.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64.h>
#include <std_srvs/Trigger.h>

#include <atomic>
#include <cmath>
#include <mutex>
#include <random>
#include <string>
#include <thread>

#include "accel_intrinsics/GetIntrinsics.h"
#include "accel_intrinsics/IntrinsicResult.h"
#include "wait_for.h"

namespace {

constexpr double kG = 9.80665;

// The test's device: rows u, v, w and offsets (m/s^2), white noise per sample.
const double kS[3][3] = {{1.021, 0.012, -0.006}, {-0.009, 0.984, 0.014}, {0.005, -0.007, 1.012}};
const double kO[3] = {0.05, -0.03, 0.08};
constexpr double kNoise = 0.01;

struct Joint {
  std::string name;
  double x = 0.0, v = 0.0, command = 0.0;
};

class Rig {
 public:
  Rig() {
    ros::NodeHandle nh;
    std::string outer_topic, inner_topic;
    EXPECT_TRUE(ros::param::get("/gimbal_controller/ros_joint/axes/X/joint", joints_[0].name));
    EXPECT_TRUE(ros::param::get("/gimbal_controller/ros_joint/axes/Y/joint", joints_[1].name));
    EXPECT_TRUE(ros::param::get("/gimbal_controller/ros_joint/axes/X/command_topic", outer_topic));
    EXPECT_TRUE(ros::param::get("/gimbal_controller/ros_joint/axes/Y/command_topic", inner_topic));
    command_subs_[0] = nh.subscribe<std_msgs::Float64>(
        outer_topic, 10, [this](const std_msgs::Float64::ConstPtr& m) { on_command(0, m->data); });
    command_subs_[1] = nh.subscribe<std_msgs::Float64>(
        inner_topic, 10, [this](const std_msgs::Float64::ConstPtr& m) { on_command(1, m->data); });
    joint_pub_ = nh.advertise<sensor_msgs::JointState>("joint_states", 10);
    imu_pub_ = nh.advertise<sensor_msgs::Imu>("imu/data_raw", 100);
    thread_ = std::thread([this] { loop(); });
  }
  ~Rig() {
    running_ = false;
    thread_.join();
  }
  std::atomic<bool> inner_silent{false};

 private:
  void on_command(int i, double rad) {
    std::lock_guard<std::mutex> lock(mutex_);
    joints_[i].command = rad;
  }
  // x'' = wn^2 (command - x) - 2 zeta wn x', zeta 0.5 (16 % overshoot), 1 ms steps.
  void loop() {
    std::mt19937 rng(20261127);
    std::normal_distribution<double> noise(0.0, kNoise);
    const double wn = 20.0, zeta = 0.5;
    ros::WallTime next = ros::WallTime::now();
    for (long k = 0; running_; ++k) {
      next += ros::WallDuration(0.001);
      ros::WallTime::sleepUntil(next);
      std::lock_guard<std::mutex> lock(mutex_);
      for (Joint& j : joints_) {
        const double a = wn * wn * (j.command - j.x) - 2.0 * zeta * wn * j.v;
        j.v += a * 0.001;
        j.x += j.v * 0.001;
      }
      const ros::Time now = ros::Time::now();
      if (k % 20 == 0) {
        sensor_msgs::JointState js;
        js.header.stamp = now;
        for (int i = 0; i < 2; ++i) {
          if (i == 1 && inner_silent) continue;
          js.name.push_back(joints_[i].name);
          js.position.push_back(joints_[i].x);
          js.velocity.push_back(joints_[i].v);
        }
        joint_pub_.publish(js);
      }
      if (k % 10 == 0) {
        // f = (Rx(X) Rz(Y))^T (0, 0, g): the third row of Rx(X) Rz(Y), times g.
        const double X = joints_[0].x, Y = joints_[1].x;
        const double f[3] = {kG * std::sin(X) * std::sin(Y), kG * std::sin(X) * std::cos(Y),
                             kG * std::cos(X)};
        double r[3];
        for (int s = 0; s < 3; ++s) {
          r[s] = kO[s] + noise(rng);
          for (int c = 0; c < 3; ++c) r[s] += kS[s][c] * f[c];
        }
        sensor_msgs::Imu imu;
        imu.header.stamp = now;
        imu.header.frame_id = "dut";
        imu.linear_acceleration.x = r[0];
        imu.linear_acceleration.y = r[1];
        imu.linear_acceleration.z = r[2];
        imu.orientation_covariance[0] = -1.0;
        imu.angular_velocity_covariance[0] = -1.0;
        imu_pub_.publish(imu);
      }
    }
  }

  std::mutex mutex_;
  Joint joints_[2];
  ros::Subscriber command_subs_[2];
  ros::Publisher joint_pub_, imu_pub_;
  std::atomic<bool> running_{true};
  std::thread thread_;
};

double norm_row(int s) {
  return std::sqrt(kS[s][0] * kS[s][0] + kS[s][1] * kS[s][1] + kS[s][2] * kS[s][2]);
}

}  // namespace

TEST(RosJointStand, FullRunMatchesTheTestsTruthThenASilentJointIsNamed) {
  ros::NodeHandle nh, pnh("~");
  double max_sigma = 4.0, timeout_s = 60.0;
  pnh.getParam("max_sigma", max_sigma);
  pnh.getParam("timeout_s", timeout_s);
  Rig rig;
  test_wait::LatestValues progress;
  ros::Subscriber progress_sub = nh.subscribe("gimbal_controller/progress", 10,
                                              &test_wait::LatestValues::on_message, &progress);
  accel_intrinsics::IntrinsicResult result;
  std::atomic<bool> have_result{false};
  ros::Subscriber result_sub = nh.subscribe<accel_intrinsics::IntrinsicResult>(
      "calibration/result", 1, [&](const accel_intrinsics::IntrinsicResult::ConstPtr& m) {
        result = *m;
        have_result = true;
      });
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/start", ros::Duration(30.0)));
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(30.0)));
  ros::WallDuration(1.0).sleep();  // subscriptions connected, joints reported
  std_srvs::Trigger start;
  ASSERT_TRUE(ros::service::call("/gimbal_controller/start", start));
  ASSERT_TRUE(start.response.success) << start.response.message;
  ASSERT_TRUE(test_wait::wait_for([&] { return progress("state") == "DONE"; }, timeout_s,
                                  "the controller's DONE"))
      << progress.message();
  ASSERT_TRUE(
      test_wait::wait_for([&] { return have_result.load(); }, 20.0, "the calibration result"));
  for (int p = 0; p < 3; ++p) EXPECT_EQ(result.positions[p], 6u);

  // The truth from the test's S: |u|, |v|, |w| and the angles uv, vw, wu.
  const int pairs[3][2] = {{0, 1}, {1, 2}, {2, 0}};
  for (int s = 0; s < 3; ++s) {
    EXPECT_LE(std::abs(result.responsivity[s] - norm_row(s)),
              max_sigma * result.responsivity_std[s])
        << "|"
        << "uvw"[s] << "| " << result.responsivity[s] << " +- " << result.responsivity_std[s]
        << " truth " << norm_row(s);
    EXPECT_LT(result.responsivity_std[s], 1e-3);
    const int a = pairs[s][0], b = pairs[s][1];
    const double dot = kS[a][0] * kS[b][0] + kS[a][1] * kS[b][1] + kS[a][2] * kS[b][2];
    const double truth_deg = std::acos(dot / (norm_row(a) * norm_row(b))) * 180.0 / M_PI;
    EXPECT_LE(std::abs(result.angles_deg[s] - truth_deg), max_sigma * result.angles_std_deg[s])
        << "angle " << s << ": " << result.angles_deg[s] << " +- " << result.angles_std_deg[s]
        << " truth " << truth_deg;
    EXPECT_LT(result.angles_std_deg[s], 0.1);
    EXPECT_LE(std::abs(result.offset[s] - kO[s]), max_sigma * result.offset_std[s] + 1e-9)
        << "offset " << s;
  }

  // The inner joint falls silent: the next run aborts with a fault that names it.
  std::string inner;
  ros::param::get("/gimbal_controller/ros_joint/axes/Y/joint", inner);
  rig.inner_silent = true;
  std_srvs::Trigger again;
  ASSERT_TRUE(ros::service::call("/gimbal_controller/start", again));
  ASSERT_TRUE(test_wait::wait_for([&] { return progress("state") == "ABORTED"; }, 15.0,
                                  "ABORTED for the silent joint"))
      << progress.message();
  EXPECT_NE(progress.message().find("'" + inner + "'"), std::string::npos) << progress.message();
  EXPECT_NE(progress.message().find("no JointState"), std::string::npos) << progress.message();
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "ros_joint_stand_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
