// Private to the io library: kalibr's accelerometer noise keys (its IMU configuration), written
// here only. The calibration export (kalibr_imu.yaml, exporters.cpp) and noise_report's kalibr
// file (noise_document.cpp) both call it, so the two files cannot disagree on a key or a unit.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace accel_intrinsics {
namespace io {
namespace detail {

// Shortest text that reads back to the same double (no "-0").
std::string round_trip_text(double v);

struct KalibrNoiseKeys {
  // "update_rate", "accelerometer_noise_density", "accelerometer_random_walk", one line each,
  // each prefixed by the indent; a key without a finite value is left out.
  std::string lines;
  // The keys left out, by name.
  std::vector<std::string> missing;
};

// density: continuous-time white-noise density per axis, (m/s^2)/sqrt(Hz); walk: random walk per
// axis, (m/s^3)/sqrt(Hz). kalibr takes one value for the three axes: the largest finite one of
// u, v, w (NaN marks an axis without a figure).
KalibrNoiseKeys kalibr_noise_keys(const Eigen::Vector3d& density, const Eigen::Vector3d& walk,
                                  double rate_hz, const std::string& indent);

}  // namespace detail
}  // namespace io
}  // namespace accel_intrinsics
