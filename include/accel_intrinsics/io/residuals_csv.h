// Residuals of two fits as a long-format CSV for plots (scripts/plot_residuals): one line per
// dwell and accelerometer,
//   phase,step,angle_rad,time_s,approach,accelerometer,measured,sigma,
//   model_before,residual_before,z_before,model_after,residual_after,z_after
// (models from the digital twins of the two fits, core::device_from_fit).
#pragma once

#include <iosfwd>
#include <string>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/fit.h"

namespace accel_intrinsics {
namespace io {

void write_residuals_csv(std::ostream& out, const core::PositionTable& table,
                         const core::FitResult& before_fit, const core::FitResult& after_fit);
// Atomic; throws IoError naming the path.
void write_residuals_csv(const std::string& path, const core::PositionTable& table,
                         const core::FitResult& before_fit, const core::FitResult& after_fit);

}  // namespace io
}  // namespace accel_intrinsics
