// Shared main for the gtest binaries that need no roscore (core, io, drivers and ros_unit tests).
#include <gtest/gtest.h>

#include "support/source_dir.h"

#ifndef ACCEL_SOURCE_DIR
#error "ACCEL_SOURCE_DIR must be defined for test/gtest_main.cpp (see CMakeLists.txt)"
#endif

namespace accel_intrinsics {
namespace test_support {

const std::string& source_dir() {
  static const std::string dir = ACCEL_SOURCE_DIR;
  return dir;
}

}  // namespace test_support
}  // namespace accel_intrinsics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
