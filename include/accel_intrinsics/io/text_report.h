// The text report of a calibration (offline_fit's standard output): input, warnings, model, the
// certificate's parameters with their standard uncertainties, S and P, the fit quality; then the
// analysis report and the timing lag when the report has them.
#pragma once

#include <iosfwd>
#include <string>

#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {
namespace io {

// One accelerometer's noise model in words, parts that are zero left out, two significant digits:
// "u: white 0.00051 (m/s^2)/sqrt(Hz); random walk 0.053 (m/s^2)/sqrt(s) (relative std of its
// scale 0.93)". The white density is white_std / sqrt(rate_hz); `unit` is the output unit.
std::string noise_axis_words(const std::string& axis, const core::AxisNoiseModel& noise,
                             double rate_hz, const std::string& unit);

// The parameter table of one fit (uses context.input and warnings for the header lines).
void write_fit_report(std::ostream& out, const core::FitResult& fit, const ResultContext& context,
                      const std::string& output_unit = "m/s^2");
// write_fit_report of the certificate, then (after a blank line) the analysis report and the
// timing-lag line.
void write_text_report(std::ostream& out, const core::CalibrationReport& report,
                       const ResultContext& context);

}  // namespace io
}  // namespace accel_intrinsics
