// noise_report: the command line (include/accel_intrinsics/ros/noise_report.h).
#include "accel_intrinsics/ros/noise_report.h"

#include <console_bridge/console.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;

int main(int argc, char** argv) {
  CLI::App app{
      "Noise figures of a long static recording: overlapping Allan deviation, white-noise "
      "density N, bias instability B (with its tau) and random walk K per accelerometer."};
  ai::NoiseReportArguments args;
  app.add_option("--bag", args.bag, "recording (rosbag) with sensor_msgs/Imu messages");
  app.add_option("--csv", args.csv, "samples: header t,u,v,w, then seconds and m/s^2");
  auto* topic =
      app.add_option("--imu-topic", args.imu_topic, "IMU topic in the bag")->capture_default_str();
  app.add_option("--json", args.json_out, "write the figures and the Allan curve as JSON");
  app.add_option("--plot", args.plot_out, "write a log-log Allan plot (PNG) with the fitted lines");
  app.add_option("--kalibr", args.kalibr_out,
                 "write kalibr's IMU configuration (accelerometer keys)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << ai::kNoiseReportProgram << ": error: " << ai::as_one_line(e.what())
              << " (see --help)" << std::endl;
    return 2;
  }
  args.imu_topic_given = topic->count() > 0;
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  return ai::run_noise_report(args, std::cout, std::cerr);
}
