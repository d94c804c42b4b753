// The quality gate (docs/design.md section 5): a fit whose reduced chi-square lies far above its
// 99.9 % band, whose responsivities or angles are physically implausible, or whose dwells hold
// too few samples is not a calibration. Every result carries the verdict; offline_fit exits 3,
// the node's service answers success: false, supervise fails, each naming the reasons.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/fit.h"

namespace accel_intrinsics {
namespace core {

struct QualityOptions {
  // "Far above the band": reduced chi-square above `chi2_far_factor` times the upper end of its
  // `chi2_band` central band for the fit's degrees of freedom. An effect the model lacks raises
  // chi-square a little (the analysis names it); garbage (a wrong clock, a wrong table) raises it
  // by orders of magnitude.
  double chi2_band = 0.999;
  double chi2_far_factor = 10.0;
  // Responsivities relative to their mean (any output unit), and absolute when the outputs are
  // in m/s^2 (dimensionless responsivity).
  double max_responsivity_spread = 0.5;  // |r - mean| / mean
  double min_responsivity_si = 0.5;
  double max_responsivity_si = 2.0;
  bool outputs_in_si = true;  // false for counts or volts (output_unit)
  // Angles between the axes of maximum response, degrees: a MEMS triad is within a few degrees of
  // orthogonal; 30 degrees off is a wrong table or a wrong axis assignment.
  double min_angle_deg = 60.0;
  double max_angle_deg = 120.0;
  // Fewer samples leave a dwell without a meaningful standard error.
  std::uint64_t min_samples_per_dwell = 3;
};

struct Quality {
  bool pass = true;
  std::vector<std::string> reasons;  // empty when pass
  std::string summary() const;       // "passed" or the reasons joined by "; "
};

// The upper end of the reduced chi-square's central `band` for `dof` degrees of freedom.
double reduced_chi2_upper(int dof, double band);

Quality assess_quality(const FitResult& fit, const PositionTable& table,
                       const QualityOptions& options = {});

}  // namespace core
}  // namespace accel_intrinsics
