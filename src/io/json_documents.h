// Private to the io library: the JSON trees behind the result and analysis documents, built once
// and emitted as JSON or YAML. No public header includes nlohmann.
#pragma once

#include <nlohmann/json.hpp>

#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/analysis/raw_stream_analysis.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {
namespace io {
namespace detail {

// The fit's keys (the contract's plus model_label, *_std, chi2, dof, fitted_effects).
nlohmann::json fit_json(const core::FitResult& fit);
// "noise_model" (docs/design.md section 12): the string "white", or {kind, source, rate_hz, rest
// {t_start, t_end, samples}, axes {u,v,w: {white_std, gm_sigma, gm_tau_s, rw_density,
// slow_scale_rel_var}}}.
nlohmann::json noise_model_json(const core::NoiseModel& model);
// The analysis' keys (analysis_report.h).
nlohmann::json analysis_json(const core::AnalysisResult& analysis);
// "timing_lag" {...}, and appended to "effects" when detected.
void add_timing_lag(const core::TimingLagEstimate& lag, nlohmann::json* analysis);
// "uncertainty_budget" (budget_file.cpp, docs/design.md section 9): angles in degrees.
nlohmann::json budget_json(const core::UncertaintyBudget& budget);
// The whole result document (result_document.h).
nlohmann::json result_document(const core::CalibrationReport& report, const ResultContext& context);

}  // namespace detail
}  // namespace io
}  // namespace accel_intrinsics
