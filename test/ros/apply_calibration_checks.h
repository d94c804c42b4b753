// The checks of apply_calibration.test (the node) and apply_calibration_nodelet.test (the
// nodelet, standalone): a replayed simulated run, and a file that cannot be read. The including
// file defines kStartAsNodelet.
#pragma once

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/ros/conversions.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

namespace {

constexpr double kStampOffset = 1000.0;  // recordings start at t = 0; ROS stamps must not

core::SimulationOptions device(std::uint64_t seed, double rate_hz) {
  core::SimulationOptions sim;
  sim.truth.S << 1.02, 0.015, -0.02, 0.018, 0.97, 0.012, -0.011, 0.021, 1.03;
  sim.truth.O << 0.12, -0.08, 0.2;
  sim.rate_hz = rate_hz;
  sim.protocol.steps_per_phase = 8;
  sim.protocol.dwell_s = 1.0;
  sim.protocol.move_s = 0.5;
  sim.protocol.phase_change_s = 1.0;
  sim.seed = seed;
  return sim;
}

// The specific force of docs/design.md section 1 at a commanded angle.
Eigen::Vector3d true_force(core::Phase phase, double angle, double g) {
  const double s = std::sin(angle), c = std::cos(angle);
  if (phase == core::Phase::X) return g * Eigen::Vector3d(0.0, s, c);
  if (phase == core::Phase::Y) return g * Eigen::Vector3d(s, 0.0, c);
  return g * Eigen::Vector3d(s, c, 0.0);
}

struct Received {
  std::mutex mutex;
  std::vector<sensor_msgs::Imu> messages;
  void on(const sensor_msgs::Imu::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex);
    messages.push_back(*m);
  }
  std::size_t size() {
    std::lock_guard<std::mutex> lock(mutex);
    return messages.size();
  }
};

// The command that starts the apply node (or nodelet) named `name` on `file`.
std::string start_command(const std::string& name, const std::string& file) {
  const std::string args =
      " __name:=" + name + " _calibration_file:=" + file + " _queue_size:=5000";
  return kStartAsNodelet
             ? "rosrun nodelet nodelet standalone accel_intrinsics/ApplyCalibrationNodelet" + args
             : "rosrun accel_intrinsics apply_calibration" + args;
}

pid_t start_node(const std::string& file) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const std::string command = "exec " + start_command("apply_under_test", file);
    ::execlp("bash", "bash", "-c", command.c_str(), (char*)nullptr);
    _exit(127);
  }
  return pid;
}

TEST(ApplyCalibration, RefusesAFileItCannotRead) {
  const std::string missing = "/tmp/accel_intrinsics_rostest/no_such_calibration.json";
  FILE* pipe = ::popen((start_command("apply_bad", missing) + " 2>&1").c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[512];
  while (std::fgets(buffer, sizeof(buffer), pipe)) output += buffer;
  const int status = ::pclose(pipe);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_NE(WEXITSTATUS(status), 0) << output;
  if (!kStartAsNodelet) {
    EXPECT_EQ(WEXITSTATUS(status), 2) << output;
  }
  EXPECT_NE(output.find("/apply_bad/calibration_file"), std::string::npos) << output;
  EXPECT_NE(output.find(missing), std::string::npos) << output;
}

TEST(ApplyCalibration, CorrectedDwellMeansEqualTheTrueForce) {
  ros::NodeHandle nh, pnh("~");
  double sigmas = 5.0, rate_hz = 200.0;
  pnh.getParam("sigmas", sigmas);
  pnh.getParam("rate_hz", rate_hz);

  // The calibration: the fit of one simulated run, saved as offline_fit would.
  const core::SimulationOptions fit_run = device(31, rate_hz);
  const core::CalibrationReport report =
      core::calibrate(core::simulate_position_table(fit_run), nullptr, core::CalibrateOptions{});
  ASSERT_TRUE(report.noise.has_value());
  const std::string dir = "/tmp/accel_intrinsics_rostest/apply_calibration";
  std::filesystem::create_directories(dir);
  const std::string file = dir + "/result.json";
  ai::io::write_result_json(file, report, ai::io::ResultContext{});

  // The run to correct: another seed of the same device.
  const core::Recording rec = core::simulate_recording(device(32, rate_hz));
  Received received;
  ros::Subscriber sub = nh.subscribe("imu/data_calibrated", 50000, &Received::on, &received);
  ros::Publisher pub = nh.advertise<sensor_msgs::Imu>("imu/data_raw", 50000);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const pid_t node = start_node(file);
  ASSERT_GT(node, 0);
  const ros::WallTime connect_deadline = ros::WallTime::now() + ros::WallDuration(30.0);
  while ((pub.getNumSubscribers() == 0 || sub.getNumPublishers() == 0) &&
         ros::WallTime::now() < connect_deadline) {
    ros::WallDuration(0.05).sleep();
  }
  ASSERT_GT(pub.getNumSubscribers(), 0u);
  ASSERT_GT(sub.getNumPublishers(), 0u);
  std::size_t sent = 0;
  for (const core::ImuSample& s : rec.samples) {
    core::ImuSample shifted = s;
    shifted.stamp_s += kStampOffset;
    pub.publish(ai::to_msg(shifted, "dut"));
    if (++sent % 50 == 0) ros::WallDuration(0.002).sleep();  // ~25 kHz: no queue overflows
    // Flow control: the node's queues hold 5000 messages; a loaded machine can starve it for
    // longer than they last at 25 kHz, so the test keeps at most 2000 in flight.
    if (sent % 1000 == 0) {
      const ros::WallTime catch_up = ros::WallTime::now() + ros::WallDuration(30.0);
      while (received.size() + 2000 < sent && ros::WallTime::now() < catch_up)
        ros::WallDuration(0.005).sleep();
    }
  }
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(30.0);
  while (received.size() < sent && ros::WallTime::now() < deadline) ros::WallDuration(0.05).sleep();
  ::kill(node, SIGINT);
  int status = 0;
  ::waitpid(node, &status, 0);
  ASSERT_EQ(received.size(), sent) << "every message corrected";

  // Dwells: SETTLED to the next MOVING or DONE.
  const Eigen::Matrix3d P = report.certificate.S.inverse();
  const double g = report.certificate.local_gravity;
  const Eigen::Vector3d sigma = report.noise->sample_std;
  const Eigen::Matrix3d stated = P * sigma.cwiseAbs2().asDiagonal() * P.transpose();
  int dwells = 0, raw_far = 0;
  for (std::size_t c = 0; c + 1 < rec.commands.size(); ++c) {
    const core::GimbalEvent& e = rec.commands[c];
    if (e.state != core::GimbalState::Settled) continue;
    const double t0 = e.stamp_s + kStampOffset, t1 = rec.commands[c + 1].stamp_s + kStampOffset;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero(), raw_sum = Eigen::Vector3d::Zero();
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    std::vector<Eigen::Vector3d> values;
    std::size_t k = 0;
    for (const sensor_msgs::Imu& m : received.messages) {
      const double t = m.header.stamp.toSec();
      if (t < t0 || t >= t1) continue;
      const Eigen::Vector3d a(m.linear_acceleration.x, m.linear_acceleration.y,
                              m.linear_acceleration.z);
      values.push_back(a);
      sum += a;
      for (int i = 0; i < 9; ++i) {
        EXPECT_NEAR(m.linear_acceleration_covariance[i], stated(i / 3, i % 3), 1e-15)
            << "covariance filled";
      }
      ++k;
    }
    for (const core::ImuSample& s : rec.samples) {
      if (s.stamp_s + kStampOffset >= t0 && s.stamp_s + kStampOffset < t1) raw_sum += s.outputs;
    }
    ASSERT_GT(k, 10u);
    const Eigen::Vector3d mean = sum / k;
    for (const Eigen::Vector3d& v : values) scatter += (v - mean) * (v - mean).transpose();
    scatter /= static_cast<double>(k - 1);
    const Eigen::Vector3d truth = true_force(e.phase, e.angle_rad, g);
    // Uncertainty: the mean's noise, and the fit's (S, O) through d(a) = -P (dS a + dO).
    Eigen::Matrix<double, 3, 12> J = Eigen::Matrix<double, 3, 12>::Zero();
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) J.col(3 * i + j) = -P.col(i) * mean(j);
      J.col(9 + i) = -P.col(i);
    }
    const Eigen::Matrix3d cov = J * report.certificate.covariance * J.transpose() + stated / k;
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(mean(i), truth(i), sigmas * std::sqrt(cov(i, i)))
          << "phase " << core::phase_name(e.phase) << " step " << e.step << " component " << i;
      // The stated covariance describes the published scatter.
      EXPECT_NEAR(std::sqrt(scatter(i, i)), std::sqrt(stated(i, i)),
                  0.25 * std::sqrt(stated(i, i)));
    }
    // Without the correction this dwell would be far off (the test can fail).
    if (((raw_sum / k) - truth).norm() > 20.0 * std::sqrt(cov.trace())) ++raw_far;
    ++dwells;
  }
  EXPECT_EQ(dwells, 24);
  EXPECT_GT(raw_far, 12);
}

}  // namespace
