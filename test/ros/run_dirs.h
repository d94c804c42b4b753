// The calibration node's files are in its run directory (io/run_directory.h,
// docs/design.md section 15): output_dir/<device>/latest is the newest run of the device.
#pragma once

#include <string>

namespace run_dirs {

inline std::string latest(const std::string& output_dir, const std::string& device = "unnamed") {
  return output_dir + "/" + device + "/latest";
}

}  // namespace run_dirs
