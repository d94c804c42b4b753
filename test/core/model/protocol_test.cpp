#include "accel_intrinsics/core/model/protocol.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/effects.h"
#include "accel_intrinsics/core/model/model.h"

namespace core = accel_intrinsics::core;

TEST(Protocol, ScheduleVisitsEveryPhaseAndStepInOrder) {
  core::ProtocolOptions options;
  options.steps_per_phase = 8;
  const auto schedule = core::build_schedule(options);
  ASSERT_EQ(schedule.size(), 24u);
  for (std::size_t i = 0; i < schedule.size(); ++i) {
    EXPECT_EQ(core::index(schedule[i].phase), static_cast<int>(i / 8));
    EXPECT_EQ(schedule[i].step, i % 8);
    EXPECT_DOUBLE_EQ(schedule[i].angle_rad, 2 * core::kPi * (i % 8) / 8.0);
    EXPECT_LT(schedule[i].move_start_s, schedule[i].settled_s);
    EXPECT_NEAR(schedule[i].dwell_end_s - schedule[i].settled_s, options.dwell_s, 1e-12);
    if (i > 0) {
      EXPECT_DOUBLE_EQ(schedule[i].move_start_s, schedule[i - 1].dwell_end_s);
    }
  }
}

TEST(Protocol, TwoWaySweepReturnsFromAbove) {
  core::ProtocolOptions options;
  options.steps_per_phase = 4;
  options.two_way = true;
  const auto schedule = core::build_schedule(options);
  ASSERT_EQ(schedule.size(), 24u);
  const unsigned expected_steps[8] = {0, 1, 2, 3, 3, 2, 1, 0};
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(schedule[i].step, expected_steps[i]);
    EXPECT_EQ(schedule[i].approach, i < 4 ? +1 : -1);
  }
}

TEST(Protocol, ClosingPositionRevisitsZeroAtTwoPiAfterTheLastStep) {
  core::ProtocolOptions options;
  options.steps_per_phase = 6;
  options.closing_position = true;
  const std::uint32_t n = options.steps_per_phase;
  const auto schedule = core::build_schedule(options);
  ASSERT_EQ(schedule.size(), 3u * (n + 1));
  EXPECT_EQ(core::scheduled_positions_per_phase(options), n + 1);
  for (std::size_t i = 0; i < schedule.size(); ++i) {
    const core::ScheduledPosition& p = schedule[i];
    const std::uint32_t k = static_cast<std::uint32_t>(i % (n + 1));
    EXPECT_EQ(core::index(p.phase), static_cast<int>(i / (n + 1))) << i;
    EXPECT_EQ(p.step, k) << i;
    EXPECT_EQ(p.steps, n) << i;
    EXPECT_EQ(p.approach, +1) << i;
    EXPECT_EQ(core::is_closing_step(p.step, p.steps), k == n) << i;
    EXPECT_DOUBLE_EQ(p.angle_rad, 2 * core::kPi * k / n) << i;
    // The closing position is timed like any other step of the phase: one move, settle, dwell.
    const double travel = k == 0 ? options.phase_change_s : options.move_s;
    EXPECT_NEAR(p.settled_s - p.move_start_s, travel + options.settle_s, 1e-12) << i;
    EXPECT_NEAR(p.dwell_end_s - p.settled_s, options.dwell_s, 1e-12) << i;
    if (i > 0) EXPECT_DOUBLE_EQ(p.move_start_s, schedule[i - 1].dwell_end_s) << i;
  }
  // Exactly 2 pi (not wrapped to 0), right after step N-1 and before the next phase begins.
  const core::ScheduledPosition& closing = schedule[n];
  EXPECT_EQ(closing.step, n);
  EXPECT_EQ(closing.angle_rad, 2 * core::kPi);
  EXPECT_EQ(core::step_angle(n, n), 2 * core::kPi);
  EXPECT_EQ(schedule[n - 1].step, n - 1);
  EXPECT_EQ(schedule[n + 1].phase, core::Phase::Y);
  EXPECT_EQ(schedule[n + 1].step, 0u);
  // The same instant a phase without it would have ended, plus one step.
  core::ProtocolOptions plain = options;
  plain.closing_position = false;
  const auto base = core::build_schedule(plain);
  EXPECT_NEAR(closing.dwell_end_s - base[n - 1].dwell_end_s,
              options.move_s + options.settle_s + options.dwell_s, 1e-12);
  EXPECT_NEAR(schedule.back().dwell_end_s - base.back().dwell_end_s,
              3 * (options.move_s + options.settle_s + options.dwell_s), 1e-9);
}

TEST(Protocol, ClosingPositionTopsTheUpSweepOfATwoWaySweep) {
  core::ProtocolOptions options;
  options.steps_per_phase = 4;
  options.two_way = true;
  options.closing_position = true;
  EXPECT_NO_THROW(core::validate(options));
  const auto schedule = core::build_schedule(options);
  ASSERT_EQ(schedule.size(), 27u);
  EXPECT_EQ(core::scheduled_positions_per_phase(options), 9u);
  // Up 0..3, the closing position 4 at 2 pi, then back down 3..0 from above.
  const unsigned expected_steps[9] = {0, 1, 2, 3, 4, 3, 2, 1, 0};
  for (int phase = 0; phase < 3; ++phase) {
    for (int i = 0; i < 9; ++i) {
      const core::ScheduledPosition& p = schedule[9 * phase + i];
      EXPECT_EQ(core::index(p.phase), phase);
      EXPECT_EQ(p.step, expected_steps[i]) << i;
      EXPECT_EQ(p.approach, i <= 4 ? +1 : -1) << i;
      EXPECT_DOUBLE_EQ(p.angle_rad, 2 * core::kPi * expected_steps[i] / 4.0) << i;
    }
  }
  // The return sweep now really comes from above: every return angle is below the one before.
  for (int i = 5; i < 9; ++i) EXPECT_LT(schedule[i].angle_rad, schedule[i - 1].angle_rad) << i;
  // The closing position is visited once per phase, never on the way down.
  int closing = 0;
  for (const auto& p : schedule) closing += core::is_closing_step(p.step, p.steps) ? 1 : 0;
  EXPECT_EQ(closing, 3);
}

TEST(Protocol, StepRangeAcceptsTheClosingStepOnly) {
  EXPECT_TRUE(core::step_in_protocol(0, 24));
  EXPECT_TRUE(core::step_in_protocol(23, 24));
  EXPECT_TRUE(core::step_in_protocol(24, 24));  // the closing position
  EXPECT_FALSE(core::step_in_protocol(25, 24));
  EXPECT_FALSE(core::step_in_protocol(0, 0));
  EXPECT_TRUE(core::is_closing_step(24, 24));
  EXPECT_FALSE(core::is_closing_step(23, 24));
  EXPECT_FALSE(core::is_closing_step(0, 0));
  // The closing position does not relax the requirements on the sweep itself.
  core::ProtocolOptions options;
  options.closing_position = true;
  options.steps_per_phase = 2;
  EXPECT_THROW(core::validate(options), std::invalid_argument);
  options.steps_per_phase = 3;
  EXPECT_NO_THROW(core::validate(options));
  EXPECT_EQ(core::build_schedule(options).size(), 12u);
}

TEST(Protocol, RejectsTooFewStepsNamingTheField) {
  core::ProtocolOptions options;
  options.steps_per_phase = 2;
  try {
    core::validate(options);
    FAIL() << "expected an exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("steps_per_phase"), std::string::npos);
  }
  options.steps_per_phase = 12;
  options.dwell_s = 0.0;
  EXPECT_THROW(core::validate(options), std::invalid_argument);
}

TEST(Model, SpecificForceFollowsEquationFour) {
  const std::vector<core::Effect> none;
  const double g = 9.8;
  const double a = 0.7;
  core::DwellGeometry geom;
  geom.angle_rad = a;
  geom.phase = core::Phase::X;
  auto f = core::specific_force<double>(none, nullptr, geom, g);
  EXPECT_NEAR(f(0), 0.0, 1e-15);
  EXPECT_NEAR(f(1), g * std::sin(a), 1e-15);
  EXPECT_NEAR(f(2), g * std::cos(a), 1e-15);
  geom.phase = core::Phase::Y;
  f = core::specific_force<double>(none, nullptr, geom, g);
  EXPECT_NEAR(f(0), g * std::sin(a), 1e-15);
  EXPECT_NEAR(f(2), g * std::cos(a), 1e-15);
  geom.phase = core::Phase::Z;
  f = core::specific_force<double>(none, nullptr, geom, g);
  EXPECT_NEAR(f(0), g * std::sin(a), 1e-15);
  EXPECT_NEAR(f(1), g * std::cos(a), 1e-15);
  EXPECT_NEAR(f(2), 0.0, 1e-15);
}

TEST(Model, EachEffectTermMatchesItsDefinition) {
  core::Device device;
  device.S << 1.01, 0.01, -0.02, 0.005, 0.99, 0.01, 0.02, -0.01, 1.02;
  device.O << 0.1, -0.2, 0.05;
  const double g = 9.80665;
  core::DwellGeometry geom;
  geom.phase = core::Phase::Y;
  geom.angle_rad = 1.1;
  geom.time_s = 100.0;
  geom.approach = -1;
  const Eigen::Vector3d base = core::predict_outputs(device, geom, g);
  const Eigen::Vector3d f = core::specific_force<double>({}, nullptr, geom, g);
  const Eigen::Vector3d L = device.S * f;
  EXPECT_TRUE(base.isApprox(L + device.O, 1e-14));

  auto with = [&](const core::Effect& e) {
    core::Device d = device;
    d.effects = {e};
    return core::predict_outputs(d, geom, g);
  };
  const double norm_v = device.S.row(1).norm();
  Eigen::Vector3d r = with(core::make_effect("quadratic_nonlinearity", "v", 1e-3));
  EXPECT_NEAR(r(1) - base(1), 1e-3 * L(1) * L(1) / norm_v, 1e-12);
  EXPECT_NEAR(r(0), base(0), 1e-15);
  r = with(core::make_effect("cubic_nonlinearity", "v", 1e-4));
  EXPECT_NEAR(r(1) - base(1), 1e-4 * std::pow(L(1), 3) / (norm_v * norm_v), 1e-12);
  r = with(core::make_effect("offset_drift", "w", 2e-5));
  EXPECT_NEAR(r(2) - base(2), 2e-5 * 100.0, 1e-12);

  auto at_angle = [&](double alpha, double scale_tilt, bool tilt) {
    core::DwellGeometry gg = geom;
    gg.angle_rad = alpha;
    Eigen::Vector3d ff = core::specific_force<double>({}, nullptr, gg, g);
    if (tilt) {
      ff *= std::cos(scale_tilt);
      ff(1) += g * std::sin(scale_tilt);
    }
    return Eigen::Vector3d(device.S * ff + device.O);
  };
  r = with(core::make_effect("angle_offset", "y", 0.01));
  EXPECT_TRUE(r.isApprox(at_angle(1.11, 0, false), 1e-13));
  r = with(core::make_effect("angle_scale", "y", 0.002));
  EXPECT_TRUE(r.isApprox(at_angle(1.1 * 1.002, 0, false), 1e-13));
  r = with(core::make_effect("backlash", "y", 0.004));  // approach -1: -b/2
  EXPECT_TRUE(r.isApprox(at_angle(1.1 - 0.002, 0, false), 1e-13));
  r = with(core::make_effect("axis_tilt", "y", 0.003));
  EXPECT_TRUE(r.isApprox(at_angle(1.1, 0.003, true), 1e-13));
  // An effect on another phase changes nothing.
  r = with(core::make_effect("angle_offset", "x", 0.01));
  EXPECT_TRUE(r.isApprox(base, 1e-15));
}

TEST(Model, ValidateRefusesASingularOrNonFiniteDevice) {
  core::Device device;
  device.S << 1.01, 0.01, -0.02, 0.005, 0.99, 0.01, 0.02, -0.01, 1.02;
  device.O << 0.1, -0.2, 0.05;
  EXPECT_NO_THROW(core::validate(device));
  core::Device rank2 = device;
  rank2.S.row(2) = 0.5 * device.S.row(0) + 2.0 * device.S.row(1);  // w in the plane of u and v
  EXPECT_THROW(core::validate(rank2), std::invalid_argument);
  core::Device rank1 = device;
  rank1.S.row(1) = 2.0 * device.S.row(0);
  rank1.S.row(2) = -device.S.row(0);
  EXPECT_THROW(core::validate(rank1), std::invalid_argument);
  core::Device nan_offset = device;
  nan_offset.O(1) = std::nan("");
  EXPECT_THROW(core::validate(nan_offset), std::invalid_argument);
}

TEST(Model, ClosingPositionAngleIsNotWrapped) {
  // At the closing position (commanded 2 pi) an angle-scale error is eps * 2 pi, an angle offset
  // is the same as at 0: the model must never reduce the commanded angle modulo 2 pi.
  core::Device device;
  device.S << 1.01, 0.01, -0.02, 0.005, 0.99, 0.01, 0.02, -0.01, 1.02;
  device.O << 0.1, -0.2, 0.05;
  const double g = 9.80665;
  core::DwellGeometry zero, closing;
  zero.phase = closing.phase = core::Phase::X;
  zero.angle_rad = core::step_angle(0, 12);
  closing.angle_rad = core::step_angle(12, 12);
  auto with = [&](const core::DwellGeometry& geom, const char* name, double value) {
    core::Device d = device;
    d.effects = {core::make_effect(name, "x", value)};
    return Eigen::Vector3d(core::predict_outputs(d, geom, g));
  };
  const double eps = 1e-3;
  core::DwellGeometry expected = zero;
  expected.angle_rad = 2 * core::kPi * eps;  // 2 pi (1 + eps) is this orientation
  EXPECT_TRUE(with(closing, "angle_scale", eps)
                  .isApprox(core::predict_outputs(device, expected, g), 1e-12));
  EXPECT_TRUE(
      with(zero, "angle_scale", eps).isApprox(core::predict_outputs(device, zero, g), 1e-15));
  EXPECT_GT((with(closing, "angle_scale", eps) - with(zero, "angle_scale", eps)).norm(), 1e-3 * g);
  EXPECT_TRUE(
      with(closing, "angle_offset", 0.01).isApprox(with(zero, "angle_offset", 0.01), 1e-12));
}

TEST(Effects, NamesRoundTripAndBadNamesAreRejected) {
  for (const auto& info : core::effect_catalog()) {
    const char* target = info.target_kind == core::TargetKind::Accelerometer ? "w"
                         : info.target_kind == core::TargetKind::Phase       ? "z"
                                                                             : "all";
    const core::Effect e = core::make_effect(info.name, target, 1.5);
    EXPECT_EQ(e.name(), info.name);
    EXPECT_EQ(e.target_name(), target);
  }
  EXPECT_THROW(core::make_effect("gremlins", "u"), std::invalid_argument);
  EXPECT_THROW(core::make_effect("angle_offset", "u"), std::invalid_argument);
  EXPECT_THROW(core::make_effect("quadratic_nonlinearity", "x"), std::invalid_argument);
}
