// The mount check's judgement (docs/design.md section 15; issue 33 item 3) on six pose means
// written here from docs/design.md section 1 (R = S f + O at alpha = 0 and 90 deg of every phase),
// with this test's own device, offsets and 1 s of noise at 100 Hz.
#include "accel_intrinsics/core/analysis/mount_check.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace accel_intrinsics {
namespace core {
namespace {

constexpr double kG = 9.80665;
constexpr double kHalfPi = 1.57079632679489661923;

Eigen::Vector3d eq4(int phase, double a) {
  switch (phase) {
    case 0: return {0.0, std::sin(a), std::cos(a)};
    case 1: return {std::sin(a), 0.0, std::cos(a)};
    default: return {std::sin(a), std::cos(a), 0.0};
  }
}

enum class Stand {
  Correct,
  FlipX,
  FlipZ,
  SwapYZ,
  ZeroOffsetX,
  InG,
  InCounts,
  Motionless,
  Silent,
  SilentAtZ90
};

std::vector<PoseMean> visit(Stand stand, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Eigen::Matrix3d S;
  S << 1.012, 0.004, -0.003, -0.005, 0.987, 0.006, 0.002, -0.008, 1.003;
  Eigen::Vector3d O(0.25, -0.3, 0.4);
  double unit = 1.0;
  if (stand == Stand::InG) unit = 1.0 / kG;
  if (stand == Stand::InCounts) unit = 4096.0 / kG;
  std::vector<PoseMean> poses;
  for (int p = 0; p < 3; ++p) {
    for (double alpha : {0.0, kHalfPi}) {
      int phase = p;
      double a = alpha;
      if ((stand == Stand::FlipX && p == 0) || (stand == Stand::FlipZ && p == 2)) a = -alpha;
      if (stand == Stand::SwapYZ && p > 0) phase = 3 - p;
      if (stand == Stand::ZeroOffsetX && p == 0) a = alpha + 2.0 * kHalfPi;  // zero_deg 180 off
      Eigen::Vector3d f = kG * eq4(phase, a);
      if (stand == Stand::Motionless) f = Eigen::Vector3d(0.0, 0.0, kG);
      PoseMean pose;
      pose.phase = static_cast<Phase>(p);
      pose.angle_rad = alpha;
      pose.n = 100;
      if (stand == Stand::Silent || (stand == Stand::SilentAtZ90 && p == 2 && alpha > 0.0))
        pose.n = 0;
      const Eigen::Vector3d noise(gauss(rng), gauss(rng), gauss(rng));
      pose.mean = pose.n == 0 ? Eigen::Vector3d::Zero()
                              : Eigen::Vector3d(unit * (S * f + O + 0.003 * noise));
      poses.push_back(pose);
    }
  }
  return poses;
}

std::vector<std::string> labels(const MountCheck& check) {
  std::vector<std::string> out;
  for (const SetupMistake& m : check.mistakes) out.push_back(m.label());
  return out;
}

TEST(MountCheck, CorrectMountPasses) {
  for (std::uint64_t seed = 1; seed <= 50; ++seed) {
    const MountCheck c = check_mount(visit(Stand::Correct, seed));
    EXPECT_TRUE(c.correct()) << (c.mistakes.empty() ? "" : c.mistakes.front().text());
  }
}

TEST(MountCheck, EachMistakeNamedWithItsFix) {
  struct Case {
    Stand stand;
    std::vector<std::string> labels;
    const char* fix_word;
  };
  const Case cases[] = {
      {Stand::FlipX, {"axis_sign[x]"}, "phases.x.sign"},
      {Stand::FlipZ, {"axis_sign[z]"}, "phases.z.sign"},
      {Stand::SwapYZ, {"axes_swapped[y]", "axes_swapped[z]"}, "swap the two entries"},
      {Stand::ZeroOffsetX, {"zero_offset[x]"}, "phases.x.zero_deg"},
      {Stand::InG, {"output_unit"}, "output_unit:=g"},
      {Stand::InCounts, {"output_unit"}, "output_unit:=counts"},
      {Stand::Motionless, {"imu_motionless"}, "driver:="},
      {Stand::Silent, {"imu_silent"}, "imu_topic"},
      {Stand::SilentAtZ90, {"imu_silent"}, "rostopic hz"},
  };
  for (const Case& c : cases) {
    const MountCheck check = check_mount(visit(c.stand, 7));
    ASSERT_EQ(labels(check), c.labels) << static_cast<int>(c.stand);
    EXPECT_NE(check.mistakes.front().fix.find(c.fix_word), std::string::npos)
        << check.mistakes.front().text();
  }
}

// A mistake in g units is still read geometrically (directions have no unit).
TEST(MountCheck, UnitAndSignTogether) {
  std::vector<PoseMean> poses = visit(Stand::FlipZ, 3);
  for (PoseMean& p : poses) p.mean /= kG;
  const std::vector<std::string> expected = {"output_unit", "axis_sign[z]"};
  EXPECT_EQ(labels(check_mount(poses)), expected);
}

TEST(MountCheck, MissingPoseCannotBeJudged) {
  std::vector<PoseMean> poses = visit(Stand::Correct, 4);
  poses.pop_back();
  EXPECT_THROW(check_mount(poses), std::invalid_argument);
  EXPECT_EQ(mount_check_poses().size(), 6u);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
