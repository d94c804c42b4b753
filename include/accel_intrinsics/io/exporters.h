// Exporters: the fitted calibration written for the tools users already run (docs/design.md section
// 7), one writer per format. With a the specific force in the DUT frame and R the raw outputs,
// our model is R = S a + O and a = P (R - O), P = S^-1. Each file says in a comment (imucal: its
// `comment` key) the direction of its matrix, the local g the responsivities refer to, the date
// and the source result; px4 and ardupilot, which hold no axis coupling, also state the largest
// error they leave over all orientations at 1 g (and ExportText::notice repeats it for stderr).
//
//   name       file                                    read by the tool as
//   imu_calib  YAML SM: [9, row-major], bias: [3]      corrected = SM raw - bias  (SM = P, bias = P
//   O)
//              (dpkoch/imu_calib AccelCalib::loadCalib / applyCalib)
//   imucal     JSON K_a, R_a, b_a (+ identity gyro)    acc = R_a^-1 K_a^-1 (raw - b_a)
//              (mad-lab-fau/imucal FerrarisCalibrationInfo, _format_version 2.0.0)
//              K_a = diag(|u|,|v|,|w|), R_a = rows of S normalized, b_a = O
//   kalibr     YAML imu0: {model: scale-misalignment, accelerometers: {M}} + noise keys
//              raw = M a' + b, M lower triangular, a' = Q a (x along u, y in the u-v plane);
//              b (kalibr estimates its own bias) is stated in a comment
//   imu_tk     text: T (3 rows), K (3 rows), B (3 lines), blank lines between, comments after
//              (Kyle-ak/imu_tk CalibratedTriad_::load reads the first 21 numbers)
//              a' = T K (raw - B), T unit upper triangular, a' = Q a
//   px4        QGC parameter file CAL_ACC0_{X,Y,Z}{OFF,SCALE}
//              a = (raw - OFF) * SCALE per axis (PX4 calibration::Accelerometer::Correct)
//   ardupilot  Mission Planner parameter file INS_ACCOFFS_{X,Y,Z}, INS_ACCSCAL_{X,Y,Z}
//              a = SCAL * (raw - OFFS) per axis (AP_InertialSensor_Backend)
#pragma once

#include <Eigen/Core>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {
namespace io {

enum class ExportFormat { ImuCalib, Imucal, Kalibr, ImuTk, Px4, Ardupilot };

const char* export_format_name(ExportFormat format);
// The file name the calibration node gives it in output_dir: imu_calib.yaml, imucal.json,
// kalibr_imu.yaml, imu_tk_acc.calib, px4.params, ardupilot.param.
const char* export_file_name(ExportFormat format);
// "imu_calib, imucal, kalibr, imu_tk, px4, ardupilot"
std::string export_format_list();
// Throws IoError: "unknown export format 'x' (one of: ...)".
ExportFormat parse_export_format(const std::string& name);
// "NAME=FILE" (offline_fit --export); throws IoError naming the argument when malformed.
std::pair<ExportFormat, std::string> parse_export_spec(const std::string& spec);

constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();

// What every exporter needs: the linear calibration and where it came from.
struct CalibrationToExport {
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();  // rows u, v, w
  Eigen::Vector3d O = Eigen::Vector3d::Zero();
  double local_gravity = kUnknown;  // m/s^2, the g the fit used
  std::string model_label;          // e.g. "joint"
  // Fitted terms beyond S and O (e.g. "quadratic_nonlinearity[u]"): no format holds them; every
  // file names them as left out.
  std::vector<std::string> terms_left_out;
  // Noise (docs/design.md section 8), NaN when unknown: white-noise density (m/s^2)/sqrt(Hz) and
  // random walk (m/s^3)/sqrt(Hz) per accelerometer, sample rate.
  Eigen::Vector3d noise_density = Eigen::Vector3d::Constant(kUnknown);
  Eigen::Vector3d random_walk = Eigen::Vector3d::Constant(kUnknown);
  double rate_hz = kUnknown;
  std::string source;  // the result it came from (a path, or "calibration node run ...")
  std::string date;    // ISO 8601 UTC; empty: the time of the export
  // Why the result fails the quality gate (core::Quality::summary); empty when it passes. A
  // failing result is not a calibration: export_text refuses it, whoever asks.
  std::string quality_failure;
};

CalibrationToExport calibration_to_export(const StoredResult& result, const std::string& source);
CalibrationToExport calibration_to_export(const core::FitResult& fit, const std::string& source);
// The certificate with the dwells' white noise.
CalibrationToExport calibration_to_export(const core::CalibrationReport& report,
                                          const std::string& source);

struct ExportText {
  std::string text;
  // px4, ardupilot: the largest error left over all orientations at |a| = g, m/s^2; else NaN.
  double leftover_error = kUnknown;
  // One line for stderr when the format leaves something out (px4/ardupilot: the leftover error;
  // any format: fitted terms left out); empty otherwise.
  std::string notice;
};

// Throws IoError when the calibration cannot be written in the format (singular or non-finite
// S, unknown g) or when the result fails the quality gate.
ExportText export_text(ExportFormat format, const CalibrationToExport& calibration);
// export_text written atomically to `path`; throws IoError naming the path.
ExportText write_export(const std::string& path, ExportFormat format,
                        const CalibrationToExport& calibration);

}  // namespace io
}  // namespace accel_intrinsics
