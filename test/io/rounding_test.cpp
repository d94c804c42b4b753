// The one rounding of the text reports (io/rounding.h): uncertainty to two significant digits,
// value to the same place (GUM 7.2.6), cases worked by hand.
#include "accel_intrinsics/io/rounding.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace accel_intrinsics {
namespace io {
namespace {

TEST(Rounding, ValueToTheUncertaintysTwoSignificantDigits) {
  EXPECT_EQ(with_uncertainty(414.90812, 0.016437), "414.908 +- 0.016");
  EXPECT_EQ(with_uncertainty(1.0012345678, 0.000123), "1.00123 +- 0.00012");
  EXPECT_EQ(with_uncertainty(-0.0314159, 0.00271), "-0.0314 +- 0.0027");
  EXPECT_EQ(with_uncertainty(89.98765, 0.0115), "89.988 +- 0.012");
  EXPECT_EQ(with_uncertainty(1234.5, 56.7), "1235 +- 57");
  EXPECT_EQ(with_uncertainty(1234.5, 567.0), "1230 +- 570");
}

TEST(Rounding, AnUncertaintyThatRoundsUpToTheNextDecadeKeepsTwoDigits) {
  // 0.0996 -> 0.10 (not 0.100): the place moves with it.
  EXPECT_EQ(with_uncertainty(2.34567, 0.0996), "2.35 +- 0.10");
  EXPECT_EQ(with_uncertainty(2.34567, 0.996), "2.3 +- 1.0");
  EXPECT_EQ(with_uncertainty(2.34567, 0.994), "2.35 +- 0.99");
}

TEST(Rounding, NoNegativeZeroAndNoUncertainty) {
  EXPECT_EQ(with_uncertainty(-0.00004, 0.0012), "0.0000 +- 0.0012");
  const Rounded r = round_to_uncertainty(9.80665432, std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(r.value, "9.806654");
  EXPECT_EQ(r.uncertainty, "n/a");
  EXPECT_EQ(round_to_uncertainty(1.5, 0.0).uncertainty, "n/a");
  EXPECT_EQ(round_to_uncertainty(std::nan(""), 0.1).value, "n/a");
}

TEST(Rounding, TwoSignificantDigits) {
  EXPECT_EQ(two_significant(0.053123), "0.053");
  EXPECT_EQ(two_significant(0.92771), "0.93");
  EXPECT_EQ(two_significant(52.3), "52");
  EXPECT_EQ(two_significant(1234.0), "1200");
  EXPECT_EQ(two_significant(5.2345e-5), "5.2e-05");
  EXPECT_EQ(two_significant(0.0), "0");
}

TEST(Rounding, TwoSignificantDigitsKeepATrailingZeroJustAboveOneThousandth) {
  // Fixed notation from 1e-3 on shows both digits, the zero too ("0.001" would show one).
  EXPECT_EQ(two_significant(0.0010), "0.0010");
  EXPECT_EQ(two_significant(0.001996), "0.0020");
  EXPECT_EQ(two_significant(-0.0012), "-0.0012");
}

}  // namespace
}  // namespace io
}  // namespace accel_intrinsics
