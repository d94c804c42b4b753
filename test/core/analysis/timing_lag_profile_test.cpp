// Issue 15 item 4: the timing-lag estimator on a gimbal that does not move as its motion model
// says. The raw streams are made here, not with core::gimbal_pose_at/move_fraction: the timeline
// of build_schedule(), the angle along each move from a profile written in this file (raised
// cosine, trapezoidal velocity, or raised cosine followed by a damped oscillation), the outputs
// R = S g f(angle) + O (eq. 4 written out) plus white noise, stamped `lag` late.
//  - The modelled profile (written independently): the lag is recovered within 4 std at a
//    reduced chi-square near 1; so with the mild ringing of the shipped simulated gimbal
//    (config/simulated_gimbal.yaml: 2 mrad at 4 Hz).
//  - Trapezoidal velocity: unbiased (symmetric), the mismatch visible in the reduced chi-square.
//  - Strong ringing after SETTLED (20 mrad): a late bias of about 3 std, documented in
//    raw_stream_analysis.h, the mismatch visible in the reduced chi-square. (A gate on that
//    chi-square was tried and dropped: on lag-free data with short dwells the base fit's own error
//    lifts it to 1.07, above a 99.9 % chi-square bound, so it would withhold honest estimates.)
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "../../support/written_runs.h"
#include "accel_intrinsics/core/analysis/raw_stream_analysis.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

enum class Profile { RaisedCosine, Trapezoid };

struct Motion {
  Profile profile = Profile::RaisedCosine;
  double ringing_rad = 0.0;  // damped oscillation after SETTLED: A exp(-dt / tau) sin(2 pi f dt)
  double ringing_hz = 4.0;
  double ringing_tau_s = 0.1;
};

// Fraction of the step done at u = (t - MOVING) / (SETTLED - MOVING) in [0, 1].
double fraction(Profile profile, double u) {
  if (profile == Profile::RaisedCosine) return 0.5 * (1.0 - std::cos(3.14159265358979323846 * u));
  // Trapezoidal velocity: accelerate for a third, cruise at 1.5 x the mean speed, decelerate.
  if (u < 1.0 / 3.0) return 2.25 * u * u;
  if (u < 2.0 / 3.0) return 0.25 + 1.5 * (u - 1.0 / 3.0);
  return 1.0 - 2.25 * (1.0 - u) * (1.0 - u);
}

using written_runs::unit_force;

struct Streams {
  std::vector<GimbalEvent> commands;
  std::vector<ImuSample> samples;
  double sigma = 0.0;
};

Streams make_streams(const Motion& motion, double lag_s, std::uint64_t seed) {
  ProtocolOptions protocol;
  protocol.steps_per_phase = 12;
  protocol.dwell_s = 1.5;
  const std::vector<ScheduledPosition> schedule = build_schedule(protocol);
  Eigen::Matrix3d S;
  S << 1.02, 0.011, -0.014, -0.008, 0.991, 0.017, 0.012, -0.006, 1.007;
  const Eigen::Vector3d O(0.08, -0.15, 0.11);
  const double g = kStandardGravity, rate = 100.0;
  Streams out;
  out.sigma = 300e-6 * kStandardGravity * std::sqrt(rate / 2.0);
  for (const ScheduledPosition& p : schedule) {
    GimbalEvent e;
    e.phase = p.phase;
    e.step = p.step;
    e.steps = p.steps;
    e.angle_rad = p.angle_rad;
    e.stamp_s = p.move_start_s;
    e.state = GimbalState::Moving;
    out.commands.push_back(e);
    e.stamp_s = p.settled_s;
    e.state = GimbalState::Settled;
    out.commands.push_back(e);
  }
  GimbalEvent done = out.commands.back();
  done.stamp_s = schedule.back().dwell_end_s;
  done.state = GimbalState::Done;
  out.commands.push_back(done);

  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, out.sigma);
  std::size_t i = 0;
  for (int k = 0; k / rate <= schedule.back().dwell_end_s; ++k) {
    const double t = k / rate;
    while (i + 1 < schedule.size() && schedule[i + 1].move_start_s <= t) ++i;
    const ScheduledPosition& p = schedule[i];
    double angle = p.angle_rad;
    const bool in_phase = i > 0 && schedule[i - 1].phase == p.phase;
    if (in_phase && t < p.settled_s) {
      const double u = (t - p.move_start_s) / (p.settled_s - p.move_start_s);
      angle = schedule[i - 1].angle_rad +
              (p.angle_rad - schedule[i - 1].angle_rad) * fraction(motion.profile, u);
    }
    if (in_phase && t >= p.settled_s && motion.ringing_rad != 0.0) {
      const double dt = t - p.settled_s;
      angle += motion.ringing_rad * std::exp(-dt / motion.ringing_tau_s) *
               std::sin(2.0 * 3.14159265358979323846 * motion.ringing_hz * dt);
    }
    ImuSample s;
    s.stamp_s = t + lag_s;
    s.outputs = S * (g * unit_force(p.phase, angle)) + O;
    for (int a = 0; a < 3; ++a) s.outputs(a) += normal(rng);
    out.samples.push_back(s);
  }
  return out;
}

TimingLagEstimate estimate(const Streams& streams) {
  Recording rec{streams.commands, streams.samples};
  DwellAssembler assembler;
  feed_in_stamp_order(rec, &assembler);
  const FitResult base = fit(assembler.table());
  return estimate_timing_lag(streams.commands, streams.samples, assembler.table(), base);
}

constexpr double kLag = 0.010;

TEST(TimingLagProfile, ModelledProfileMadeIndependentlyGivesTheLag) {
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    const TimingLagEstimate est = estimate(make_streams(Motion{}, kLag, seed));
    std::printf("raised cosine: %s (reduced chi2 %.4f)\n", est.message.c_str(), est.reduced_chi2);
    ASSERT_TRUE(est.ok) << est.message;
    EXPECT_LT(std::abs(est.lag_s - kLag), 4.0 * est.std_s) << est.message;
    EXPECT_TRUE(est.detected);
    EXPECT_LT(est.reduced_chi2, 1.05);
  }
}

TEST(TimingLagProfile, MildRingingOfTheShippedSimulatedGimbalStillGivesTheLag) {
  Motion mild;
  mild.ringing_rad = 0.002;
  const TimingLagEstimate est = estimate(make_streams(mild, kLag, 4));
  std::printf("ringing 2 mrad: %s (reduced chi2 %.4f)\n", est.message.c_str(), est.reduced_chi2);
  ASSERT_TRUE(est.ok) << est.message;
  EXPECT_LT(std::abs(est.lag_s - kLag), 4.0 * est.std_s) << est.message;
  EXPECT_LT(est.reduced_chi2, 1.05);
}

// A symmetric profile of another shape: the lag stays unbiased (within 4 of its std, which the
// reduced chi-square inflates); the misfit shows in the reduced chi-square of the move samples.
TEST(TimingLagProfile, TrapezoidalVelocityLeavesTheLagUnbiasedAndShowsInTheChiSquare) {
  Motion trapezoid;
  trapezoid.profile = Profile::Trapezoid;
  for (std::uint64_t seed = 5; seed <= 7; ++seed) {
    const TimingLagEstimate est = estimate(make_streams(trapezoid, kLag, seed));
    std::printf("trapezoid: %s (reduced chi2 %.3f)\n", est.message.c_str(), est.reduced_chi2);
    ASSERT_TRUE(est.ok) << est.message;
    EXPECT_LT(std::abs(est.lag_s - kLag), 4.0 * est.std_s) << est.message;
    EXPECT_GT(est.reduced_chi2, 1.15);
  }
}

// Ringing after SETTLED pulls the lag late: a documented bias (raw_stream_analysis.h) of about 3
// of the (inflated) std per run, measured 0.36 ms at std 0.12 ms for 10 ms; bounded here: the
// mean error of three runs lies between 1 and 6 mean std (a lag as unbiased as the modelled
// profile's, or one lost to the ringing, falls outside), and the reduced chi-square shows it.
TEST(TimingLagProfile, StrongRingingBiasesTheLagLateAndShowsInTheChiSquare) {
  Motion ringing;
  ringing.ringing_rad = 0.02;
  double sum_error = 0.0, sum_std = 0.0;
  for (std::uint64_t seed = 8; seed <= 10; ++seed) {
    const TimingLagEstimate est = estimate(make_streams(ringing, kLag, seed));
    std::printf("ringing 20 mrad: %s (reduced chi2 %.3f)\n", est.message.c_str(), est.reduced_chi2);
    ASSERT_TRUE(est.ok) << est.message;
    EXPECT_GT(est.reduced_chi2, 1.08);
    sum_error += est.lag_s - kLag;
    sum_std += est.std_s;
  }
  const double bias = sum_error / 3.0, std_s = sum_std / 3.0;
  std::printf("mean bias %.3f ms, mean std %.3f ms\n", bias * 1e3, std_s * 1e3);
  EXPECT_GT(bias, 1.0 * std_s);
  EXPECT_LT(bias, 6.0 * std_s);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
