// The result files a calibration node writes into its output_dir, one implementation for the
// gimbal node and the tumble node: intrinsics.yaml (io::write_result_yaml) and the exports of
// ~exports (none for a result that fails the quality gate). Errors are logged, not thrown: a
// file that cannot be written must not stop a running stand.
#pragma once

#include <string>
#include <vector>

#include "accel_intrinsics/core/calibrate.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/checkpoint.h"
#include "accel_intrinsics/io/exporters.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {

void write_exports(const io::CheckpointFiles& files, const std::vector<io::ExportFormat>& formats,
                   const core::CalibrationReport& report);

// intrinsics.yaml, then the exports; nothing when the files are disabled (no output_dir).
void write_result_files(const io::CheckpointFiles& files,
                        const std::vector<io::ExportFormat>& formats,
                        const core::CalibrationReport& report, const io::ResultContext& context);

// scripts/archive add of a result file just written (with its position table), on a detached
// thread: the script takes a second or two, and a failure is a warning (the result is in its
// file). Nothing when `archive` (the URL) is empty.
void archive_result_file(const std::string& archive, const std::string& device,
                         const std::string& rig, const std::string& result_path,
                         const std::string& table_path);

}  // namespace accel_intrinsics
