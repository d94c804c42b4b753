#include "accel_intrinsics/ros/result_files.h"

#include <ros/console.h>

#include <optional>
#include <thread>

#include "accel_intrinsics/ros/params.h"
#include "accel_intrinsics/ros/scripts.h"

namespace accel_intrinsics {

core::RunActions restore_from_checkpoint(io::CheckpointFiles* files, const std::string& output_dir,
                                         core::CalibrationRun* run,
                                         const std::string& resume_param) {
  try {
    const std::optional<io::CheckpointFiles::Restored> restored = files->load();
    if (!restored) {
      ROS_INFO("calibration: resume: no checkpoint in %s, starting fresh", output_dir.c_str());
      return {};
    }
    if (restored->dropped_torn_line) {
      ROS_WARN("calibration: resume: dropped an incomplete last line of %s",
               files->table_path().c_str());
    }
    return run->restore(restored->table, restored->state);
  } catch (const std::exception& e) {
    throw ParamError("parameter " + resume_param + ": cannot read the checkpoint in " + output_dir +
                     ": " + e.what());
  }
}

void log_run_action(const core::RunAction& a) {
  using Level = core::RunAction::Level;
  if (a.repeating) {
    ROS_WARN_THROTTLE(5.0, "calibration: %s", a.text.c_str());
  } else if (a.level == Level::Error) {
    ROS_ERROR("calibration: %s", a.text.c_str());
  } else if (a.level == Level::Warn) {
    ROS_WARN("calibration: %s", a.text.c_str());
  } else {
    ROS_INFO("calibration: %s", a.text.c_str());
  }
}

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

bool write_result_files(const io::CheckpointFiles& files,
                        const std::vector<io::ExportFormat>& formats,
                        const core::CalibrationReport& report, const io::ResultContext& context) {
  if (!files.enabled()) return false;
  try {
    io::write_result_json(files.result_json_path(), report, context);
    io::write_result_yaml(files.result_path(), report, context);
    ROS_INFO("calibration: wrote %s and %s", files.result_json_path().c_str(),
             files.result_path().c_str());
  } catch (const io::IoError& e) {
    ROS_ERROR("calibration: %s", e.what());
    return false;
  }
  write_exports(files, formats, report);
  return true;
}

void archive_result_file(const std::string& archive, const std::string& device,
                         const std::string& rig, const std::string& result_path,
                         const std::string& table_path) {
  if (archive.empty()) return;
  std::vector<std::string> args = {"--archive",   archive,    "add",        result_path,
                                   "--positions", table_path, "--added-by", "calibration node"};
  if (!device.empty()) args.insert(args.end(), {"--device", device});
  if (!rig.empty()) args.insert(args.end(), {"--rig", rig});
  std::thread([args]() {
    const int status = run_package_script("archive", args);
    if (status != 0) {
      ROS_WARN("calibration: the result was not archived (%s exit status %d); it is in its file",
               package_script("archive").c_str(), status);
    }
  }).detach();
}

}  // namespace accel_intrinsics
