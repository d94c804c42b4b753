// The result of a calibration as a document: one key list, emitted as JSON (offline_fit --json)
// or YAML (the calibration node's intrinsics.yaml), so that a key means the same in both
// (docs/design.md sections 2 and 4). Keys, all from one function:
//
//   contract (docs/design.md section 2): model (joint|eq4), responsivity {u,v,w}, responsivity_std,
//     angles_deg {uv,vw,wu}, angles_std_deg, vectors {u,v,w: [x,y,z]}, offset {u,v,w},
//     offset_per_phase {u,v,w: {x,y,z}}, cross_sensitivity (3x3, rows), local_gravity,
//     reduced_chi2, residual_rms, positions {x,y,z}
//   of the certificate fit, beyond the contract: model_label (e.g.
//     "joint+quadratic_nonlinearity[u]"), vectors_std, offset_std, offset_per_phase_std,
//     cross_sensitivity_std, chi2, dof, fitted_effects [{name, target, value, std}] (the terms
//     fitted in the certificate model), noise_model ("white", or {kind, source, rate_hz, rest
//     {t_start, t_end, samples}, axes {u,v,w: {white_std, gm_sigma, gm_tau_s, rw_density,
//     slow_scale_rel_var}}}: the noise of the dwell means the fit used, docs/design.md section 12)
//   from the dwells (core/noise.h), when they tell: noise_density {u,v,w} ((m/s^2)/sqrt(Hz), the
//     continuous-time density sample_std / sqrt(rate)), noise_density_std, sample_rate_hz
//   always: certificate_model (model_label of the certificate), certificate_policy (base|refit)
//   with an analysis: effects [{name, target, value, std, p_value, ...}] (the effects the analysis
//     named, timing_lag appended when detected), ambiguous, gap {before, after} (each with
//     cv_chi2_per_point, cv_folds: out of sample), noise_entries [{name: correlated_noise,
//     named, ...}], screening, ...
//     (analysis_report.h; never replacing a key above), timing_lag when estimated;
//     analysis_error when the analysis failed
//   with a budget (offline_fit --budget, the node's budget_file): uncertainty_budget {sources,
//     combined_std, expanded {k, ...}, samples, seed, method} (docs/design.md section 9), and
//     certificate {lab, device, ...} (the budget file's certificate block) when it has fields
//   always: method (gimbal|positions|tumble); a tumble: frame, coverage {cone_deg, complete,
//     missing, closest_deg}, next_pose {up, words, target, ...}, rests [{t_start, t_end, n, mean,
//     std}], rejected_spans [{t_start, t_end, reason}], rest_detection {quiet_std, rate_hz, ...}
//     (found in a stream); with --analyze, the tumble screen as effects, ambiguous, gap,
//     not_screened, screening (core/tumble_analysis.h)
//   always: units {responsivity, offset, angles_deg, local_gravity, noise_density, ...} (the unit
//     of each key; output_unit names the device's output)
//   from the context: device_serial, imu_topic, gimbal_driver, time_utc (ISO 8601),
//     local_gravity_source, stamp (node), samples {used, dropped_*} (node), input, complete,
//     warnings (offline_fit)
//
// Non-finite numbers are null. Keys come out sorted. Files are written atomically (atomic_file.h).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "accel_intrinsics/core/analysis/uncertainty_budget.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/rest_detection.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/intrinsics.h"
#include "accel_intrinsics/core/run/calibrate.h"

namespace accel_intrinsics {
namespace io {

// What a bag gave (offline_fit's "input" block for a bag).
struct BagInputDescription {
  std::string imu_topic;
  std::string command_topic;
  std::uint64_t imu_messages = 0;
  std::uint64_t command_messages = 0;
  std::uint64_t invalid_commands = 0;
  double duration_s = 0.0;
  double read_wall_s = 0.0;
  double settle_discard_s = 0.0;
  double imu_time_offset_s = 0.0;  // added to the IMU stamps (--imu-time-offset)
  std::uint32_t files = 1;         // bags of the run
  core::AssemblerCounters counters;
  bool done_seen = false;
  double time_origin_s = std::numeric_limits<double>::quiet_NaN();
};

// Where the dwells came from: a CSV position table or a bag.
struct InputDescription {
  std::string path;
  std::size_t dwells = 0;                  // rows of the position table
  std::optional<BagInputDescription> bag;  // absent: a CSV position table
  std::string summary;                     // one line for the text report
  std::string type;                        // "csv" (default when empty), "samples"; a bag has `bag`
};

// What the document says beyond the pipeline's report.
struct ResultContext {
  double stamp_s = std::numeric_limits<double>::quiet_NaN();  // "stamp"; NaN = omitted
  std::optional<core::AssemblerCounters> samples;             // the node's "samples" block
  // offline_fit: "input", "complete" (null for a CSV, which cannot tell) and "warnings".
  std::optional<InputDescription> input;
  bool complete = true;
  std::vector<std::string> warnings;
  // The budget file's certificate block ("certificate" key) and where g came from
  // ("local_gravity_source"); empty: omitted.
  std::vector<std::pair<std::string, std::string>> certificate;
  std::string gravity_source;
  // A hand tumble (docs/design.md section 11): the rests fitted and the spans rejected ("rests",
  // "rejected_spans"), and, when found in a stream, the detector's levels ("rest_detection").
  std::optional<core::RestDetection> rest_detection;
  double rest_min_s = 0.0;
  // Where the run came from (docs/design.md section 15, "One result document"): the device's
  // serial ("device_serial"), the IMU topic as resolved ("imu_topic"), the gimbal driver
  // ("gimbal_driver") and the UTC time the result was written, ISO 8601 ("time_utc"); empty:
  // omitted.
  std::string device_serial;
  std::string imu_topic;
  std::string gimbal_driver;
  std::string time_utc;
};

std::string result_json_text(const core::CalibrationReport& report, const ResultContext& context);
std::string result_yaml_text(const core::CalibrationReport& report, const ResultContext& context);
// Atomic; throw IoError naming the path.
void write_result_json(const std::string& path, const core::CalibrationReport& report,
                       const ResultContext& context);
void write_result_yaml(const std::string& path, const core::CalibrationReport& report,
                       const ResultContext& context);

// ---- reading results back (exporters, comparisons) --------------------------------------------

struct StoredEffect {
  std::string name;
  std::string target;
  double value = 0.0;
  double std = 0.0;
};

// The certificate of a result file. Non-finite (null) numbers read as NaN.
struct StoredResult {
  core::FitModel model = core::FitModel::Joint;
  std::string model_label;      // e.g. "joint+quadratic_nonlinearity[u]"
  core::Intrinsics intrinsics;  // responsivity, angles (rad) and their std; no covariance
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();  // rows u, v, w
  Eigen::Vector3d O = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cross_sensitivity = Eigen::Matrix3d::Identity();  // P = S^-1
  double local_gravity = 0.0;
  std::vector<StoredEffect> fitted_effects;
  // noise_density and sample_rate_hz when the file has them, else NaN.
  Eigen::Vector3d noise_density =
      Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double sample_rate_hz = std::numeric_limits<double>::quiet_NaN();
  Eigen::Vector3d O_std = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  // uncertainty_budget.expanded when the result has one (comparisons, certificates).
  std::optional<core::IntrinsicValues> expanded;  // angles in radians
  double coverage_factor = 2.0;
  // The quality gate (docs/design.md section 5); a file written before the gate existed passes.
  bool quality_pass = true;
  std::vector<std::string> quality_reasons;
};

// Reads a result written by write_result_json/yaml, by offline_fit before them, or an old node
// YAML (whose `model` held the label and whose `effects` held the fitted terms). Throws IoError
// naming the path (and the key when one is missing or malformed).
StoredResult read_result_file(const std::string& path);

}  // namespace io
}  // namespace accel_intrinsics
