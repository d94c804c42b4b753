// Rest detection's quiet level (rest_detection.h quiet_std_of), on streams written here sample by
// sample: a quantized output whose blocks read constant is floored by its output step.
#include "accel_intrinsics/core/dwells/rest_detection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace accel_intrinsics {
namespace core {
namespace {

TEST(RestDetection, TheQuietStdOfAQuantizedStreamIsFlooredByItsFirstStep) {
  // A still DUT read through an output quantized to 0.01 m/s^2: x reads 0.00 once, then 0.01
  // for good; y and z never change. Every block but the first reads constant (std 0), so the
  // quiet std of x rests on the one output step, seen between the first two samples: half a step
  // (rest_detection.cpp, floored()); y and z show no step and stay at 0.
  const double step = 0.01;
  std::vector<ImuSample> samples(200);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    samples[i].stamp_s = 0.01 * static_cast<double>(i);
    samples[i].outputs = Eigen::Vector3d(i == 0 ? 0.0 : step, 0.0, 9.81);
  }
  const Eigen::Vector3d quiet = quiet_std_of(samples, 10, 0.5);
  EXPECT_NEAR(quiet.x(), 0.5 * step, 1e-12);
  EXPECT_EQ(quiet.y(), 0.0);
  EXPECT_EQ(quiet.z(), 0.0);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
