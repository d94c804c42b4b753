#include "accel_intrinsics/io/exporters.h"

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/fit/quality.h"
#include "accel_intrinsics/core/model/calibration_forms.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "kalibr_noise_keys.h"

namespace accel_intrinsics {
namespace io {
namespace {

struct FormatInfo {
  ExportFormat format;
  const char* name;
  const char* file_name;
};
constexpr FormatInfo kFormats[] = {
    {ExportFormat::ImuCalib, "imu_calib", "imu_calib.yaml"},
    {ExportFormat::Imucal, "imucal", "imucal.json"},
    {ExportFormat::Kalibr, "kalibr", "kalibr_imu.yaml"},
    {ExportFormat::ImuTk, "imu_tk", "imu_tk_acc.calib"},
    {ExportFormat::Px4, "px4", "px4.params"},
    {ExportFormat::Ardupilot, "ardupilot", "ardupilot.param"},
};

std::string num(double v) {
  return detail::round_trip_text(v);
}

std::string short_num(double v, int precision = 4) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.*g", precision, v);
  return buf;
}

std::string list(const double* v, int n) {
  std::string out = "[";
  for (int i = 0; i < n; ++i) out += (i ? ", " : "") + num(v[i]);
  return out + "]";
}

std::string vector_list(const Eigen::Vector3d& v) {
  return list(v.data(), 3);
}

std::string matrix_rows_list(const Eigen::Matrix3d& m) {
  std::string out = "[";
  for (int r = 0; r < 3; ++r) {
    const Eigen::Vector3d row = m.row(r).transpose();
    out += (r ? ", " : "") + vector_list(row);
  }
  return out + "]";
}

std::string now_utc() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

// The statements every file carries, one per line, without comment markers.
std::vector<std::string> provenance(const CalibrationToExport& c, const std::string& date) {
  std::vector<std::string> lines;
  lines.push_back("local gravity g = " + num(c.local_gravity) +
                  " m/s^2: the fit took the specific force as g in each position, so the scale "
                  "of every matrix below is relative to this g");
  lines.push_back("date (UTC): " + date);
  lines.push_back("source result: " + (c.source.empty() ? std::string("(unnamed)") : c.source) +
                  (c.model_label.empty() ? "" : " (model " + c.model_label + ")"));
  lines.push_back("units: raw outputs and specific force in m/s^2");
  if (!c.terms_left_out.empty()) {
    std::string terms;
    for (const std::string& t : c.terms_left_out) terms += (terms.empty() ? "" : ", ") + t;
    lines.push_back("left out (this format holds only the linear model R = S a + O): " + terms);
  }
  return lines;
}

std::string comment_block(const std::vector<std::string>& lines, const char* marker = "# ") {
  std::string out;
  for (const std::string& l : lines) out += marker + l + "\n";
  return out;
}

std::string vector_words(const Eigen::Vector3d& v) {
  return num(v(0)) + " " + num(v(1)) + " " + num(v(2));
}

// ---- one writer per format ----------------------------------------------------------------------

ExportText imu_calib_text(const CalibrationToExport& c, std::vector<std::string> lines) {
  const Eigen::Matrix3d P = c.S.inverse();
  const Eigen::Vector3d bias = P * c.O;
  std::vector<std::string> head = {
      "accel_intrinsics calibration for dpkoch/imu_calib (apply_calib node, param calib_file)",
      "imu_calib applies corrected = SM * raw - bias",
      "direction: SM maps raw outputs to specific force (raw -> DUT frame); SM = P = S^-1, "
      "row-major; bias = P O (in the corrected frame, not the raw offset O = " +
          vector_words(c.O) + ")"};
  head.insert(head.end(), lines.begin(), lines.end());
  Eigen::Matrix<double, 9, 1> sm;
  for (int i = 0; i < 9; ++i) sm(i) = P(i / 3, i % 3);
  ExportText out;
  out.text =
      comment_block(head) + "SM: " + list(sm.data(), 9) + "\nbias: " + vector_list(bias) + "\n";
  return out;
}

ExportText imucal_text(const CalibrationToExport& c, std::vector<std::string> lines) {
  const Eigen::Vector3d norms = c.S.rowwise().norm();
  Eigen::Matrix3d R_a = c.S;
  for (int i = 0; i < 3; ++i) R_a.row(i) /= norms(i);
  std::string comment =
      "accel_intrinsics calibration for mad-lab-fau/imucal (CalibrationInfo.from_json_file). "
      "imucal applies acc = R_a^-1 K_a^-1 (raw - b_a). direction: K_a R_a maps specific force "
      "(DUT frame) to raw outputs (DUT frame -> raw): K_a = diag(|u|,|v|,|w|), R_a = the rows of "
      "S normalized, b_a = O (raw). The gyroscope entries are identity and zero: this file "
      "calibrates the accelerometer only; call calibrate(..., acc_unit='m/s^2', gyr_unit=None) "
      "and the gyroscope passes through unchanged.";
  for (const std::string& l : lines) comment += " " + l + ".";
  auto rows = [](const Eigen::Matrix3d& m) {
    nlohmann::json j = nlohmann::json::array();
    for (int r = 0; r < 3; ++r) j.push_back({m(r, 0), m(r, 1), m(r, 2)});
    return j;
  };
  nlohmann::json j = nlohmann::json::object();
  j["acc_unit"] = "m/s^2";
  j["gyr_unit"] = nullptr;
  j["from_acc_unit"] = "m/s^2";
  j["from_gyr_unit"] = nullptr;
  j["comment"] = comment;
  j["K_a"] = rows(Eigen::Matrix3d(norms.asDiagonal()));
  j["R_a"] = rows(R_a);
  j["b_a"] = {c.O(0), c.O(1), c.O(2)};
  j["K_g"] = rows(Eigen::Matrix3d::Identity());
  j["R_g"] = rows(Eigen::Matrix3d::Identity());
  j["K_ga"] = rows(Eigen::Matrix3d::Zero());
  j["b_g"] = {0.0, 0.0, 0.0};
  j["cal_type"] = "Ferraris";
  j["_format_version"] = "2.0.0";
  ExportText out;
  out.text = j.dump(4) + "\n";
  return out;
}

ExportText kalibr_text(const CalibrationToExport& c, std::vector<std::string> lines) {
  const core::LowerTriangularForm f = core::lower_triangular_form(c.S);
  std::vector<std::string> head = {
      "accel_intrinsics calibration for ethz-asl/kalibr (IMU configuration, "
      "--imu-models scale-misalignment)",
      "kalibr's accelerometer model is raw = M a' + b with M lower triangular",
      "direction: M maps specific force to raw outputs (frame a' -> raw); a' = Q a is the DUT "
      "frame turned so that x lies along u and y in the u-v plane (M M^T = S S^T), with Q = " +
          matrix_rows_list(f.Q) +
          (f.Q.determinant() < 0.0 ? " (a reflection: the triad is left-handed)" : ""),
      "b: kalibr estimates its own bias; the fitted raw offset O is " + vector_words(c.O) +
          " m/s^2",
      "noise: accelerometer_noise_density (m/s^2)/sqrt(Hz) is the continuous-time white-noise "
      "density (per-sample std = density * sqrt(update_rate)); kalibr takes one value for the "
      "three axes: the largest of u, v, w"};
  head.insert(head.end(), lines.begin(), lines.end());
  std::string body =
      "imu0:\n  model: scale-misalignment\n  accelerometers:\n    M: " + matrix_rows_list(f.M) +
      "\n";
  const detail::KalibrNoiseKeys keys =
      detail::kalibr_noise_keys(c.noise_density, c.random_walk, c.rate_hz, "  ");
  body += keys.lines;
  std::string missing_noise;
  for (const std::string& key : keys.missing) {
    if (key == "update_rate") continue;  // a rate is not in every source result
    missing_noise += (missing_noise.empty() ? "" : " or ") + key;
  }
  if (!missing_noise.empty())
    head.push_back("no " + missing_noise + " in the source result: add it from noise_report");
  ExportText out;
  out.text = comment_block(head) + body;
  return out;
}

ExportText imu_tk_text(const CalibrationToExport& c, std::vector<std::string> lines) {
  const core::UpperTriangularInverseForm f = core::upper_triangular_inverse_form(c.S);
  std::ostringstream s;
  auto matrix = [&s](const Eigen::Matrix3d& m) {
    for (int r = 0; r < 3; ++r)
      s << num(m(r, 0)) << " " << num(m(r, 1)) << " " << num(m(r, 2)) << "\n";
    s << "\n";
  };
  matrix(f.T);
  matrix(f.K);
  for (int i = 0; i < 3; ++i) s << num(c.O(i)) << "\n";
  s << "\n";
  std::vector<std::string> tail = {
      "accel_intrinsics calibration for imu_tk (CalibratedTriad::load reads the 21 numbers above "
      "and stops: these comments must stay below them)",
      "imu_tk applies a' = T K (raw - B): T misalignment (unit upper triangular), K scale, B bias",
      "direction: T K maps raw outputs to specific force (raw -> frame a'); a' = Q a, the DUT "
      "frame turned by Q = " +
          matrix_rows_list(f.Q) + "; T K = Q P; B = O (raw)"};
  tail.insert(tail.end(), lines.begin(), lines.end());
  ExportText out;
  out.text = s.str() + comment_block(tail);
  return out;
}

// px4 and ardupilot: a = SCALE (raw - OFF) per axis.
ExportText diagonal_text(ExportFormat format, const CalibrationToExport& c,
                         std::vector<std::string> lines) {
  const core::DiagonalForm f = core::diagonal_form(c.S);
  ExportText out;
  out.leftover_error = f.worst_error_per_g * c.local_gravity;
  const std::string leftover =
      "largest error left over all orientations at 1 g: " + short_num(out.leftover_error) +
      " m/s^2 (this format has no axis coupling: g * ||diag(SCALE) S - I||_2)";
  const bool px4 = format == ExportFormat::Px4;
  out.notice = std::string(export_format_name(format)) + " export: " + leftover;
  std::vector<std::string> head = {
      std::string("accel_intrinsics calibration for ") +
          (px4 ? "PX4 (QGroundControl parameter file; applies a = (raw - CAL_ACC0_xOFF) * "
                 "CAL_ACC0_xSCALE per axis)"
               : "ArduPilot (Mission Planner parameter file; applies a = INS_ACCSCAL_x * (raw - "
                 "INS_ACCOFFS_x) per axis)"),
      "direction: SCALE maps raw outputs to specific force per axis (raw -> DUT frame), "
      "SCALE_i = S_ii / |s_i|^2, OFF = O (raw, m/s^2); the axis coupling of P = S^-1 is dropped",
      leftover,
      px4 ? "set CAL_ACC0_ID to your accelerometer's device id (PX4 ignores a calibration whose "
            "id does not match) and keep CAL_ACC0_ROT as it is"
          : "ArduPilot refuses INS_ACCSCAL outside 0.8..1.2 and INS_ACCOFFS beyond 3.5 m/s^2; "
            "these values assume AHRS_ORIENTATION and the board rotation map DUT x,y,z to the "
            "sensor axes u,v,w"};
  head.insert(head.end(), lines.begin(), lines.end());
  std::ostringstream s;
  if (px4) {
    s << comment_block(head) << "#\n# Vehicle-Id Component-Id Name Value Type\n";
    const char axes[3] = {'X', 'Y', 'Z'};
    for (int i = 0; i < 3; ++i)
      s << "1\t1\tCAL_ACC0_" << axes[i] << "OFF\t" << num(c.O(i)) << "\t9\n";
    for (int i = 0; i < 3; ++i) {
      s << "1\t1\tCAL_ACC0_" << axes[i] << "SCALE\t" << num(f.scale(i)) << "\t9\n";
    }
  } else {
    s << comment_block(head);
    const char axes[3] = {'X', 'Y', 'Z'};
    for (int i = 0; i < 3; ++i) s << "INS_ACCOFFS_" << axes[i] << "," << num(c.O(i)) << "\n";
    for (int i = 0; i < 3; ++i) s << "INS_ACCSCAL_" << axes[i] << "," << num(f.scale(i)) << "\n";
  }
  out.text = s.str();
  return out;
}

std::vector<std::string> terms_of(const std::vector<std::string>& names,
                                  const std::vector<std::string>& targets) {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < names.size(); ++i) out.push_back(names[i] + "[" + targets[i] + "]");
  return out;
}

}  // namespace

const char* export_format_name(ExportFormat format) {
  for (const FormatInfo& f : kFormats) {
    if (f.format == format) return f.name;
  }
  return "?";
}

const char* export_file_name(ExportFormat format) {
  for (const FormatInfo& f : kFormats) {
    if (f.format == format) return f.file_name;
  }
  return "export";
}

std::string export_format_list() {
  std::string out;
  for (const FormatInfo& f : kFormats) out += (out.empty() ? "" : ", ") + std::string(f.name);
  return out;
}

ExportFormat parse_export_format(const std::string& name) {
  for (const FormatInfo& f : kFormats) {
    if (name == f.name) return f.format;
  }
  throw IoError("unknown export format '" + name + "' (one of: " + export_format_list() + ")");
}

std::pair<ExportFormat, std::string> parse_export_spec(const std::string& spec) {
  const std::size_t eq = spec.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == spec.size()) {
    throw IoError("--export '" + spec + "' is not NAME=FILE (NAME one of: " + export_format_list() +
                  ")");
  }
  return {parse_export_format(spec.substr(0, eq)), spec.substr(eq + 1)};
}

CalibrationToExport calibration_to_export(const StoredResult& result, const std::string& source) {
  CalibrationToExport c;
  c.S = result.S;
  c.O = result.O;
  c.local_gravity = result.local_gravity;
  c.model_label = result.model_label;
  std::vector<std::string> names, targets;
  for (const StoredEffect& e : result.fitted_effects) {
    names.push_back(e.name);
    targets.push_back(e.target);
  }
  c.terms_left_out = terms_of(names, targets);
  c.noise_density = result.noise_density;
  c.rate_hz = result.sample_rate_hz;
  if (!result.quality_pass)
    c.quality_failure = core::Quality{false, result.quality_reasons}.summary();
  c.source = source;
  return c;
}

CalibrationToExport calibration_to_export(const core::FitResult& fit, const std::string& source) {
  CalibrationToExport c;
  c.S = fit.S;
  c.O = fit.O;
  c.local_gravity = fit.local_gravity;
  c.model_label = fit.model_label();
  std::vector<std::string> names, targets;
  for (const core::Effect& e : fit.effects) {
    names.push_back(e.name());
    targets.push_back(e.target_name());
  }
  c.terms_left_out = terms_of(names, targets);
  c.source = source;
  return c;
}

CalibrationToExport calibration_to_export(const core::CalibrationReport& report,
                                          const std::string& source) {
  CalibrationToExport c = calibration_to_export(report.certificate, source);
  if (!report.quality.pass) c.quality_failure = report.quality.summary();
  if (report.noise) {
    c.noise_density = report.noise->density;
    c.rate_hz = report.noise->rate_hz;
  }
  return c;
}

ExportText export_text(ExportFormat format, const CalibrationToExport& c) {
  const std::string what = std::string("cannot export to ") + export_format_name(format) + ": ";
  if (!c.quality_failure.empty()) {
    throw IoError(what + "the result fails the quality gate (" + c.quality_failure +
                  "); a failing fit is not a calibration to apply");
  }
  if (!(std::isfinite(c.local_gravity) && c.local_gravity > 0.0)) {
    throw IoError(what + "the result states no local gravity");
  }
  if (!c.S.allFinite() || !c.O.allFinite()) {
    throw IoError(what + "the result's vectors or offsets are not finite numbers");
  }
  const std::vector<std::string> lines = provenance(c, c.date.empty() ? now_utc() : c.date);
  ExportText out;
  try {
    switch (format) {
      case ExportFormat::ImuCalib: out = imu_calib_text(c, lines); break;
      case ExportFormat::Imucal: out = imucal_text(c, lines); break;
      case ExportFormat::Kalibr: out = kalibr_text(c, lines); break;
      case ExportFormat::ImuTk: out = imu_tk_text(c, lines); break;
      case ExportFormat::Px4:
      case ExportFormat::Ardupilot: out = diagonal_text(format, c, lines); break;
    }
  } catch (const std::invalid_argument& e) {
    throw IoError(what + e.what());
  }
  if (!c.terms_left_out.empty()) {
    std::string terms;
    for (const std::string& t : c.terms_left_out) terms += (terms.empty() ? "" : ", ") + t;
    out.notice += std::string(out.notice.empty() ? "" : "; ") + export_format_name(format) +
                  " export leaves out the fitted terms " + terms;
  }
  return out;
}

ExportText write_export(const std::string& path, ExportFormat format,
                        const CalibrationToExport& calibration) {
  ExportText out = export_text(format, calibration);
  write_file_atomically(path, out.text);
  return out;
}

}  // namespace io
}  // namespace accel_intrinsics
