// offline_fit --residuals-csv: the residual CSV of the base fit and the analysis' refit.
#include "accel_intrinsics/ros/offline_fit_residuals.h"

#include "accel_intrinsics/io/residuals_csv.h"

namespace accel_intrinsics {

std::string residuals_csv_refusal(const core::CalibrationReport& report) {
  if (report.method == "tumble") {
    return "a hand tumble's rests have no known orientation to plot residuals against "
           "(the result's \"rests\" hold each rest's mean)";
  }
  return "";
}

void write_offline_residuals_csv(const std::string& path, const core::PositionTable& table,
                                 const core::CalibrationReport& report) {
  const core::FitResult& before = report.analysis ? report.analysis->before_fit : report.base_fit;
  const core::FitResult& after = report.analysis ? report.analysis->after_fit : report.base_fit;
  io::write_residuals_csv(path, table, before, after);
}

}  // namespace accel_intrinsics
