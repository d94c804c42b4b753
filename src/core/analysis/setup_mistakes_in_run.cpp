// Setup mistakes in the analysis and the quality gate of a finished run (setup_mistakes.h,
// docs/design.md section 15).
#include <exception>

#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/analysis/setup_mistakes.h"

namespace accel_intrinsics {
namespace core {

bool stop_analysis_on_setup_mistakes(const PositionTable& table, const AnalysisOptions& options,
                                     AnalysisResult* result) {
  SetupOptions setup;
  setup.local_gravity = options.local_gravity;
  setup.output_unit = options.output_unit;
  result->setup_mistakes = detect_setup_mistakes(table, setup);
  if (result->setup_mistakes.empty()) return false;
  std::string labels;
  for (const SetupMistake& m : result->setup_mistakes)
    labels += (labels.empty() ? "" : ", ") + m.label();
  result->stop_reason = "setup mistake found (" + labels +
                        "): no physical effect is screened on a run read wrongly; " +
                        kUnknownOrientationsAdvice;
  try {
    FitOptions fo;
    fo.model = FitModel::Joint;
    fo.local_gravity = options.local_gravity;
    fo.noise_model = options.noise_model;
    result->before_fit = fit(table, fo);
    result->after_fit = result->before_fit;
    result->before = compute_gap(table, result->before_fit, options.harmonics, options.time_bins);
    result->after = result->before;
  } catch (const std::exception&) {
    // A run this wrong may not fit at all: the mistakes are the report.
  }
  return true;
}

void name_setup_mistakes(const PositionTable& table, const SetupOptions& options,
                         Quality* quality) {
  if (quality->pass) return;
  const std::vector<SetupMistake> mistakes = detect_setup_mistakes(table, options);
  if (mistakes.empty()) return;
  quality->reasons.clear();
  for (const SetupMistake& m : mistakes) quality->reasons.push_back("setup mistake " + m.text());
  quality->reasons.push_back(kUnknownOrientationsAdvice);
}

}  // namespace core
}  // namespace accel_intrinsics
