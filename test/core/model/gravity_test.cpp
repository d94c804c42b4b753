#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "accel_intrinsics/core/model/constants.h"

using accel_intrinsics::core::normal_gravity;

// Published WGS 84 normal gravity on the ellipsoid (NIMA TR8350.2, table 3.4):
// gamma_e = 9.7803253359, gamma_p = 9.8321849378 m/s^2.
TEST(NormalGravity, MatchesPublishedValuesOnTheEllipsoid) {
  EXPECT_NEAR(normal_gravity(0.0), 9.7803253359, 1e-10);
  EXPECT_NEAR(normal_gravity(90.0), 9.8321849378, 1e-9);
  EXPECT_NEAR(normal_gravity(-90.0), 9.8321849378, 1e-9);
  // 45 deg: the International Gravity Formula 1980 series gives 9.806199203 m/s^2; its
  // truncation error is about 1e-6 m/s^2, so the closed form must agree to that level.
  EXPECT_NEAR(normal_gravity(45.0), 9.806199203, 2e-6);
  EXPECT_NEAR(normal_gravity(45.0), normal_gravity(-45.0), 1e-15);
}

TEST(NormalGravity, FreeAirGradientIsAbout3086MicroGalPerMetre) {
  const double dg = normal_gravity(45.0, 1000.0) - normal_gravity(45.0, 0.0);
  EXPECT_NEAR(dg / 1000.0, -3.086e-6, 0.01e-6);
}

TEST(NormalGravity, RejectsBadLatitude) {
  EXPECT_THROW(normal_gravity(91.0), std::invalid_argument);
  EXPECT_THROW(normal_gravity(std::nan("")), std::invalid_argument);
}

// South of the south pole is as impossible as north of the north pole: both ends are checked.
TEST(NormalGravity, RejectsLatitudeSouthOfTheSouthPole) {
  EXPECT_THROW(normal_gravity(-100.0), std::invalid_argument);
  EXPECT_THROW(normal_gravity(-90.001), std::invalid_argument);
  EXPECT_NO_THROW(normal_gravity(-90.0));
}
