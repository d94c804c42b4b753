// noise_report: noise figures of a long static recording (docs/design.md section 8).
//
//   rosrun accel_intrinsics noise_report (--bag FILE | --csv SAMPLES.csv) [--imu-topic T]
//       [--json OUT] [--plot OUT.png] [--kalibr OUT.yaml]
//
// SAMPLES.csv: a header line, then t,u,v,w per line (seconds, outputs in m/s^2). A bag: the
// sensor_msgs/Imu messages of the IMU topic (header stamps, linear_acceleration = R_u, R_v, R_w).
// Prints N, B (with its tau) and K per accelerometer with their uncertainties; --json writes
// io::noise_json_text, --kalibr io::kalibr_imu_noise_yaml, --plot a log-log Allan plot with the
// fitted lines (scripts/plot_allan, run by /usr/bin/python3, from the JSON).
#pragma once

#include <Eigen/Core>
#include <iosfwd>
#include <string>
#include <vector>

#include "accel_intrinsics/ros/names.h"

namespace accel_intrinsics {

constexpr char kNoiseReportProgram[] = "noise_report";

struct NoiseReportArguments {
  std::string bag;  // exactly one of bag and csv
  std::string csv;
  std::string imu_topic = names::kImuTopic;
  bool imu_topic_given = false;
  std::string json_out;
  std::string plot_out;
  std::string kalibr_out;
};

// 0 on success; 1 bad input (one line "noise_report: error: ..." on `err`, no file written);
// 2 bad command line.
int run_noise_report(const NoiseReportArguments& args, std::ostream& out, std::ostream& err);

// The samples of a CSV t,u,v,w file; throws std::runtime_error naming the file and line.
void read_samples_csv(const std::string& path, std::vector<double>* stamps,
                      std::vector<Eigen::Vector3d>* outputs);

}  // namespace accel_intrinsics
