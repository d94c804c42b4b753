// Shared by the serial gimbal rostests (grbl_stand, smc100_one_axis): the emulator's command
// log against the commands the protocol needs, written here from the axis map in the test's
// parameters (not from the driver's code).
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

namespace serial_checks {

inline std::vector<std::string> read_lines(const std::string& path) {
  std::vector<std::string> lines;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

inline std::string fixed4(double v) {
  char b[48];
  std::snprintf(b, sizeof b, "%.4f", v);
  return b;
}

// Stage positions (deg) of the N positions of each phase: alpha_n = 360 n / N.
inline double alpha_deg(int n, int steps) {
  return 360.0 * n / steps;
}

}  // namespace serial_checks
