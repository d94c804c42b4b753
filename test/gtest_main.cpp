// Shared main for the gtest binaries that need no roscore (core_tests, ros_unit_tests).
#include <gtest/gtest.h>

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
