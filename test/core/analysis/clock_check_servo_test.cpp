// ClockCheck with moves whose motion fills only part of MOVING -> SETTLED (docs/design.md
// section 15). The streams are written here from the equations, not by the package's simulator:
// a position servo (second-order, wn 20 rad/s, zeta 0.5: 16 % overshoot, as the ros_joint stand's
// joint controller) that reports SETTLED after the joint has stayed within 0.05 deg of the target
// for 0.3 s, and an IMU that reads gravity through eq. (4) with its own scale factors,
// misalignments, biases and noise. Correct clocks pass; an IMU shifted by 0.5 s or 5 s is named
// with its offset within 0.1 s (the onset's tolerance: the motion's start is found to a bin or two
// plus the smoothing of the motion signal). An operator who turns a head after a random delay
// (onsets scattered over seconds) passes too.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include "accel_intrinsics/core/analysis/clock_check.h"

namespace accel_intrinsics {
namespace core {
namespace {

constexpr double kPiHere = 3.14159265358979323846;
constexpr double kG = 9.80665;

// The joint's remaining error after a step of `delta` commanded at t = 0 (underdamped
// second-order step response).
double servo_error(double delta, double t) {
  const double wn = 20.0, zeta = 0.5;
  const double wd = wn * std::sqrt(1.0 - zeta * zeta);
  return delta * std::exp(-zeta * wn * t) *
         (std::cos(wd * t) + zeta / std::sqrt(1.0 - zeta * zeta) * std::sin(wd * t));
}

// A stand: per phase 12 steps of 30 deg; the first step of a phase is a remount (the pose jumps
// in the middle of a 4 s move). `onset_s(move)` delays each step's motion after MOVING (0 for the
// servo); the gimbal reports SETTLED once the joint stayed within tolerance for settle_s.
struct Stand {
  std::vector<GimbalEvent> commands;
  std::vector<double> change_s;    // per segment: when the joint starts toward `target`
  std::vector<double> from_rad;    // angle before
  std::vector<double> target_rad;  // angle after
  std::vector<Phase> phase;        // the phase of the segment
  std::vector<bool> jump;          // a remount: the pose jumps at change_s
  double end_s = 0.0;
};

Stand make_stand(const std::function<double(std::size_t)>& onset_s) {
  const double tolerance = 0.05 * kPiHere / 180.0, settle_s = 0.3, dwell_s = 0.8;
  Stand s;
  double t = 0.5;
  std::size_t move = 0;
  const Phase phases[] = {Phase::X, Phase::Y, Phase::Z};
  for (Phase p : phases) {
    double angle = 0.0;
    for (std::uint32_t step = 0; step < 12; ++step) {
      const double target = step * 30.0 * kPiHere / 180.0;
      GimbalEvent e;
      e.phase = p;
      e.step = step;
      e.steps = 12;
      e.angle_rad = target;
      e.stamp_s = t;
      e.state = GimbalState::Moving;
      s.commands.push_back(e);
      double settled = 0.0;
      if (step == 0) {
        s.change_s.push_back(t + 2.0);
        s.jump.push_back(true);
        settled = t + 4.0;
      } else {
        const double start = t + onset_s(move++);
        s.change_s.push_back(start);
        s.jump.push_back(false);
        // Last instant outside the tolerance, to 1 ms.
        double out = 0.0;
        for (double u = 0.0; u < 3.0; u += 1e-3) {
          if (std::abs(servo_error(target - angle, u)) > tolerance) out = u;
        }
        settled = start + out + settle_s;
      }
      s.from_rad.push_back(angle);
      s.target_rad.push_back(target);
      s.phase.push_back(p);
      e.stamp_s = settled;
      e.state = GimbalState::Settled;
      s.commands.push_back(e);
      angle = target;
      t = settled + dwell_s;
    }
  }
  GimbalEvent done = s.commands.back();
  done.stamp_s = t;
  done.state = GimbalState::Done;
  s.commands.push_back(done);
  s.end_s = t;
  return s;
}

// Gravity in the device frame at angle a of a phase (eq. 4).
Eigen::Vector3d gravity(Phase p, double a) {
  switch (p) {
    case Phase::X: return kG * Eigen::Vector3d(0.0, std::sin(a), std::cos(a));
    case Phase::Y: return kG * Eigen::Vector3d(std::sin(a), 0.0, std::cos(a));
    default: return kG * Eigen::Vector3d(std::sin(a), std::cos(a), 0.0);
  }
}

// The IMU, stamped `offset_s` late, 200 Hz, its own device.
ClockCheckResult check(const Stand& s, double offset_s, std::uint64_t seed) {
  Eigen::Matrix3d k;
  k << 1.012, 0.004, -0.003, 0.002, 0.991, 0.005, -0.004, 0.001, 1.021;
  const Eigen::Vector3d bias(0.05, -0.08, 0.12);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.01);
  ClockCheck check;
  for (const GimbalEvent& c : s.commands) check.add_command(c);
  std::size_t seg = 0;
  for (double t = 0.0; t < s.end_s; t += 1.0 / 200.0) {
    while (seg + 1 < s.change_s.size() && t >= s.change_s[seg + 1]) ++seg;
    double a = s.from_rad[seg];
    Phase p = s.phase[seg];
    if (t >= s.change_s[seg]) {
      a = s.jump[seg] ? s.target_rad[seg]
                      : s.target_rad[seg] -
                            servo_error(s.target_rad[seg] - s.from_rad[seg], t - s.change_s[seg]);
    } else if (s.jump[seg] && seg > 0) {
      p = s.phase[seg - 1];  // still mounted for the previous phase
    }
    ImuSample sample;
    sample.stamp_s = t + offset_s;
    sample.outputs = k * gravity(p, a) + bias;
    for (int i = 0; i < 3; ++i) sample.outputs(i) += noise(rng);
    check.add_sample(sample);
  }
  return check.result();
}

TEST(ClockCheckServo, OvershootingServoWithCorrectClocksPasses) {
  const Stand s = make_stand([](std::size_t) { return 0.0; });
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const ClockCheckResult r = check(s, 0.0, seed);
    ASSERT_TRUE(r.checked) << r.not_checked_why;
    EXPECT_FALSE(r.motion_fills_moves) << "end gap " << r.end_gap_s;
    EXPECT_FALSE(r.offset_found) << r.message("imu_time_offset_s");
    EXPECT_LT(std::abs(r.best_shift_s), 0.1) << "start gap " << r.start_gap_s;
  }
}

TEST(ClockCheckServo, OvershootingServoWithShiftedImuIsNamed) {
  const Stand s = make_stand([](std::size_t) { return 0.0; });
  const double offsets[] = {0.5, -0.5, 5.0, -5.0};
  std::uint64_t seed = 10;
  for (double offset : offsets) {
    const ClockCheckResult r = check(s, offset, ++seed);
    ASSERT_TRUE(r.checked) << r.not_checked_why;
    EXPECT_TRUE(r.offset_found) << "offset " << offset << ": best shift " << r.best_shift_s
                                << " start gap " << r.start_gap_s << " end gap " << r.end_gap_s;
    EXPECT_NEAR(r.offset_s, offset, 0.1);
    const std::string m = r.message("imu_time_offset_s");
    EXPECT_NE(m.find(offset > 0.0 ? "later than the gimbal's" : "earlier than the gimbal's"),
              std::string::npos)
        << m;
  }
}

TEST(ClockCheckServo, HeadTurnedByHandAfterScatteredDelaysPasses) {
  // The operator starts each turn 0.3 to 3 s after MOVING: all motion inside the moves, onsets
  // scattered; no clock is named.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> delay(0.3, 3.0);
  std::vector<double> delays;
  for (int i = 0; i < 40; ++i) delays.push_back(delay(rng));
  const Stand s = make_stand([&](std::size_t move) { return delays[move % delays.size()]; });
  const ClockCheckResult r = check(s, 0.0, 3);
  ASSERT_TRUE(r.checked) << r.not_checked_why;
  EXPECT_FALSE(r.offset_found) << r.message("imu_time_offset_s");
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
