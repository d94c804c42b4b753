// noise_report's files (docs/design.md section 8): the JSON document, and kalibr's IMU
// configuration (its accelerometer keys).
//
// JSON keys: noise_density {u,v,w} ((m/s^2)/sqrt(Hz), continuous-time white-noise density N,
// read at tau = 1 s), noise_density_std, bias_instability {u,v,w} (B, m/s^2),
// bias_instability_std, bias_instability_tau_s, bias_instability_floor_seen {u,v,w} (false: the
// minimum is at the longest tau, B only an upper bound), random_walk {u,v,w} ((m/s^3)/sqrt(Hz), K,
// read at tau = 3 s), random_walk_std, rate_hz, duration_s, samples, source, conventions (one
// line), and allan {tau_s: [...], adev {u,v,w: [...]}, relative_std: [...]} (the curve;
// scripts/plot_allan draws it).
#pragma once

#include <string>

#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace io {

std::string noise_json_text(const core::StaticRecordNoise& noise, const std::string& source);

// kalibr's IMU configuration (the --imu file of kalibr_calibrate_imu_camera): top-level
// accelerometer_noise_density and accelerometer_random_walk (the largest of u, v, w: kalibr takes
// one value for the three axes) and update_rate, with comments on the conventions and the gyro
// keys it does not know.
std::string kalibr_imu_noise_yaml(const core::StaticRecordNoise& noise, const std::string& source,
                                  const std::string& rostopic);

}  // namespace io
}  // namespace accel_intrinsics
