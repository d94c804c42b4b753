// The manual driver without ROS (docs/design.md section 15): the test plays the operator through
// the protocol (reads the target's stage positions in WAIT_OPERATOR, turns its own two-axis head
// there, calls continue) with an IMU written here (its own S and offsets, its own Rx Rz); a wrong
// pose is named (the phase and angle the IMU sees) and waited on, then corrected.
#include "accel_intrinsics/drivers/manual_gimbal.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>

#include "accel_intrinsics/core/run/gimbal_protocol.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

// The test's head: outer axis X about world x, inner axis Y about the outer frame's z.
Eigen::Vector3d force_at(double x_deg, double y_deg) {
  const double x = x_deg * kDeg, y = y_deg * kDeg;
  Eigen::Matrix3d rx, rz;
  rx << 1, 0, 0, 0, std::cos(x), -std::sin(x), 0, std::sin(x), std::cos(x);
  rz << std::cos(y), -std::sin(y), 0, std::sin(y), std::cos(y), 0, 0, 0, 1;
  return (rx * rz).transpose() * Eigen::Vector3d(0.0, 0.0, 9.81);
}

// The test's device: a few percent off identity, with offsets.
Eigen::Vector3d imu_outputs(const Eigen::Vector3d& f) {
  Eigen::Matrix3d S;
  S << 1.03, 0.02, -0.01, -0.015, 0.98, 0.025, 0.01, -0.02, 1.01;
  return S * f + Eigen::Vector3d(0.12, -0.1, 0.18);
}

ai::ManualGimbalOptions options() {
  ai::ManualGimbalOptions o;
  o.axis_map.phases[0].axis = "X";
  o.axis_map.phases[0].hold = {{"Y", 0.0}};
  o.axis_map.phases[1].axis = "X";
  o.axis_map.phases[1].hold = {{"Y", 90.0}};
  o.axis_map.phases[2].axis = "Y";
  o.axis_map.phases[2].hold = {{"X", 90.0}};
  return o;
}

}  // namespace

TEST(ManualGimbal, NearestPoseNamesPhaseAndAngle) {
  // eq. (4) directions of each phase come back as that phase and angle.
  const ai::PoseMatch x =
      ai::nearest_pose(Eigen::Vector3d(0.0, std::sin(2.0), std::cos(2.0)), core::Phase::Y);
  EXPECT_EQ(x.phase, core::Phase::X);
  EXPECT_NEAR(x.alpha_rad, 2.0, 1e-12);
  const ai::PoseMatch z =
      ai::nearest_pose(Eigen::Vector3d(std::sin(4.0), std::cos(4.0), 0.0), core::Phase::X);
  EXPECT_EQ(z.phase, core::Phase::Z);
  EXPECT_NEAR(z.alpha_rad, 4.0, 1e-12);
  // z up lies in the planes of x and y: the preferred one wins.
  EXPECT_EQ(ai::nearest_pose(Eigen::Vector3d(0, 0, 1), core::Phase::Y).phase, core::Phase::Y);
  EXPECT_EQ(ai::nearest_pose(Eigen::Vector3d(0, 0, 1), core::Phase::X).phase, core::Phase::X);
}

TEST(ManualGimbal, OperatorRunWithAWrongPoseNamedAndCorrected) {
  ai::ManualGimbal driver(options());
  EXPECT_EQ(driver.topics().imu, "imu/data_raw");
  core::GimbalProtocolOptions p;
  p.protocol.steps_per_phase = 6;
  p.protocol.dwell_s = 0.5;
  p.start_delay_s = 0.1;
  p.settle_timeout_s = 10.0;
  core::GimbalProtocol protocol(p, &driver);
  protocol.start(0.0);

  std::map<std::string, double> head = {{"X", 0.0}, {"Y", 0.0}};  // where the operator left it
  bool mistake_made = false, mistake_named = false;
  std::string complaint;
  int waits = 0, settled = 0;
  double t = 0.0;
  for (int k = 0; k < 200000 && protocol.state() != core::ProtocolState::Done &&
                  protocol.state() != core::ProtocolState::Aborted;
       ++k) {
    t = k * 1e-3;
    if (k % 10 == 0) driver.on_imu(t, imu_outputs(force_at(head["X"], head["Y"])));  // 100 Hz
    if (k % 10 != 0) continue;
    for (const core::ProtocolAction& a : protocol.tick(t)) {
      if (a.kind == core::ProtocolAction::Kind::Command &&
          a.command.state == core::GimbalState::Settled)
        ++settled;
    }
    if (protocol.state() != core::ProtocolState::WaitOperator) continue;
    // The operator reads the request and turns the head.
    const core::ProtocolStatus st = protocol.status(t);
    ++waits;
    ASSERT_FALSE(st.stage_deg.empty());
    head = st.stage_deg;
    // The held axis is named when a phase begins.
    EXPECT_EQ(st.operator_request.find(", ") != std::string::npos, st.position.step == 0)
        << st.operator_request;
    if (st.position.phase == core::Phase::Y && st.position.step == 2 && !mistake_made) {
      // Phase y at 120 deg: the operator turns X to 300 deg instead (60 deg short the other way).
      EXPECT_NEAR(st.stage_deg.at("X"), 120.0, 1e-9);
      EXPECT_EQ(st.operator_request, "phase y: set X to 120.0 deg");
      head["X"] = 300.0;
      mistake_made = true;
    } else if (mistake_made && !mistake_named) {
      // The next wait is the same position again, with the pose the IMU saw named.
      EXPECT_EQ(st.position.phase, core::Phase::Y);
      EXPECT_EQ(st.position.step, 2u);
      complaint = st.operator_complaint;
      // The device's S and offsets tilt the measured direction by a degree or so.
      const std::string seen = "the IMU sees phase y at ";
      ASSERT_EQ(complaint.rfind(seen, 0), 0u) << complaint;
      EXPECT_NEAR(std::stod(complaint.substr(seen.size())), 300.0, 3.0) << complaint;
      EXPECT_NE(complaint.find("not phase y at 120.0 deg"), std::string::npos) << complaint;
      EXPECT_NE(st.text.find(complaint), std::string::npos);
      mistake_named = true;
    } else {
      EXPECT_TRUE(st.operator_complaint.empty()) << st.operator_complaint;
    }
    ASSERT_TRUE(protocol.continue_after_remount(t).success);
  }
  ASSERT_EQ(protocol.state(), core::ProtocolState::Done) << protocol.status(t).text;
  EXPECT_TRUE(mistake_named);
  EXPECT_EQ(settled, 18);
  EXPECT_EQ(waits, 19);  // one per position and the one repeated
}

TEST(ManualGimbal, WaitsWithoutImuAndNeverSettlesUnchecked) {
  ai::ManualGimbal driver(options());
  ai::GimbalTarget target;
  target.phase = core::Phase::Z;
  target.angle_rad = 30.0 * kDeg;
  driver.move_to(target, 0.0);
  EXPECT_TRUE(driver.needs_operator(0.0));
  EXPECT_EQ(driver.operator_request(), "phase z: set Y to 30.0 deg, X to 90.0 deg");
  driver.operator_continue(1.0);
  driver.update(5.0);  // no IMU sample since continue: still checking
  EXPECT_FALSE(driver.settled(5.0));
  EXPECT_FALSE(driver.needs_operator(5.0));
  for (int i = 0; i < 20; ++i) driver.on_imu(5.0 + 0.06 * i, imu_outputs(force_at(90.0, 30.0)));
  driver.update(6.2);
  EXPECT_TRUE(driver.settled(6.2));
}
