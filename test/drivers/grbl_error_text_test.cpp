// grbl_error_text (grbl_driver.h): the text shown with a controller's "error:N" reply.
#include <gtest/gtest.h>

#include <string>

#include "accel_intrinsics/drivers/grbl_driver.h"

namespace accel_intrinsics {
namespace {

// The operator reads the fault by this text: Grbl v1.1's error 8 is the '$' command refused
// outside IDLE (its error table); 7 (an EEPROM read failure) must not be given that text.
TEST(GrblErrorText, CodeEightIsTheDollarCommandOutsideIdle) {
  EXPECT_EQ(grbl_error_text(8), "Grbl '$' command cannot be used unless Grbl is IDLE.");
  EXPECT_EQ(grbl_error_text(7).find("IDLE"), std::string::npos) << grbl_error_text(7);
  EXPECT_EQ(grbl_error_text(9), "G-code locked out during alarm or jog state");
}

}  // namespace
}  // namespace accel_intrinsics
