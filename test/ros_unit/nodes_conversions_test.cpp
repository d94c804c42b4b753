// conversions.h: GimbalCommand, Imu and IntrinsicResult against the core types. No roscore.
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <map>
#include <string>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/ros/conversions.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

TEST(Conversions, GimbalCommandRoundTrip) {
  for (std::uint8_t phase = 0; phase < 3; ++phase) {
    for (std::uint8_t state = 0; state < 3; ++state) {
      ai::GimbalCommand msg;
      msg.header.stamp = ros::Time(1234, 500000000);
      msg.phase = phase;
      msg.step = 7;
      msg.steps = 12;
      msg.angle = 2.0 * core::kPi * 7 / 12;
      msg.state = state;
      const core::GimbalEvent e = ai::to_core(msg);
      EXPECT_DOUBLE_EQ(e.stamp_s, 1234.5);
      EXPECT_EQ(core::index(e.phase), phase);
      EXPECT_EQ(static_cast<int>(e.state), state);
      EXPECT_EQ(e.step, 7u);
      EXPECT_EQ(e.steps, 12u);
      const ai::GimbalCommand back = ai::to_msg(e);
      EXPECT_EQ(back.header.stamp, msg.header.stamp);
      EXPECT_EQ(back.phase, phase);
      EXPECT_EQ(back.state, state);
      EXPECT_EQ(back.angle, msg.angle);
    }
  }
  EXPECT_EQ(ai::GimbalCommand::MOVING, static_cast<int>(core::GimbalState::Moving));
  EXPECT_EQ(ai::GimbalCommand::SETTLED, static_cast<int>(core::GimbalState::Settled));
  EXPECT_EQ(ai::GimbalCommand::DONE, static_cast<int>(core::GimbalState::Done));
}

TEST(Conversions, ImuFollowsContract) {
  core::ImuSample s;
  s.stamp_s = 100.25;
  s.outputs = Eigen::Vector3d(0.1, -0.2, 9.8);
  const sensor_msgs::Imu msg = ai::to_msg(s, "dut", 4e-4);
  EXPECT_EQ(msg.header.frame_id, "dut");
  EXPECT_EQ(msg.orientation_covariance[0], -1.0);
  EXPECT_EQ(msg.angular_velocity_covariance[0], -1.0);
  EXPECT_EQ(msg.linear_acceleration.x, 0.1);
  EXPECT_EQ(msg.linear_acceleration.y, -0.2);
  EXPECT_EQ(msg.linear_acceleration.z, 9.8);
  EXPECT_EQ(msg.linear_acceleration_covariance[0], 4e-4);
  EXPECT_EQ(msg.linear_acceleration_covariance[4], 4e-4);
  EXPECT_EQ(msg.linear_acceleration_covariance[8], 4e-4);
  EXPECT_EQ(msg.linear_acceleration_covariance[1], 0.0);
  const core::ImuSample back = ai::to_core(msg);
  EXPECT_NEAR(back.stamp_s, 100.25, 1e-9);
  EXPECT_EQ(back.outputs, s.outputs);
  // NaN passes through (the assembler drops and counts it).
  sensor_msgs::Imu bad = msg;
  bad.linear_acceleration.y = std::nan("");
  EXPECT_TRUE(std::isnan(ai::to_core(bad).outputs(1)));
}

TEST(Conversions, IntrinsicResult) {
  core::FitResult fit;
  fit.model = core::FitModel::Eq4;
  fit.local_gravity = 9.80123;
  fit.S << 1.01, 0.002, 0.0, 0.0, 0.99, 0.003, 0.001, 0.0, 1.002;
  fit.O << 0.1, 0.2, 0.3;
  fit.O_std << 0.01, 0.02, 0.03;
  fit.intrinsics.responsivity << 1.01, 0.99, 1.002;
  fit.intrinsics.responsivity_std << 1e-4, 2e-4, 3e-4;
  fit.intrinsics.angles_rad << core::deg_to_rad(89.9), core::deg_to_rad(90.1),
      core::deg_to_rad(90.0);
  fit.intrinsics.angles_std_rad << core::deg_to_rad(0.01), core::deg_to_rad(0.02),
      core::deg_to_rad(0.03);
  for (int s = 0; s < 3; ++s)
    for (int p = 0; p < 3; ++p) fit.offset_per_phase(s, p) = 10 * s + p;
  fit.cross_sensitivity = fit.S.inverse();
  fit.reduced_chi2 = 1.1;
  fit.residual_rms = 0.002;
  fit.positions = {{12, 12, 11}};
  const ai::IntrinsicResult msg = ai::to_msg(fit);
  EXPECT_EQ(msg.model, fit.model_label());
  EXPECT_DOUBLE_EQ(msg.local_gravity, 9.80123);
  EXPECT_DOUBLE_EQ(msg.responsivity[1], 0.99);
  EXPECT_DOUBLE_EQ(msg.responsivity_std[2], 3e-4);
  EXPECT_NEAR(msg.angles_deg[0], 89.9, 1e-12);
  EXPECT_NEAR(msg.angles_std_deg[1], 0.02, 1e-12);
  EXPECT_DOUBLE_EQ(msg.u.x, 1.01);
  EXPECT_DOUBLE_EQ(msg.v.z, 0.003);
  EXPECT_DOUBLE_EQ(msg.w.x, 0.001);
  EXPECT_DOUBLE_EQ(msg.offset[2], 0.3);
  EXPECT_DOUBLE_EQ(msg.offset_std[1], 0.02);
  EXPECT_DOUBLE_EQ(msg.offset_per_phase[1], 1.0);   // u_y
  EXPECT_DOUBLE_EQ(msg.offset_per_phase[3], 10.0);  // v_x
  EXPECT_DOUBLE_EQ(msg.cross_sensitivity[5], fit.cross_sensitivity(1, 2));
  EXPECT_EQ(msg.positions[2], 11u);
  EXPECT_DOUBLE_EQ(msg.reduced_chi2, 1.1);
}

TEST(Conversions, MalformedGimbalCommandsAreRefused) {
  ai::GimbalCommand msg;
  msg.header.stamp = ros::Time(10.0);
  msg.phase = ai::GimbalCommand::PHASE_Y;
  msg.state = ai::GimbalCommand::SETTLED;
  msg.step = 3;
  msg.steps = 4;
  msg.angle = 1.0;
  EXPECT_TRUE(ai::is_well_formed(msg));
  ai::GimbalCommand bad = msg;
  bad.phase = 3;
  EXPECT_FALSE(ai::is_well_formed(bad));
  bad = msg;
  bad.angle = NAN;
  EXPECT_FALSE(ai::is_well_formed(bad));
  bad = msg;
  bad.step = 5;  // beyond the closing position
  EXPECT_FALSE(ai::is_well_formed(bad));
  bad = msg;
  bad.header.stamp = ros::Time();
  EXPECT_FALSE(ai::is_well_formed(bad));
}

TEST(Conversions, StatusMessageCarriesTheRunState) {
  core::RunStatus st;
  st.state = core::RunState::Aborted;
  st.fault = "IMU stream stopped";
  st.retries = 2;
  st.dwells_per_phase = {{4, 1, 0}};
  const auto msg = ai::to_status_msg(st, "run aborted", "", 12.5, "/calibration");
  EXPECT_EQ(msg.level, diagnostic_msgs::DiagnosticStatus::ERROR);
  std::map<std::string, std::string> values;
  for (const auto& kv : msg.values) values[kv.key] = kv.value;
  EXPECT_EQ(values["state"], "ABORTED");
  EXPECT_EQ(values["run_state"], "aborted");
  EXPECT_EQ(values["fault"], "IMU stream stopped");
  EXPECT_EQ(values["retries"], "2");
  EXPECT_EQ(values["dwells_y"], "1");
  st.state = core::RunState::Dwelling;
  st.fault.clear();
  const auto running = ai::to_status_msg(st, "collecting", "", 13.0, "/calibration");
  EXPECT_EQ(running.level, diagnostic_msgs::DiagnosticStatus::OK);
  for (const auto& kv : running.values) {
    if (kv.key == "state") {
      EXPECT_EQ(kv.value, "COLLECTING");
    }
  }
}
