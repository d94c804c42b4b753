// The stage kinematics R = Rx(X) Rz(Y) (docs/design.md section 15): with the default axis map it
// reproduces section 1's three phases (written out here from the equations, not from the
// package's model), and a tilted turning axis gives model.h's axis_tilt term.
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/gimbal_kinematics.h"
#include "accel_intrinsics/core/model/model.h"

namespace core = accel_intrinsics::core;

namespace {

constexpr double kG = 9.80665;

// Section 1, eq. (4), written out.
Eigen::Vector3d section1_force(core::Phase p, double a) {
  switch (p) {
    case core::Phase::X: return kG * Eigen::Vector3d(0.0, std::sin(a), std::cos(a));
    case core::Phase::Y: return kG * Eigen::Vector3d(std::sin(a), 0.0, std::cos(a));
    default: return kG * Eigen::Vector3d(std::sin(a), std::cos(a), 0.0);
  }
}

// Rx and Rz from their matrices (not Eigen's AngleAxis, which the implementation uses).
Eigen::Matrix3d rx(double t) {
  Eigen::Matrix3d m;
  m << 1, 0, 0, 0, std::cos(t), -std::sin(t), 0, std::sin(t), std::cos(t);
  return m;
}
Eigen::Matrix3d rz(double t) {
  Eigen::Matrix3d m;
  m << std::cos(t), -std::sin(t), 0, std::sin(t), std::cos(t), 0, 0, 0, 1;
  return m;
}

}  // namespace

TEST(StageKinematics, IsRxOfXTimesRzOfY) {
  for (double x : {-2.0, 0.0, 0.3, 1.9}) {
    for (double y : {-1.0, 0.0, 0.8, 3.0}) {
      core::StageAngles s;
      s.x_rad = x;
      s.y_rad = y;
      const Eigen::Matrix3d R = core::stage_rotation(s);
      EXPECT_NEAR((R - rx(x) * rz(y)).norm(), 0.0, 1e-14) << x << " " << y;
      EXPECT_NEAR(R.determinant(), 1.0, 1e-14);
    }
  }
}

TEST(StageKinematics, DefaultAxisMapIsSection1) {
  const double deg = core::kPi / 180.0;
  // The default axis map in degrees, as config/grbl_gimbal.yaml writes it.
  struct Row {
    core::Phase phase;
    bool alpha_on_x;
    double other_deg;
  } rows[] = {
      {core::Phase::X, true, 0.0}, {core::Phase::Y, true, 90.0}, {core::Phase::Z, false, 90.0}};
  for (const Row& row : rows) {
    for (double a_deg : {0.0, 15.0, 60.0, 90.0, 137.5, 180.0, 250.0, 300.0, 359.0}) {
      const double a = a_deg * deg;
      const core::StageAngles s = core::default_stage_angles(row.phase, a);
      EXPECT_NEAR(row.alpha_on_x ? s.x_rad : s.y_rad, a, 1e-15);
      EXPECT_NEAR(row.alpha_on_x ? s.y_rad : s.x_rad, row.other_deg * deg, 1e-15);
      const Eigen::Matrix3d R = core::stage_rotation(s);
      const Eigen::Vector3d f = R.transpose() * Eigen::Vector3d(0.0, 0.0, kG);
      EXPECT_NEAR((f - section1_force(row.phase, a)).norm(), 0.0, 1e-12)
          << "phase " << core::phase_name(row.phase) << " alpha " << a_deg
          << " deg: " << f.transpose();
      EXPECT_NEAR((core::specific_force_in_dut(core::phase_pose(row.phase, a), kG) -
                   section1_force(row.phase, a))
                      .norm(),
                  0.0, 1e-12);
    }
  }
}

TEST(StageKinematics, TiltedAxisIsTheModelsAxisTilt) {
  // model.h's axis_tilt: f_p = g sin(tau), the other two scaled by cos(tau).
  for (core::Phase p : core::kPhases) {
    for (double tau : {-0.02, 0.005, 0.3}) {
      for (double a : {0.0, 1.0, 2.5, 4.0, 5.9}) {
        Eigen::Vector3d expected = std::cos(tau) * section1_force(p, a);
        expected(core::index(p)) = kG * std::sin(tau);
        const Eigen::Vector3d f = core::specific_force_in_dut(core::phase_pose(p, a, tau), kG);
        EXPECT_NEAR((f - expected).norm(), 0.0, 1e-12)
            << "phase " << core::phase_name(p) << " tau " << tau << " a " << a;
        core::Effect tilt;
        tilt.kind = core::EffectKind::AxisTilt;
        tilt.target = core::index(p);
        tilt.value = tau;
        core::DwellGeometry geom;
        geom.phase = p;
        geom.angle_rad = a;
        const Eigen::Vector3d model = core::specific_force({tilt}, &tau, geom, kG);
        EXPECT_NEAR((f - model).norm(), 0.0, 1e-12);
      }
    }
  }
}
