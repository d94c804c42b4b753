// CalibrationApplier (the apply node's per-message work), without a roscore: the corrected
// acceleration is P (R - O), every other field passes through, the covariance is filled from the
// noise when known and carried through P otherwise.
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "accel_intrinsics/ros/apply_calibration_node.h"

namespace ai = accel_intrinsics;

namespace {

sensor_msgs::Imu raw_message() {
  sensor_msgs::Imu m;
  m.header.seq = 7;
  m.header.stamp = ros::Time(12.5);
  m.header.frame_id = "dut";
  m.orientation.w = 0.5;
  m.orientation.x = 0.1;
  m.orientation_covariance[0] = -1.0;
  m.angular_velocity.x = 0.01;
  m.angular_velocity.y = -0.02;
  m.angular_velocity.z = 0.03;
  m.angular_velocity_covariance[4] = 0.25;
  m.linear_acceleration.x = 0.3;
  m.linear_acceleration.y = -0.2;
  m.linear_acceleration.z = 9.9;
  return m;
}

ai::io::ApplyCalibration calibration() {
  ai::io::ApplyCalibration c;
  Eigen::Matrix3d S;
  S << 1.02, 0.01, -0.02, 0.015, 0.97, 0.012, -0.011, 0.021, 1.03;
  c.P = S.inverse();
  c.O = Eigen::Vector3d(0.1, -0.05, 0.2);
  return c;
}

TEST(ApplyCalibration, CorrectsAccelerationAndPassesTheRestThrough) {
  const ai::io::ApplyCalibration c = calibration();
  const ai::CalibrationApplier applier(c);
  const sensor_msgs::Imu in = raw_message();
  sensor_msgs::Imu out;
  applier.apply(in, &out);
  const Eigen::Vector3d expected = c.P * (Eigen::Vector3d(0.3, -0.2, 9.9) - c.O);
  EXPECT_NEAR(out.linear_acceleration.x, expected(0), 1e-14);
  EXPECT_NEAR(out.linear_acceleration.y, expected(1), 1e-14);
  EXPECT_NEAR(out.linear_acceleration.z, expected(2), 1e-14);
  EXPECT_EQ(out.header.seq, in.header.seq);
  EXPECT_EQ(out.header.stamp, in.header.stamp);
  EXPECT_EQ(out.header.frame_id, in.header.frame_id);
  EXPECT_EQ(out.orientation.w, in.orientation.w);
  EXPECT_EQ(out.orientation.x, in.orientation.x);
  EXPECT_EQ(out.orientation_covariance, in.orientation_covariance);
  EXPECT_EQ(out.angular_velocity.y, in.angular_velocity.y);
  EXPECT_EQ(out.angular_velocity_covariance, in.angular_velocity_covariance);
  // No noise known, input covariance all zero (unknown): passed through.
  EXPECT_EQ(out.linear_acceleration_covariance, in.linear_acceleration_covariance);
}

TEST(ApplyCalibration, CovarianceFromTheNoiseOrCarriedThroughP) {
  ai::io::ApplyCalibration c = calibration();
  sensor_msgs::Imu in = raw_message();
  sensor_msgs::Imu out;
  // The input states a covariance: P C P^T.
  Eigen::Matrix3d C = Eigen::Vector3d(1e-4, 2e-4, 3e-4).asDiagonal();
  C(0, 1) = C(1, 0) = 1e-5;
  for (int i = 0; i < 9; ++i) in.linear_acceleration_covariance[i] = C(i / 3, i % 3);
  ai::CalibrationApplier(c).apply(in, &out);
  const Eigen::Matrix3d through = c.P * C * c.P.transpose();
  for (int i = 0; i < 9; ++i)
    EXPECT_NEAR(out.linear_acceleration_covariance[i], through(i / 3, i % 3), 1e-18);
  // -1: unknown, left alone.
  in.linear_acceleration_covariance.fill(0.0);
  in.linear_acceleration_covariance[0] = -1.0;
  ai::CalibrationApplier(c).apply(in, &out);
  EXPECT_EQ(out.linear_acceleration_covariance[0], -1.0);
  // The file states the noise: P diag(sigma^2) P^T, whatever the input says.
  c.sample_std = Eigen::Vector3d(0.01, 0.02, 0.015);
  const ai::CalibrationApplier with_noise(c);
  EXPECT_TRUE(with_noise.noise_known());
  with_noise.apply(in, &out);
  const Eigen::Matrix3d expected = c.P * c.sample_std.cwiseAbs2().asDiagonal() * c.P.transpose();
  for (int i = 0; i < 9; ++i) {
    EXPECT_NEAR(out.linear_acceleration_covariance[i], expected(i / 3, i % 3), 1e-18) << i;
  }
}

}  // namespace
