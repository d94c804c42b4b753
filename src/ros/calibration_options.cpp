// The calibration node's parameters (config/calibration.yaml documents each one).
#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/budget_file.h"
#include "accel_intrinsics/io/exporters.h"
#include "accel_intrinsics/ros/calibration_node.h"
#include "accel_intrinsics/ros/params.h"

namespace accel_intrinsics {

CalibrationOptions CalibrationOptions::load(const ros::NodeHandle& pnh) {
  CalibrationOptions o;
  std::string model = core::model_name(o.calibrate.fit.model);
  read_param(pnh, "model", &model);
  try {
    o.calibrate.fit.model = core::parse_model(model);
  } catch (const std::invalid_argument&) {
    throw ParamError("parameter " + param_name(pnh, "model") + ": unknown model '" + model +
                     "' (joint or eq4)");
  }
  const bool have_g = read_param(pnh, "local_gravity", &o.calibrate.fit.local_gravity);
  double latitude_deg = 0.0, height_m = 0.0;
  const bool have_lat = read_param(pnh, "latitude_deg", &latitude_deg);
  read_param(pnh, "height_m", &height_m);
  require(!(have_g && have_lat), pnh, "local_gravity",
          "give either local_gravity or latitude_deg (with height_m), not both");
  if (have_lat) {
    try {
      o.calibrate.fit.local_gravity = core::normal_gravity(latitude_deg, height_m);
    } catch (const std::invalid_argument& e) {
      throw ParamError("parameter " + param_name(pnh, "latitude_deg") + ": " + e.what());
    }
  }
  require(
      std::isfinite(o.calibrate.fit.local_gravity) && o.calibrate.fit.local_gravity > 9.7 &&
          o.calibrate.fit.local_gravity < 9.9,
      pnh, "local_gravity",
      "must be in (9.7, 9.9) m/s^2 (got " + std::to_string(o.calibrate.fit.local_gravity) + ")");
  read_param(pnh, "output_unit", &o.calibrate.output_unit);
  require(!o.calibrate.output_unit.empty(), pnh, "output_unit", "must not be empty (m/s^2)");
  o.gravity_source = have_lat ? "normal gravity at parameters latitude_deg, height_m"
                     : have_g ? "parameter local_gravity"
                              : "standard gravity (default; no local_gravity given)";
  std::string budget_file;
  if (read_param(pnh, "budget_file", &budget_file) && !budget_file.empty()) {
    try {
      const io::BudgetFile budget = io::read_budget_file(budget_file);
      o.calibrate.budget = budget.spec;
      o.certificate = budget.certificate;
    } catch (const io::IoError& e) {
      throw ParamError("parameter " + param_name(pnh, "budget_file") + ": " + e.what());
    }
  }
  read_param(pnh, "min_positions_per_phase", &o.calibrate.fit.min_positions_per_phase);
  require(o.calibrate.fit.min_positions_per_phase >= 3, pnh, "min_positions_per_phase",
          "must be >= 3");
  o.run.min_positions_per_phase = o.calibrate.fit.min_positions_per_phase;
  read_param(pnh, "settle_discard_s", &o.run.assembler.settle_discard_s);
  require(
      std::isfinite(o.run.assembler.settle_discard_s) && o.run.assembler.settle_discard_s >= 0.0,
      pnh, "settle_discard_s", "must be finite and >= 0 s");
  read_param(pnh, "reorder_window_s", &o.run.assembler.reorder_window_s);
  require(std::isfinite(o.run.assembler.reorder_window_s) &&
              o.run.assembler.reorder_window_s >= 0.0 && o.run.assembler.reorder_window_s <= 60.0,
          pnh, "reorder_window_s", "must be in [0, 60] s");
  read_param(pnh, "flush_period_s", &o.flush_period_s);
  require(std::isfinite(o.flush_period_s) && o.flush_period_s > 0.0 && o.flush_period_s <= 10.0,
          pnh, "flush_period_s", "must be in (0, 10] s");
  read_param(pnh, "status_period_s", &o.status_period_s);
  require(std::isfinite(o.status_period_s) && o.status_period_s > 0.0, pnh, "status_period_s",
          "must be > 0 s");
  read_param(pnh, "steps", &o.run.steps);
  read_param(pnh, "frame_id", &o.frame_id);
  read_param(pnh, "immediate_imu", &o.immediate_imu);
  read_param(pnh, "imu_coalesce_s", &o.imu_coalesce_s);
  require(std::isfinite(o.imu_coalesce_s) && o.imu_coalesce_s >= 0.0 && o.imu_coalesce_s <= 0.05,
          pnh, "imu_coalesce_s", "must be in [0, 0.05] s");
  read_param(pnh, "imu_batch_s", &o.imu_batch_s);
  require(std::isfinite(o.imu_batch_s) && o.imu_batch_s >= 0.0 && o.imu_batch_s <= 0.05, pnh,
          "imu_batch_s", "must be in [0, 0.05] s");
  read_param(pnh, "file_prefix", &o.file_prefix);
  require(o.file_prefix.find('/') == std::string::npos, pnh, "file_prefix", "must not contain '/'");
  // Analysis.
  read_param(pnh, "analyze", &o.calibrate.analyze);
  o.run.record_moves = o.calibrate.analyze;
  o.calibrate.analysis.local_gravity = o.calibrate.fit.local_gravity;
  read_param(pnh, "analysis/alpha", &o.calibrate.analysis.alpha);
  read_param(pnh, "analysis/max_effects", &o.calibrate.analysis.max_effects);
  read_param(pnh, "analysis/monte_carlo_draws", &o.calibrate.analysis.monte_carlo_draws);
  int analysis_seed = static_cast<int>(o.calibrate.analysis.seed % 2147483647ULL);
  if (read_param(pnh, "analysis/seed", &analysis_seed)) {
    require(analysis_seed >= 0, pnh, "analysis/seed", "must be >= 0");
    o.calibrate.analysis.seed = static_cast<std::uint64_t>(analysis_seed);
  }
  try {
    core::validate(o.calibrate.analysis);
  } catch (const std::invalid_argument& e) {
    throw ParamError("parameter " + param_name(pnh, "analysis") + ": " + e.what());
  }
  std::string certificate = "base";
  read_param(pnh, "certificate_model", &certificate);
  require(certificate == "base" || certificate == "refit", pnh, "certificate_model",
          "must be 'base' or 'refit' (got '" + certificate + "')");
  o.calibrate.certificate_refit = certificate == "refit";

  // Resume and watchdogs.
  read_param(pnh, "resume", &o.resume);
  read_param(pnh, "imu_timeout_s", &o.run.imu_timeout_s);
  require(std::isfinite(o.run.imu_timeout_s) && o.run.imu_timeout_s >= 0.0, pnh, "imu_timeout_s",
          "must be finite and >= 0 s (0 = off)");
  read_param(pnh, "min_samples_per_dwell", &o.run.min_samples_per_dwell);
  std::string on_fault = "abort";
  read_param(pnh, "on_fault", &on_fault);
  require(on_fault == "abort" || on_fault == "retry", pnh, "on_fault",
          "must be 'abort' or 'retry' (got '" + on_fault + "')");
  o.run.retry_on_fault = on_fault == "retry";
  read_param(pnh, "max_retries", &o.run.max_retries);
  read_param(pnh, "resume_idle_controller", &o.run.resume_idle_controller);
  require(o.run.max_retries <= 100, pnh, "max_retries", "must be in [0, 100]");
  // Clocks (docs/design.md section 5).
  read_param(pnh, "imu_time_offset_s", &o.run.imu_time_offset_s);
  require(std::isfinite(o.run.imu_time_offset_s), pnh, "imu_time_offset_s", "must be finite (s)");
  read_param(pnh, "clock_check", &o.run.check_clock);
  read_param(pnh, "idle_fit_after_s", &o.idle_fit_after_s);
  require(std::isfinite(o.idle_fit_after_s) && o.idle_fit_after_s > 0.0, pnh, "idle_fit_after_s",
          "must be > 0 s");
  read_param(pnh, "gimbal_controller", &o.gimbal_controller);
  require(!o.gimbal_controller.empty(), pnh, "gimbal_controller", "must not be empty");

  read_param(pnh, "output_dir", &o.output_dir);
  require(!(o.resume && o.output_dir.empty()), pnh, "resume",
          "needs output_dir (the checkpoint lives there)");
  if (!o.output_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.output_dir, ec);
    require(!ec && std::filesystem::is_directory(o.output_dir), pnh, "output_dir",
            "cannot create directory '" + o.output_dir + "'" + (ec ? ": " + ec.message() : ""));
  }
  std::vector<std::string> exports;
  read_param(pnh, "exports", &exports);
  for (const std::string& name : exports) {
    try {
      o.exports.push_back(io::parse_export_format(name));
    } catch (const io::IoError& e) {
      throw ParamError("parameter " + param_name(pnh, "exports") + ": " + e.what());
    }
  }
  require(o.exports.empty() || !o.output_dir.empty(), pnh, "exports",
          "needs output_dir (the files are written there)");
  read_param(pnh, "device_serial", &o.device_serial);
  require(!o.device_serial.empty(), pnh, "device_serial", "must not be empty");
  read_param(pnh, "archive", &o.archive);
  read_param(pnh, "archive_device", &o.archive_device);
  read_param(pnh, "archive_rig", &o.archive_rig);
  require(o.archive.empty() || !o.output_dir.empty(), pnh, "archive",
          "needs output_dir (the archived result and position table are written there)");
  return o;
}

}  // namespace accel_intrinsics
