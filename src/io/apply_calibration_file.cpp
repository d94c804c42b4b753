#include "accel_intrinsics/io/apply_calibration_file.h"

#include <yaml-cpp/yaml.h>

#include <Eigen/Dense>
#include <cmath>

#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {
namespace io {

ApplyCalibration read_apply_calibration(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw IoError("cannot read the calibration file '" + path + "'");
  } catch (const YAML::Exception& e) {
    throw IoError("cannot parse the calibration file '" + path + "': " + e.what());
  }
  ApplyCalibration out;
  if (root.IsMap() && root["SM"]) {
    // dpkoch/imu_calib: corrected = SM * raw - bias.
    const YAML::Node sm = root["SM"], bias = root["bias"];
    if (!sm.IsSequence() || sm.size() != 9 || !bias || !bias.IsSequence() || bias.size() != 3) {
      throw IoError("the imu_calib file '" + path + "' needs SM (9 numbers) and bias (3 numbers)");
    }
    Eigen::Vector3d b;
    try {
      for (int i = 0; i < 9; ++i) out.P(i / 3, i % 3) = sm[i].as<double>();
      for (int i = 0; i < 3; ++i) b(i) = bias[i].as<double>();
    } catch (const YAML::Exception&) {
      throw IoError("the imu_calib file '" + path +
                    "' has a value in SM or bias that is not a number");
    }
    const Eigen::FullPivLU<Eigen::Matrix3d> lu(out.P);
    if (!out.P.allFinite() || !b.allFinite() || !lu.isInvertible()) {
      throw IoError("the imu_calib file '" + path + "' has a singular or non-finite SM or bias");
    }
    out.O = lu.solve(b);
    out.kind = "imu_calib";
    return out;
  }
  if (!root.IsMap() || !root["cross_sensitivity"]) {
    throw IoError("'" + path +
                  "' is neither a calibration result (offline_fit JSON, intrinsics.yaml) "
                  "nor an imu_calib file (SM, bias)");
  }
  const StoredResult result = read_result_file(path);
  // P from the vectors (the matrix the fit determined), as the result's cross_sensitivity is.
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(result.S);
  if (!result.S.allFinite() || !result.O.allFinite() || !lu.isInvertible()) {
    throw IoError("the result '" + path + "' has singular or non-finite vectors or offsets");
  }
  out.P = lu.inverse();
  out.O = result.O;
  out.local_gravity = result.local_gravity;
  if (result.noise_density.allFinite() && std::isfinite(result.sample_rate_hz)) {
    out.sample_std = result.noise_density * std::sqrt(result.sample_rate_hz);
  }
  out.kind = "result";
  return out;
}

}  // namespace io
}  // namespace accel_intrinsics
