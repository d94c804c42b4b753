// ClockCheck's share of the IMU motion inside the moves (clock_check.h: explained_at_zero), on a
// stream written here by hand: with one-bin blocks and one sample per bin, the motion at a bin
// boundary is the change of the output between the two bins (summed over the axes), so the share
// is the total variation inside the moves over the total variation of the whole stream.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <vector>

#include "accel_intrinsics/core/analysis/clock_check.h"

namespace accel_intrinsics {
namespace core {
namespace {

constexpr double kBin = 0.01;

GimbalEvent command(double stamp_s, std::uint32_t step, GimbalState state) {
  GimbalEvent e;
  e.stamp_s = stamp_s;
  e.phase = Phase::X;
  e.steps = 4;
  e.step = step;
  e.angle_rad = 0.5 * 3.14159265358979 * step;
  e.state = state;
  return e;
}

// Motion at the stream's very last bin boundary counts in the whole (the share's denominator): a
// DUT knocked as the recording ends is motion outside every move. Four moves of 0.5 s (1 s of rest
// first, dwells of 1 s) turn u from j to j + 1 (total variation 1 each); 1 s after the last one the
// final sample reads u one higher (variation 1 outside the moves): 4 of 5 inside the moves.
TEST(ClockCheckSample, MotionInTheLastBinCountsInTheTotal) {
  ClockCheckOptions options;
  options.bin_s = kBin;
  options.block_s = kBin;  // one-bin blocks: the last boundary's motion is that of the last bin
  ClockCheck check(options);
  const double moves_at[] = {1.0, 2.5, 4.0, 5.5};
  for (std::uint32_t j = 0; j < 4; ++j) {
    check.add_command(command(moves_at[j], j, GimbalState::Moving));
    check.add_command(command(moves_at[j] + 0.5, j, GimbalState::Settled));
  }
  const auto u_at = [&](double t) {
    double u = 0.0;
    for (double start : moves_at) {
      if (t >= start + 0.5) {
        u += 1.0;
      } else if (t > start) {
        u += (t - start) / 0.5;
      }
    }
    return u;
  };
  const int bins = 700;  // to 7.0 s: the last move ends at 6.0 s
  ImuSample first;
  first.stamp_s = 0.0;                              // the origin of the bins
  first.outputs = Eigen::Vector3d(0.0, 2.0, -1.0);  // at rest, like the samples after it
  check.add_sample(first);
  for (int i = 0; i < bins; ++i) {
    ImuSample s;
    s.stamp_s = (i + 0.5) * kBin;  // one sample in the middle of each bin
    s.outputs = Eigen::Vector3d(u_at(s.stamp_s), 2.0, -1.0);
    if (i + 1 == bins) s.outputs(0) += 1.0;  // the knock
    check.add_sample(s);
  }
  const ClockCheckResult r = check.result();
  ASSERT_TRUE(r.checked) << r.not_checked_why;
  EXPECT_NEAR(r.explained_at_zero, 4.0 / 5.0, 1e-6);
  EXPECT_FALSE(r.offset_found) << r.offset_s;
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
