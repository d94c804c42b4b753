// The joint controller emulator's servo motion (emulators/joint_motion.h) against the damped
// oscillator's closed form: the overshoot of a small step, the speed limit of a large one, the
// final position, and the integration step not changing the motion.
#include "accel_intrinsics/emulators/joint_motion.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace ai = accel_intrinsics;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

struct Trace {
  double peak_rad = -1e9;
  double peak_speed_rad_s = 0.0;
  double first_within_s = -1.0;  // first time within `band` of the target
};

// Runs the joint for duration_s in 20 ms calls (the emulator's 50 Hz), recording the peak
// position, the peak speed and when it first came within band_rad of target_rad.
Trace run(ai::JointMotion* joint, double target_rad, double duration_s, double band_rad) {
  Trace t;
  joint->command(target_rad);
  for (double s = 0.0; s < duration_s; s += 0.02) {
    joint->advance(0.02);
    t.peak_rad = std::max(t.peak_rad, joint->position_rad());
    t.peak_speed_rad_s = std::max(t.peak_speed_rad_s, std::abs(joint->velocity_rad_s()));
    if (t.first_within_s < 0.0 && std::abs(joint->position_rad() - target_rad) < band_rad)
      t.first_within_s = s + 0.02;
  }
  return t;
}

}  // namespace

TEST(JointMotion, SmallStepOvershootsAsTheDampedOscillator) {
  ai::JointMotionOptions o;
  o.natural_frequency_hz = 2.0;
  o.damping_ratio = 0.6;
  o.max_speed_deg_s = 1000.0;  // not reached by a 2 deg step
  ai::JointMotion joint(o);
  const double step = 2.0 * kDeg;
  const Trace t = run(&joint, step, 3.0, 1e-3 * kDeg);
  // Closed form of x'' + 2 zeta wn x' + wn^2 x = wn^2 step from rest: peak overshoot
  // exp(-pi zeta / sqrt(1 - zeta^2)) = 9.48 % at zeta = 0.6.
  const double expected = std::exp(-kPi * 0.6 / std::sqrt(1.0 - 0.36));
  EXPECT_NEAR(expected, 0.0948, 1e-4);
  EXPECT_NEAR((t.peak_rad - step) / step, expected, 0.003);
  EXPECT_NEAR(o.small_step_overshoot(), expected, 1e-12);
  // Peak speed of the same solution: wn step exp(-zeta phi / sqrt(1 - zeta^2)), phi = acos(zeta).
  const double wn = 2.0 * kPi * 2.0;
  const double peak_speed = wn * step * std::exp(-0.6 * std::acos(0.6) / 0.8);
  EXPECT_NEAR(t.peak_speed_rad_s, peak_speed, 0.01 * peak_speed);
  EXPECT_NEAR(joint.position_rad(), step, 1e-4 * kDeg);  // rung down after 3 s (ten 1/(zeta wn))
}

TEST(JointMotion, LargeMoveKeepsTheSpeedLimitAndArrives) {
  ai::JointMotionOptions o;  // defaults: 2 Hz, damping 0.7, 90 deg/s
  ai::JointMotion joint(o, 0.0);
  const Trace t = run(&joint, 90.0 * kDeg, 4.0, 0.05 * kDeg);
  EXPECT_LE(t.peak_speed_rad_s, 90.0 * kDeg * (1.0 + 1e-12));
  EXPECT_GE(t.peak_speed_rad_s, 90.0 * kDeg * 0.999);  // it does run at the limit
  // 90 deg at 90 deg/s: no sooner than 1 s; the approach adds a fraction of a second.
  EXPECT_GE(t.first_within_s, 1.0);
  EXPECT_LE(t.first_within_s, 2.0);
  // It overshoots a little (the servo's ring), less than the small-step share of the move.
  EXPECT_GT(t.peak_rad, 90.0 * kDeg);
  EXPECT_LT(t.peak_rad - 90.0 * kDeg, o.small_step_overshoot() * 90.0 * kDeg);
  EXPECT_NEAR(joint.position_rad(), 90.0 * kDeg, 0.001 * kDeg);
  // And back down: the same limit the other way.
  const Trace back = run(&joint, -30.0 * kDeg, 4.0, 0.05 * kDeg);
  EXPECT_LE(back.peak_speed_rad_s, 90.0 * kDeg * (1.0 + 1e-12));
  EXPECT_GE(back.first_within_s, 120.0 / 90.0);
  EXPECT_NEAR(joint.position_rad(), -30.0 * kDeg, 0.001 * kDeg);
}

TEST(JointMotion, OneLongAdvanceEqualsManyShortOnes) {
  ai::JointMotionOptions o;
  ai::JointMotion a(o, 0.1), b(o, 0.1);
  a.command(1.0);
  b.command(1.0);
  a.advance(0.7);  // one call of 0.7 s (a coarse simulated clock step)
  for (int i = 0; i < 35; ++i) b.advance(0.02);
  EXPECT_NEAR(a.position_rad(), b.position_rad(), 1e-3);
  EXPECT_NEAR(a.velocity_rad_s(), b.velocity_rad_s(), 1e-2);
  const double before = a.position_rad();
  a.advance(0.0);
  a.advance(-1.0);
  a.advance(std::nan(""));
  EXPECT_EQ(a.position_rad(), before);
}

TEST(JointMotion, HoldsStillWithoutACommand) {
  ai::JointMotion joint(ai::JointMotionOptions{}, 0.25);
  joint.advance(10.0);
  EXPECT_EQ(joint.position_rad(), 0.25);
  EXPECT_EQ(joint.command_rad(), 0.25);
}

TEST(JointMotion, InvalidOptionsNameTheField) {
  auto message = [](ai::JointMotionOptions o) -> std::string {
    try {
      o.validate();
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  ai::JointMotionOptions o;
  EXPECT_EQ(message(o), "");
  o.natural_frequency_hz = 0.0;
  EXPECT_NE(message(o).find("natural_frequency_hz"), std::string::npos);
  o = {};
  o.damping_ratio = -0.1;
  EXPECT_NE(message(o).find("damping_ratio"), std::string::npos);
  o = {};
  o.max_speed_deg_s = std::nan("");
  EXPECT_NE(message(o).find("max_speed_deg_s"), std::string::npos);
  o = {};
  o.max_step_s = 0.1;  // too coarse for 2 Hz
  EXPECT_NE(message(o).find("max_step_s"), std::string::npos);
  EXPECT_THROW(ai::JointMotion(o, 0.0), std::invalid_argument);
}
