#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "accel_intrinsics/core/constants.h"
#include "accel_intrinsics/core/effects.h"
#include "accel_intrinsics/core/model.h"
#include "accel_intrinsics/core/protocol.h"

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

TEST(Effects, NamesRoundTripAndBadNamesAreRejected) {
  for (const auto& info : core::effect_catalog()) {
    const char* target = info.target_kind == core::TargetKind::Accelerometer ? "w"
                         : info.target_kind == core::TargetKind::Phase     ? "z"
                                                                           : "all";
    const core::Effect e = core::make_effect(info.name, target, 1.5);
    EXPECT_EQ(e.name(), info.name);
    EXPECT_EQ(e.target_name(), target);
  }
  EXPECT_THROW(core::make_effect("gremlins", "u"), std::invalid_argument);
  EXPECT_THROW(core::make_effect("angle_offset", "u"), std::invalid_argument);
  EXPECT_THROW(core::make_effect("quadratic_nonlinearity", "x"), std::invalid_argument);
}
