// The tf chain the gimbal controller broadcasts reproduces the specific force of model.h
// (docs/design.md eq. 4 at the true angle, with the gimbal effects) in all three phases, and the
// simulated accelerometer turns it into predict_outputs() of the truth device. No roscore.
#include <gtest/gtest.h>
#include <tf2/buffer_core.h>

#include <cmath>
#include <vector>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/drivers/accelerometer_source.h"
#include "accel_intrinsics/drivers/gimbal_driver.h"
#include "accel_intrinsics/ros/gimbal_controller_node.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

namespace {

constexpr double kG = 9.80665;

core::Effect effect(core::EffectKind kind, int target, double value) {
  core::Effect e;
  e.kind = kind;
  e.target = target;
  e.value = value;
  return e;
}

// The values of the effect terms, in order (the model's parameter vector).
std::vector<double> values_of(const std::vector<core::Effect>& effects) {
  std::vector<double> values;
  for (const auto& e : effects) values.push_back(e.value);
  return values;
}

// R_world_dut as a tf listener sees it: the controller's message through tf2's BufferCore.
Eigen::Matrix3d through_tf(const ai::GimbalTransforms& transforms, double t_s) {
  tf2::BufferCore buffer;
  const tf2_msgs::TFMessage msg =
      ai::make_tf_message(transforms, ros::Time(t_s), "world", "gimbal", "dut");
  for (const auto& t : msg.transforms) buffer.setTransform(t, "test");
  const geometry_msgs::TransformStamped t = buffer.lookupTransform("world", "dut", ros::Time(t_s));
  const Eigen::Quaterniond q(t.transform.rotation.w, t.transform.rotation.x, t.transform.rotation.y,
                             t.transform.rotation.z);
  return q.toRotationMatrix();
}

Eigen::Vector3d force_in_dut(const Eigen::Matrix3d& R_world_dut) {
  return R_world_dut.transpose() * Eigen::Vector3d(0.0, 0.0, kG);  // REP 103: +g up
}

}  // namespace

TEST(GimbalTf, LinksAreProperRotationsAboutTheStageAxes) {
  // world -> gimbal turns about world x (the outer axis X), gimbal -> dut about z (inner axis Y).
  for (core::Phase p : core::kPhases) {
    for (double a : {0.0, 0.7, 2.0, 4.5}) {
      const ai::GimbalTransforms t = ai::gimbal_transforms(p, a, 0.0);
      const Eigen::Matrix3d W = t.world_gimbal.toRotationMatrix();
      const Eigen::Matrix3d M = t.gimbal_dut.toRotationMatrix();
      EXPECT_NEAR(M.determinant(), 1.0, 1e-12);
      EXPECT_NEAR((W * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX()).norm(), 0.0, 1e-12);
      EXPECT_NEAR((M * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitZ()).norm(), 0.0, 1e-12);
    }
  }
}

TEST(GimbalTf, IdealChainIsEquation4) {
  for (core::Phase p : core::kPhases) {
    for (int n = 0; n < 24; ++n) {
      const double a = 2.0 * core::kPi * n / 24.0;
      const Eigen::Vector3d f = force_in_dut(through_tf(ai::gimbal_transforms(p, a, 0.0), 10.0));
      const Eigen::Vector3d expected = kG * core::in_plane_direction(p, a);
      EXPECT_NEAR((f - expected).norm(), 0.0, 1e-12)
          << "phase " << core::phase_name(p) << " n " << n;
    }
  }
}

TEST(GimbalTf, SimulatedGimbalWithEffectsMatchesSpecificForce) {
  // All four gimbal effects in every phase, different values per phase.
  std::vector<core::Effect> effects;
  for (int p = 0; p < 3; ++p) {
    effects.push_back(effect(core::EffectKind::AngleOffset, p, 0.003 * (p + 1)));
    effects.push_back(effect(core::EffectKind::AngleScale, p, -0.002 * (p + 1)));
    effects.push_back(effect(core::EffectKind::AxisTilt, p, 0.01 * (p + 1) - 0.015));
    effects.push_back(effect(core::EffectKind::Backlash, p, 0.004));
  }
  const std::vector<double> values = values_of(effects);

  ai::SimulatedGimbalOptions options;
  options.move_s = 1.0;
  options.settle_s = 0.5;
  options.phase_change_s = 3.0;
  options.ringing_rad = 0.0;
  options.effects = effects;
  ai::SimulatedGimbalDriver driver(options);

  double t = 0.0;
  for (core::Phase p : core::kPhases) {
    for (int approach : {+1, -1}) {
      for (int n = 0; n < 12; ++n) {
        ai::GimbalTarget target;
        target.phase = p;
        target.step = n;
        target.steps = 12;
        target.angle_rad = core::step_angle(n, 12);
        target.approach = approach;
        driver.move_to(target, t);
        EXPECT_FALSE(driver.settled(t + 0.1));
        t += 10.0;
        ASSERT_TRUE(driver.settled(t));
        const Eigen::Vector3d f = force_in_dut(through_tf(driver.orientation(t), t));

        core::DwellGeometry geom;
        geom.phase = p;
        geom.angle_rad = target.angle_rad;
        geom.approach = approach;
        const Eigen::Vector3d expected = core::specific_force(effects, values.data(), geom, kG);
        EXPECT_NEAR((f - expected).norm(), 0.0, 1e-11)
            << "phase " << core::phase_name(p) << " step " << n << " approach " << approach
            << "\n f = " << f.transpose() << "\n model = " << expected.transpose();
      }
    }
  }
}

TEST(GimbalTf, MoveIsSmoothAndSettles) {
  ai::SimulatedGimbalOptions options;
  options.move_s = 1.0;
  options.settle_s = 0.5;
  options.phase_change_s = 2.0;
  options.ringing_rad = 0.01;
  ai::SimulatedGimbalDriver driver(options);
  ai::GimbalTarget target;
  target.phase = core::Phase::X;
  target.step = 0;
  target.steps = 4;
  target.angle_rad = 0.0;
  driver.move_to(target, -10.0);  // the first move mounts the DUT: phase_change_s
  EXPECT_FALSE(driver.settled(-10.0 + 2.4));
  ASSERT_TRUE(driver.settled(-10.0 + 2.5));
  target.step = 1;
  target.angle_rad = core::kPi / 2;
  const Eigen::Matrix3d before = driver.orientation(0.0).world_dut();
  driver.move_to(target, 0.0);
  // At the MOVING stamp the DUT has not moved yet.
  EXPECT_TRUE(driver.orientation(0.0).world_dut().isApprox(before, 1e-12));
  EXPECT_FALSE(driver.settled(1.2));
  EXPECT_TRUE(driver.settled(1.5));
  // Ringing has decayed below 1e-4 rad well into the dwell.
  const Eigen::Vector3d f = force_in_dut(driver.orientation(2.0).world_dut());
  EXPECT_NEAR((f - kG * core::in_plane_direction(core::Phase::X, core::kPi / 2)).norm(), 0.0, 1e-3);
}

// One motion model: driven through a protocol's schedule, the simulated gimbal is, at every
// instant of every move within a phase and of every dwell, where core::gimbal_pose_at() (the
// simulator's and the timing-lag estimator's motion) puts it, gimbal effects included; and it
// settles exactly at the schedule's SETTLED times.
TEST(GimbalTf, SimulatedGimbalMovesAlongTheCoreProfile) {
  std::vector<core::Effect> effects;
  effects.push_back(effect(core::EffectKind::AngleOffset, 0, 0.003));
  effects.push_back(effect(core::EffectKind::AngleScale, 1, -0.002));
  effects.push_back(effect(core::EffectKind::AxisTilt, 2, 0.004));
  effects.push_back(effect(core::EffectKind::Backlash, 1, 0.005));
  const std::vector<double> values = values_of(effects);

  core::ProtocolOptions protocol;
  protocol.steps_per_phase = 8;
  protocol.move_s = 0.8;
  protocol.settle_s = 0.4;
  protocol.dwell_s = 1.0;
  protocol.phase_change_s = 3.0;
  protocol.two_way = true;
  const std::vector<core::ScheduledPosition> schedule = core::build_schedule(protocol);

  ai::SimulatedGimbalOptions options;
  options.move_s = protocol.move_s;
  options.settle_s = protocol.settle_s;
  options.phase_change_s = protocol.phase_change_s;
  options.ringing_rad = 0.0;
  options.effects = effects;
  ai::SimulatedGimbalDriver driver(options);

  int compared = 0, compared_moving = 0;
  for (std::size_t i = 0; i < schedule.size(); ++i) {
    const core::ScheduledPosition& p = schedule[i];
    driver.move_to(ai::target_of(p), p.move_start_s);
    EXPECT_FALSE(driver.settled(p.settled_s - 1e-6)) << "position " << i;
    ASSERT_TRUE(driver.settled(p.settled_s + 1e-9)) << "position " << i;
    EXPECT_NEAR(driver.settled_at(p.settled_s + 0.05), p.settled_s, 1e-9) << "position " << i;
    const bool remount = i == 0 || schedule[i - 1].phase != p.phase;
    const double from = remount ? p.settled_s : p.move_start_s;
    for (double t = from; t < p.dwell_end_s; t += 0.01) {
      const core::GimbalPose pose = core::gimbal_pose_at(schedule, t);
      const core::DwellGeometry geom = core::geometry_of(pose, t);
      const Eigen::Vector3d expected = core::specific_force(effects, values.data(), geom, kG);
      const Eigen::Vector3d f = force_in_dut(driver.orientation(t).world_dut());
      ASSERT_NEAR((f - expected).norm(), 0.0, 1e-10)
          << "position " << i << " t " << t << " (moving: " << !pose.at_rest << ")";
      ++compared;
      if (!pose.at_rest && pose.angle_rad != p.angle_rad) ++compared_moving;
    }
  }
  EXPECT_GT(compared_moving, 1000);  // the moves themselves were compared, not just the dwells
  EXPECT_GT(compared, compared_moving);
}

// An abort mid-move freezes the gimbal where it is; the next move in the phase starts there.
TEST(GimbalTf, StopMidMoveThenResumeIsContinuous) {
  ai::SimulatedGimbalOptions options;
  options.move_s = 1.0;
  options.settle_s = 0.5;
  ai::SimulatedGimbalDriver driver(options);
  ai::GimbalTarget target;
  target.phase = core::Phase::X;
  target.steps = 4;
  driver.move_to(target, -10.0);  // mount at step 0
  target.step = 1;
  target.angle_rad = core::kPi / 2;
  driver.move_to(target, 0.0);
  const Eigen::Matrix3d at_stop = driver.orientation(0.6).world_dut();
  driver.stop(0.6);
  EXPECT_TRUE(driver.settled(0.6));
  EXPECT_TRUE(driver.orientation(5.0).world_dut().isApprox(at_stop, 1e-12));
  driver.move_to(target, 5.0);
  EXPECT_TRUE(driver.orientation(5.0).world_dut().isApprox(at_stop, 1e-12));
  EXPECT_FALSE(driver.settled(6.4));
  ASSERT_TRUE(driver.settled(6.5));
  const Eigen::Vector3d f = force_in_dut(driver.orientation(6.5).world_dut());
  EXPECT_NEAR((f - kG * core::in_plane_direction(core::Phase::X, core::kPi / 2)).norm(), 0.0,
              1e-12);
}

TEST(GimbalTf, RejectsSensorEffects) {
  ai::SimulatedGimbalOptions options;
  options.effects.push_back(effect(core::EffectKind::QuadraticNonlinearity, 0, 1e-4));
  EXPECT_THROW(options.validate(), std::invalid_argument);
  options.effects.clear();
  options.move_s = -1.0;
  EXPECT_THROW(options.validate(), std::invalid_argument);
}

TEST(SimulatedAccelerometer, ReproducesPredictOutputs) {
  ai::SimulatedAccelerometerOptions options;
  options.truth.S << 1.012, 0.004, -0.003, -0.005, 0.987, 0.006, 0.002, -0.008, 1.003;
  options.truth.O << 0.05, -0.03, 0.08;
  options.truth.effects.push_back(effect(core::EffectKind::QuadraticNonlinearity, 0, 2e-4));
  options.truth.effects.push_back(effect(core::EffectKind::CubicNonlinearity, 2, -3e-6));
  options.truth.effects.push_back(effect(core::EffectKind::OffsetDrift, 1, 1e-4));
  options.noise_density = 0.0;
  options.rate_hz = 100.0;
  options.local_gravity = kG;

  for (core::Phase p : core::kPhases) {
    for (int n = 0; n < 8; ++n) {
      const double a = core::step_angle(n, 8);
      const Eigen::Matrix3d R = through_tf(ai::gimbal_transforms(p, a, 0.0), 1.0);
      ai::SimulatedAccelerometer sensor(options, [&R](double, Eigen::Matrix3d* out) {
        *out = R;
        return ai::OrientationStatus::Available;
      });
      sensor.set_time_origin(100.0);
      std::vector<core::ImuSample> samples;
      sensor.poll(150.0, &samples);  // first poll starts the sample clock
      sensor.poll(150.05, &samples);
      ASSERT_GE(samples.size(), 5u);
      core::Device device = options.truth;
      for (const core::ImuSample& s : samples) {
        core::DwellGeometry geom;
        geom.phase = p;
        geom.angle_rad = a;
        geom.time_s = s.stamp_s - 100.0;
        const Eigen::Vector3d expected = core::predict_outputs(device, geom, kG);
        EXPECT_NEAR((s.outputs - expected).norm(), 0.0, 1e-10)
            << "phase " << core::phase_name(p) << " angle " << a;
      }
    }
  }
}

TEST(SimulatedAccelerometer, StampsOnGridWithLagNoiseAndQuantization) {
  ai::SimulatedAccelerometerOptions options;
  options.truth.effects.push_back(effect(core::EffectKind::TimingLag, 0, 0.005));
  options.rate_hz = 200.0;
  options.noise_density = 1e-3;
  options.quantization = 0.01;
  int asked_future = 0;
  ai::SimulatedAccelerometer sensor(options, [&](double t, Eigen::Matrix3d* out) {
    if (t > 10.5) {
      ++asked_future;
      return ai::OrientationStatus::NotYet;  // tf not there yet
    }
    *out = Eigen::Matrix3d::Identity();
    return ai::OrientationStatus::Available;
  });
  std::vector<core::ImuSample> samples;
  sensor.poll(10.0, &samples);
  sensor.poll(11.0, &samples);
  ASSERT_EQ(samples.size(), 101u);  // 10.000 .. 10.500, waits at 10.505
  EXPECT_GE(asked_future, 1);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    EXPECT_NEAR(samples[i].stamp_s, 10.0 + 0.005 * i + 0.005, 1e-9);
    for (int k = 0; k < 3; ++k) {
      const double q = samples[i].outputs(k) / 0.01;
      EXPECT_NEAR(q, std::round(q), 1e-6);
    }
    EXPECT_NEAR(samples[i].outputs(2), kG, 0.1);
  }
  EXPECT_NEAR(options.noise_std(), 1e-3 * std::sqrt(100.0), 1e-15);
}

TEST(SimulatedAccelerometer, RejectsGimbalEffects) {
  ai::SimulatedAccelerometerOptions options;
  options.truth.effects.push_back(effect(core::EffectKind::AngleOffset, 0, 1e-3));
  EXPECT_THROW(options.validate(), std::invalid_argument);
  options.truth.effects.clear();
  options.truth.S.setZero();
  EXPECT_THROW(options.validate(), std::invalid_argument);
}
