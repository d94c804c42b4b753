// The result files a calibration node writes into its output_dir, one implementation for the
// gimbal node and the tumble node: result.json and intrinsics.yaml (one document, io::
// write_result_json/yaml) and the exports of
// ~exports (none for a result that fails the quality gate). Errors are logged, not thrown: a
// file that cannot be written must not stop a running stand.
#pragma once

#include <string>
#include <vector>

#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/core/run/calibration_run.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/checkpoint.h"
#include "accel_intrinsics/io/exporters.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {

// ~resume: reloads the checkpoint of `files` (in `output_dir`; later rows are appended to it)
// into `run` and returns the run's actions (none when
// there is no checkpoint: a fresh run). A checkpoint that cannot be read is not silently replaced
// by a fresh run: throws ParamError naming `resume_param`.
core::RunActions restore_from_checkpoint(io::CheckpointFiles* files, const std::string& output_dir,
                                         core::CalibrationRun* run,
                                         const std::string& resume_param);

// The run's Log action as a ROS log line at its level ("repeating" ones throttled).
void log_run_action(const core::RunAction& action);

void write_exports(const io::CheckpointFiles& files, const std::vector<io::ExportFormat>& formats,
                   const core::CalibrationReport& report);

// result.json and intrinsics.yaml, then the exports; nothing when the files are disabled (no
// output_dir). Returns whether intrinsics.yaml was written.
bool write_result_files(const io::CheckpointFiles& files,
                        const std::vector<io::ExportFormat>& formats,
                        const core::CalibrationReport& report, const io::ResultContext& context);

// scripts/archive add of a result file just written (with its position table), on a detached
// thread: the script takes a second or two, and a failure is a warning (the result is in its
// file). Nothing when `archive` (the URL) is empty.
void archive_result_file(const std::string& archive, const std::string& device,
                         const std::string& rig, const std::string& result_path,
                         const std::string& table_path);

}  // namespace accel_intrinsics
