// The calibration the apply node uses (docs/design.md section 7): a = P (R - O), read from our
// result files (offline_fit's JSON, the calibration node's intrinsics.yaml: read_result_file) or
// from a dpkoch/imu_calib YAML (SM, bias: corrected = SM raw - bias, so P = SM and O = SM^-1 bias).
#pragma once

#include <Eigen/Core>
#include <limits>
#include <string>

namespace accel_intrinsics {
namespace io {

struct ApplyCalibration {
  Eigen::Matrix3d P = Eigen::Matrix3d::Identity();  // raw -> specific force (DUT frame)
  Eigen::Vector3d O = Eigen::Vector3d::Zero();      // raw offsets, m/s^2
  // Per-sample noise standard deviation of the raw outputs (m/s^2), NaN when the file does not
  // say: noise_density * sqrt(sample_rate_hz) of a result file.
  Eigen::Vector3d sample_std = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  std::string kind;                                                 // "result" or "imu_calib"
  double local_gravity = std::numeric_limits<double>::quiet_NaN();  // result files only
};

// Throws IoError naming the path (unreadable, unparsable, neither kind, singular matrix).
ApplyCalibration read_apply_calibration(const std::string& path);

}  // namespace io
}  // namespace accel_intrinsics
