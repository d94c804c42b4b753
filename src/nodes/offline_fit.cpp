// offline_fit: the command line of the offline tool (include/accel_intrinsics/ros/offline_fit.h).
#include "accel_intrinsics/ros/offline_fit.h"

#include <console_bridge/console.h>

#include <iostream>
#include <string>
#include <vector>

namespace ai = accel_intrinsics;

int main(int argc, char** argv) {
  ai::OfflineFitArguments args;
  int status = 0;
  if (!ai::parse_offline_fit_arguments(std::vector<std::string>(argv + 1, argv + argc), &args,
                                       &status, std::cout, std::cerr))
    return status;
  // rosbag and cpp_common log parse errors through console_bridge; the exception they throw
  // carries the same news and becomes our one line on stderr.
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  return ai::run_offline_fit(args, std::cout, std::cerr);
}
