// The discrepancy analysis (core/discrepancy.h) and the timing lag as documents: the analysis
// JSON (the calibration node's calibration/analysis topic and analysis.json; merged into
// offline_fit's JSON) and the human-readable analysis report.
#pragma once

#include <iosfwd>
#include <string>

#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {
namespace io {

// The analysis alone: `effects` [{name, target, value, std, p_value, unit, p_raw, score_chi2,
// delta_chi2, step, closest_alternative, closest_correlation}], `ambiguous`, `gap {before,
// after}` (docs/design.md section 2) plus localization, model_before, model_after, local_gravity,
// stop_reason, screening, unidentifiable, not_screened, unobservable.
std::string analysis_json_text(const core::AnalysisResult& analysis);

// What the node publishes on calibration/analysis and writes to analysis.json: the analysis keys
// above, `timing_lag` {ok, message, value, std, p_value, detected, lr_chi2, samples_used,
// detection_threshold} when estimated (and appended to `effects` as {name: timing_lag, target:
// all, value, std, p_value} when detected), certificate_model, certificate_policy, base_model,
// refit_model and stamp (when context.stamp_s is finite). Throws std::invalid_argument when the
// report has no analysis.
std::string analysis_json_text(const core::CalibrationReport& report, const ResultContext& context);

// Human-readable report (a few dozen lines): gap before/after, the worst cells and harmonics,
// named effects, ambiguity, notes. For offline_fit's text output and the calibration node's log.
void write_analysis_report(std::ostream& out, const core::AnalysisResult& analysis);

// One line for a log and the calibration node's analyze service: the reduced chi-square before ->
// after, the named effects with std and p, the certificate's model and the timing lag. Throws
// std::invalid_argument when the report has no analysis.
std::string analysis_summary_line(const core::CalibrationReport& report);

}  // namespace io
}  // namespace accel_intrinsics
