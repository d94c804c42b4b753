// The calibration pipeline: fit -> discrepancy analysis -> timing lag, and which fit the
// certificate holds. The one sequence behind the calibration node (its worker and its analyze
// service) and offline_fit (docs/design.md section 4); the io writers turn its report into files.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/analysis/raw_stream_analysis.h"
#include "accel_intrinsics/core/analysis/tumble_analysis.h"
#include "accel_intrinsics/core/analysis/uncertainty_budget.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/fit/quality.h"
#include "accel_intrinsics/core/fit/tumble.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace core {

// The raw streams of a run, for the timing-lag estimate (dwell means cannot show a lag).
struct RawStreams {
  std::vector<GimbalEvent> commands;  // whole recording, or the moves only (MoveSampleRecorder)
  std::vector<ImuSample> samples;
};

struct CalibrateOptions {
  FitOptions fit;            // model, local_gravity, min_positions_per_phase
  bool analyze = false;      // discrepancy analysis, and timing lag when raw streams have commands
  AnalysisOptions analysis;  // its local_gravity is set from fit.local_gravity
  // Certificate = the analysis' refit when it named effects, else the base fit.
  bool certificate_refit = false;
  QualityOptions quality;  // the gate on the certificate
  // Unit of the raw outputs (docs/design.md section 6): "m/s^2" (responsivities dimensionless), or
  // counts, V, ...: responsivities are then in that unit per m/s^2, and the quality gate checks
  // their spread only.
  std::string output_unit = "m/s^2";
  // Type-B budget of the certificate (uncertainty_budget.h, docs/design.md section 9); none: type A
  // only.
  std::optional<BudgetSpec> budget;
};

// `options` with the fit and the analysis weighted by the run's noise model (docs/design.md section
// 12), as offline_fit and the calibration node both do; unchanged without one (white).
CalibrateOptions with_noise_model(CalibrateOptions options, const std::optional<NoiseModel>& model);

// The run's temperature (docs/design.md section 10), when some dwell recorded one: S and O, and any
// fitted temperature coefficient, refer to reference_c (T_ref, the mean dwell temperature).
struct RunTemperature {
  double reference_c = 0.0;
  double min_c = 0.0;
  double max_c = 0.0;
  std::size_t dwells_with_temperature = 0;
  std::size_t dwells = 0;
};
// Of a table; nullopt when no dwell has a temperature.
std::optional<RunTemperature> run_temperature(const PositionTable& table);

// How the orientations were known (the result's "method", docs/design.md section 11): "gimbal"
// (commanded angles), "positions" (rows with f_x,f_y,f_z), "tumble" (unknown: rests only).
std::string calibration_method(const PositionTable& table);

struct CalibrationReport {
  std::string method = "gimbal";
  FitResult base_fit;     // the fit with options.fit.model
  FitResult certificate;  // what result files and messages hold (base_fit or the refit)
  bool certificate_is_refit = false;
  bool certificate_refit_policy = false;   // the policy asked ("base" | "refit")
  std::optional<AnalysisResult> analysis;  // when analyze and it succeeded
  std::string analysis_error;              // when analyze and it failed (the fit stands)
  // When analyze and raw commands were given: estimate_timing_lag with the analysis' refit and
  // timing_lag_options_beside_screen() (its false-alarm budget beside the dwell screen).
  std::optional<TimingLagEstimate> timing_lag;
  Quality quality;  // of the certificate (docs/design.md section 5)
  std::string output_unit = "m/s^2";
  // White noise from the dwells (noise.h), when they hold samples and durations.
  std::optional<DwellNoise> noise;
  // When the dwells recorded a temperature: T_ref and the range (the result's "temperature").
  std::optional<RunTemperature> temperature;
  // When options.budget: the certificate's uncertainty budget (type A plus the type-B sources).
  std::optional<UncertaintyBudget> budget;
  // A tumble: which axis directions the rests reached, and the pose that would help most next.
  std::optional<TumbleCoverage> coverage;
  std::optional<PoseSuggestion> next_pose;
  // A tumble with analyze: the sensor effects its rests can show (tumble_analysis.h); the
  // certificate is its refit when the policy is refit and it named effects.
  std::optional<TumbleAnalysis> tumble_analysis;
};

// Fit -> analysis -> timing lag -> quality gate. Throws FitError when the fit fails (the message
// says what is missing; fit() may also throw std::invalid_argument for bad options). A failing
// analysis or lag estimate does not throw: it leaves analysis_error and the base fit as the
// certificate. `raw` may be null (a position table alone: no timing lag). With options.budget, the
// budget of the certificate is computed last (its refit failing throws FitError, an invalid spec
// std::invalid_argument).
CalibrationReport calibrate(const PositionTable& table, const RawStreams* raw,
                            const CalibrateOptions& options);

}  // namespace core
}  // namespace accel_intrinsics
