// An indexing head turned by hand: see test/ros/manual_stand.test. The operator and the IMU are
// written here: the head is this test's Rx(X) Rz(Y) at the stage angles the operator set, the
// IMU its own device (S, offsets, noise) at 100 Hz.
#include <diagnostic_msgs/DiagnosticStatus.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <std_srvs/Trigger.h>

#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <random>
#include <string>
#include <thread>

#include "accel_intrinsics/GimbalCommand.h"

namespace {

constexpr double kDeg = M_PI / 180.0;
const double kS[3][3] = {{1.021, 0.012, -0.006}, {-0.009, 0.984, 0.014}, {0.005, -0.007, 1.012}};
const double kO[3] = {0.05, -0.03, 0.08};

class Head {
 public:
  Head() {
    ros::NodeHandle nh;
    pub_ = nh.advertise<sensor_msgs::Imu>("imu/data_raw", 100);
    thread_ = std::thread([this] { loop(); });
  }
  ~Head() {
    running_ = false;
    thread_.join();
  }
  void set(double x_deg, double y_deg) {
    std::lock_guard<std::mutex> lock(mutex_);
    x_deg_ = x_deg;
    y_deg_ = y_deg;
  }

 private:
  void loop() {
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0.0, 0.01);
    while (running_) {
      ros::WallDuration(0.01).sleep();
      double X, Y;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        X = x_deg_ * kDeg;
        Y = y_deg_ * kDeg;
      }
      // f = (Rx(X) Rz(Y))^T (0, 0, g).
      const double f[3] = {9.80665 * std::sin(X) * std::sin(Y), 9.80665 * std::sin(X) * std::cos(Y),
                           9.80665 * std::cos(X)};
      double r[3];
      for (int s = 0; s < 3; ++s) {
        r[s] = kO[s] + noise(rng);
        for (int c = 0; c < 3; ++c) r[s] += kS[s][c] * f[c];
      }
      sensor_msgs::Imu imu;
      imu.header.stamp = ros::Time::now();
      imu.linear_acceleration.x = r[0];
      imu.linear_acceleration.y = r[1];
      imu.linear_acceleration.z = r[2];
      pub_.publish(imu);
    }
  }
  std::mutex mutex_;
  double x_deg_ = 0.0, y_deg_ = 0.0;
  ros::Publisher pub_;
  std::atomic<bool> running_{true};
  std::thread thread_;
};

struct Progress {
  std::mutex mutex;
  std::map<std::string, std::string> values;
  std::string message;
  void on(const diagnostic_msgs::DiagnosticStatus::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    values.clear();
    for (const auto& kv : m->values) values[kv.key] = kv.value;
    message = m->message;
  }
  std::map<std::string, std::string> get(std::string* msg) {
    std::lock_guard<std::mutex> lock(mutex);
    if (msg) *msg = message;
    return values;
  }
};

}  // namespace

TEST(ManualStand, OperatorRunWithAWrongPoseNamedThenCorrected) {
  ros::NodeHandle nh;
  Head head;
  Progress progress;
  ros::Subscriber sub = nh.subscribe("gimbal_controller/progress", 10, &Progress::on, &progress);
  std::atomic<int> settled{0};
  ros::Subscriber commands = nh.subscribe<accel_intrinsics::GimbalCommand>(
      "gimbal/command", 100, [&](const accel_intrinsics::GimbalCommand::ConstPtr& m) {
        if (m->state == accel_intrinsics::GimbalCommand::SETTLED) ++settled;
      });
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/start", ros::Duration(30.0)));
  ros::WallDuration(0.5).sleep();
  std_srvs::Trigger start;
  ASSERT_TRUE(ros::service::call("/gimbal_controller/start", start));
  ASSERT_TRUE(start.response.success) << start.response.message;

  std::string answered;  // operator_waits of the last wait answered
  bool mistake_made = false, mistake_named = false;
  int waits = 0;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(45.0);
  std::string message;
  for (;;) {
    ASSERT_LT(ros::WallTime::now(), deadline) << "no DONE; last progress: " << message;
    const std::map<std::string, std::string> p = progress.get(&message);
    const auto value = [&](const std::string& k) {
      const auto it = p.find(k);
      return it == p.end() ? std::string() : it->second;
    };
    if (value("state") == "DONE") break;
    ASSERT_NE(value("state"), "ABORTED") << message;
    if (value("state") != "WAIT_OPERATOR" || value("operator_waits") == answered) {
      ros::WallDuration(0.01).sleep();
      continue;
    }
    answered = value("operator_waits");
    ++waits;
    const double x = std::stod(value("stage_X_deg")), y = std::stod(value("stage_Y_deg"));
    EXPECT_EQ(value("request").rfind("phase " + value("phase") + ": set ", 0), 0u)
        << value("request");
    if (value("phase") == "x" && value("step") == "1" && !mistake_made) {
      EXPECT_NEAR(x, 60.0, 1e-6);
      head.set(120.0, y);  // the wrong index: 120 deg, not 60
      mistake_made = true;
    } else {
      if (mistake_made && !mistake_named) {
        // Waited on at the same position, with the pose the IMU sees named.
        EXPECT_EQ(value("phase"), "x");
        EXPECT_EQ(value("step"), "1");
        const std::string check = value("pose_check");
        const std::string seen = "the IMU sees phase x at ";
        ASSERT_EQ(check.rfind(seen, 0), 0u) << check;
        EXPECT_NEAR(std::stod(check.substr(seen.size())), 120.0, 3.0) << check;
        EXPECT_NE(check.find("not phase x at 60.0 deg"), std::string::npos) << check;
        EXPECT_NE(message.find(check), std::string::npos) << message;
        mistake_named = true;
      } else {
        EXPECT_EQ(value("pose_check"), "") << "a correct pose was refused";
      }
      head.set(x, y);
    }
    ros::WallDuration(0.05).sleep();  // the IMU at the new pose before continue
    std_srvs::Trigger cont;
    ASSERT_TRUE(ros::service::call("/gimbal_controller/continue", cont));
    EXPECT_TRUE(cont.response.success) << cont.response.message;
  }
  EXPECT_TRUE(mistake_named);
  EXPECT_EQ(waits, 19);  // 18 positions and the one repeated
  ros::WallDuration(0.2).sleep();
  EXPECT_EQ(settled.load(), 18);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "manual_stand_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
