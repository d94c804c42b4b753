// TumbleSession (tumble_session.h): the samples it refuses are counted.
#include "accel_intrinsics/core/run/tumble_session.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>

namespace accel_intrinsics {
namespace core {
namespace {

// A sample whose stamp goes back, or whose outputs are not finite, is dropped and counted: the
// count is what tells the person that the stream is out of order (and reset() clears it).
TEST(TumbleSessionInput, SamplesGoingBackOrNotFiniteAreDroppedAndCounted) {
  TumbleSession session{TumbleSessionOptions()};
  const Eigen::Vector3d still(0.0, 0.0, kStandardGravity);
  EXPECT_FALSE(session.add_sample(10.0, still));
  EXPECT_FALSE(session.add_sample(10.01, still));
  EXPECT_EQ(session.dropped_out_of_order(), 0u);
  EXPECT_FALSE(session.add_sample(10.0, still));  // back in time
  EXPECT_EQ(session.dropped_out_of_order(), 1u);
  EXPECT_FALSE(session.add_sample(10.02, Eigen::Vector3d(0.0, NAN, kStandardGravity)));
  EXPECT_EQ(session.dropped_out_of_order(), 2u);
  session.reset();
  EXPECT_EQ(session.dropped_out_of_order(), 0u);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
