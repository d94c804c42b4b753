// core::fixed, the one number formatter of messages and reports.
#include "accel_intrinsics/core/model/text_format.h"

#include <gtest/gtest.h>

#include <cmath>

namespace accel_intrinsics {
namespace core {
namespace {

TEST(TextFormat, RoundsToTheDecimalsAsked) {
  EXPECT_EQ(fixed(2.345, 1), "2.3");
  EXPECT_EQ(fixed(2.36, 1), "2.4");
  EXPECT_EQ(fixed(-1.0 / 3.0, 3), "-0.333");
  EXPECT_EQ(fixed(7.0, 0), "7");
  EXPECT_EQ(fixed(12.5, 2), "12.50");
}

TEST(TextFormat, NegativeDecimalsRoundToTensAndHundreds) {
  EXPECT_EQ(fixed(1234.0, -2), "1200");
  EXPECT_EQ(fixed(1250.0, -2), "1300");
  EXPECT_EQ(fixed(-47.0, -1), "-50");
}

TEST(TextFormat, NoNegativeZero) {
  EXPECT_EQ(fixed(-0.0004, 3), "0.000");
  EXPECT_EQ(fixed(-0.04, 1), "0.0");
  EXPECT_EQ(fixed(-0.0, 2), "0.00");
}

TEST(TextFormat, NonFiniteAndHugeValuesAreReadable) {
  EXPECT_EQ(fixed(std::nan(""), 2), "nan");
  EXPECT_EQ(fixed(HUGE_VAL, 2), "inf");
  EXPECT_EQ(fixed(-HUGE_VAL, 1), "-inf");
  EXPECT_EQ(fixed(1e300, 9).substr(0, 4), "1000");  // value * 1e9 overflows: printed as is
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
