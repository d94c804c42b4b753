// What a run offers toward the effect catalog's preconditions (effects.h Precondition): a two-way
// sweep per phase, the dwell temperatures. The discrepancy analysis screens an effect only when
// its precondition is met; the fit's own checks of the effects it is asked to fit are in
// fit_validation.cpp (validate_effects). One home for both: src/core/fit/fit_validation.cpp.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/model/effects.h"
#include "accel_intrinsics/core/model/model.h"

namespace accel_intrinsics {
namespace core {

// Whether the dwell temperatures of `table` let the analysis screen the temperature effects, and
// if not, why (for AnalysisResult::not_screened).
struct TemperatureCoverage {
  std::size_t rows = 0;
  std::size_t rows_with_temperature = 0;
  double span_k = 0.0;  // max - min of the dwell temperatures (rows that have one)
  bool screenable = false;
  std::string reason;  // empty when screenable
};
TemperatureCoverage temperature_coverage(const PositionTable& table, double min_temperature_span_k);

// What a run offers toward the catalog's preconditions.
struct RunConditions {
  std::array<bool, 3> two_way{{false, false, false}};
  TemperatureCoverage temperature;
};

RunConditions run_conditions(const PositionTable& table, const std::vector<DwellGeometry>& geoms,
                             double min_temperature_span_k);

// Whether the dwell means of a run can show `effect` (its catalog precondition): raw-stream
// effects never, two-way effects only on a two-way phase, temperature effects only with varying
// dwell temperatures.
bool screenable(const Effect& effect, const RunConditions& run);

// Why `effect` was not screened in this run: the catalog's note, with the run's reason.
std::string not_screened_note(const Effect& effect, const RunConditions& run);

// Whether an unscreened effect may be the look-alike of a named one. A temperature that was
// recorded in every dwell and stayed flat rules a temperature coefficient out as the cause of
// drift; unrecorded temperatures do not.
bool look_alike_possible(const Effect& unscreened, const RunConditions& run);

}  // namespace core
}  // namespace accel_intrinsics
