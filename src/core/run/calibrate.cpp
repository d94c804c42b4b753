#include "accel_intrinsics/core/run/calibrate.h"

#include <algorithm>
#include <exception>
#include <limits>
#include <stdexcept>

namespace accel_intrinsics {
namespace core {

namespace {

CalibrationReport fit_and_analyze(const PositionTable& table, const RawStreams* raw,
                                  const CalibrateOptions& options) {
  CalibrationReport report;
  report.certificate_refit_policy = options.certificate_refit;
  // Noise that is not white (docs/design.md section 12): the rest's slow part fitted again to the
  // run's dwell means, for the fit as for the analysis: a gimbal or position table through its
  // model (discrepancy.h slow_part_from_run), a tumble through the ellipsoid (tumble.h
  // slow_part_from_tumble). The table is prepared once for the fit (fit/prepared_table.h).
  const PreparedTable prepared(table);
  FitOptions fit_options = options.fit;
  if (fit_options.noise_model.slow_part_to_fit()) {
    const std::size_t unknown = prepared.rows_with_unknown_orientation();
    if (unknown == 0) {
      fit_options.noise_model = slow_part_from_run(table, fit_options);
    } else if (unknown == table.rows.size()) {
      fit_options.noise_model =
          slow_part_from_tumble(table, fit_options.noise_model, fit_options.local_gravity);
    }
  }
  report.base_fit = fit(prepared, fit_options);
  report.certificate = report.base_fit;
  report.noise = dwell_noise(table);
  if (!options.analyze) return report;
  if (report.base_fit.model == FitModel::Tumble) {
    TumbleAnalysisOptions tumble_options;
    tumble_options.local_gravity = options.fit.local_gravity;
    tumble_options.alpha = options.analysis.alpha;
    tumble_options.min_temperature_span_k = options.analysis.min_temperature_span_k;
    tumble_options.noise_model = fit_options.noise_model;
    try {
      report.tumble_analysis = analyze_tumble(table, tumble_options);
    } catch (const std::exception& e) {
      report.analysis_error = e.what();
      return report;
    }
    if (options.certificate_refit && !report.tumble_analysis->named.empty()) {
      report.certificate = report.tumble_analysis->after;
      report.certificate_is_refit = true;
    }
    return report;
  }

  AnalysisOptions analysis_options = options.analysis;
  analysis_options.local_gravity = options.fit.local_gravity;
  analysis_options.output_unit = options.output_unit.empty() ? "m/s^2" : options.output_unit;
  try {
    report.analysis = analyze(table, analysis_options);
    // Timing lag shows only in the raw streams around the moves.
    if (raw != nullptr && !raw->commands.empty()) {
      report.timing_lag =
          estimate_timing_lag(raw->commands, raw->samples, table, report.analysis->after_fit,
                              timing_lag_options_beside_screen());
    }
  } catch (const std::exception& e) {
    report.analysis.reset();
    report.timing_lag.reset();
    report.analysis_error = e.what();
    return report;
  }
  if (options.certificate_refit && !report.analysis->effects.empty()) {
    report.certificate = report.analysis->after_fit;
    report.certificate_is_refit = true;
  }
  return report;
}

}  // namespace

std::optional<RunTemperature> run_temperature(const PositionTable& table) {
  RunTemperature t;
  t.dwells = table.rows.size();
  t.dwells_with_temperature = rows_with_temperature(table);
  if (t.dwells_with_temperature == 0) return std::nullopt;
  t.reference_c = reference_temperature_c(table);
  t.min_c = std::numeric_limits<double>::infinity();
  t.max_c = -t.min_c;
  for (const DwellRecord& row : table.rows) {
    if (!row.has_temperature()) continue;
    t.min_c = std::min(t.min_c, row.temperature_c);
    t.max_c = std::max(t.max_c, row.temperature_c);
  }
  return t;
}

std::string calibration_method(const PositionTable& table) {
  if (!table.rows.empty() && rows_with_unknown_orientation(table) == table.rows.size())
    return "tumble";
  if (rows_with_direction(table) > 0) return "positions";
  return "gimbal";
}

CalibrateOptions with_noise_model(CalibrateOptions options,
                                  const std::optional<NoiseModel>& model) {
  if (model) {
    options.fit.noise_model = *model;
    options.analysis.noise_model = *model;
  }
  return options;
}

CalibrationReport calibrate(const PositionTable& table, const RawStreams* raw,
                            const CalibrateOptions& options) {
  CalibrationReport report = fit_and_analyze(table, raw, options);
  report.method = calibration_method(table);
  if (report.base_fit.model == FitModel::Tumble) {
    report.coverage = tumble_coverage(report.base_fit, table);
    report.next_pose = suggest_next_pose(report.base_fit, table);
    // Gimbal angles, tilts and mounts do not exist in a tumble: its type B is g alone.
    const BudgetSpec* b = options.budget ? &*options.budget : nullptr;
    if (b && (b->angle_random_std_deg != 0.0 || b->angle_offset_std_deg != 0.0 ||
              b->angle_scale_std != 0.0 || b->axis_tilt_std_deg != 0.0 ||
              b->mount_misalignment_std_deg != 0.0))
      throw std::invalid_argument(
          "a hand tumble's budget takes gravity_std_rel only: it has no gimbal angles, tilts or "
          "mounts (set the other sources to 0 or leave them out)");
  }
  report.temperature = run_temperature(table);
  report.output_unit = options.output_unit.empty() ? "m/s^2" : options.output_unit;
  QualityOptions quality = options.quality;
  quality.outputs_in_si = quality.outputs_in_si && report.output_unit == "m/s^2";
  report.quality = assess_quality(report.certificate, table, quality);
  // A failure caused by a setup mistake names the mistake, not its symptoms (section 15).
  if (report.method == "gimbal") {
    SetupOptions setup;
    setup.local_gravity = options.fit.local_gravity;
    setup.output_unit = report.output_unit;
    setup.min_gravity_ratio = quality.min_responsivity_si;
    setup.max_gravity_ratio = quality.max_responsivity_si;
    name_setup_mistakes(table, setup, &report.quality);
  }
  if (options.budget)
    report.budget = uncertainty_budget(table, report.certificate, *options.budget);
  return report;
}

}  // namespace core
}  // namespace accel_intrinsics
