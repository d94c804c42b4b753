#include "accel_intrinsics/ros/result_files.h"

#include <ros/console.h>

namespace accel_intrinsics {

void write_exports(const io::CheckpointFiles& files, const std::vector<io::ExportFormat>& formats,
                   const core::CalibrationReport& report) {
  if (formats.empty()) return;
  const io::CalibrationToExport calibration =
      io::calibration_to_export(report, files.result_path());
  if (!calibration.quality_failure.empty()) {
    ROS_ERROR("calibration: no exports written: the result fails the quality gate");
    return;
  }
  for (io::ExportFormat format : formats) {
    const std::string path = files.file_path(io::export_file_name(format));
    try {
      const io::ExportText text = io::write_export(path, format, calibration);
      ROS_INFO("calibration: wrote %s", path.c_str());
      if (!text.notice.empty()) ROS_WARN("calibration: %s", text.notice.c_str());
    } catch (const io::IoError& e) {
      ROS_ERROR("calibration: %s", e.what());
    }
  }
}

void write_result_files(const io::CheckpointFiles& files,
                        const std::vector<io::ExportFormat>& formats,
                        const core::CalibrationReport& report, const io::ResultContext& context) {
  if (!files.enabled()) return;
  try {
    io::write_result_yaml(files.result_path(), report, context);
    ROS_INFO("calibration: wrote %s", files.result_path().c_str());
  } catch (const io::IoError& e) {
    ROS_ERROR("calibration: %s", e.what());
    return;
  }
  write_exports(files, formats, report);
}

}  // namespace accel_intrinsics
