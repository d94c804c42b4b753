// offline_fit --residuals-csv FILE: the residual CSV that scripts/plot_residuals reads
// (io/residuals_csv.h), written from the run's report: "before" is the base fit, "after" the
// analysis' refit with the named effects (the base fit again when there was no analysis).
#pragma once

#include <string>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/run/calibrate.h"

namespace accel_intrinsics {

// Empty when the report has residuals against known orientations; otherwise why not (a hand
// tumble's rests have no known orientation to plot against).
std::string residuals_csv_refusal(const core::CalibrationReport& report);

// Atomic; throws io::IoError naming the path.
void write_offline_residuals_csv(const std::string& path, const core::PositionTable& table,
                                 const core::CalibrationReport& report);

}  // namespace accel_intrinsics
