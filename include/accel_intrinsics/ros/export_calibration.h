// export_calibration: a saved result (offline_fit's JSON or the calibration node's
// intrinsics.yaml) written for another tool (io/exporters.h, docs/design.md section 7).
//
//   rosrun accel_intrinsics export_calibration --result RESULT --format NAME --out FILE
//
// src/nodes/export_calibration.cpp is the command line; tests call run_export_calibration().
#pragma once

#include <iosfwd>
#include <string>

namespace accel_intrinsics {

constexpr char kExportCalibrationProgram[] = "export_calibration";

struct ExportCalibrationArguments {
  std::string result;  // result file (JSON or YAML)
  std::string format;  // io::export_format_list()
  std::string out;     // file to write
};

// 0 on success (the file written atomically, what the format leaves out as one "note:" line on
// `err`); 1 on bad input (unreadable result, unknown format, a result no format can hold), with
// exactly one line "export_calibration: error: ..." on `err` and no file written.
int run_export_calibration(const ExportCalibrationArguments& args, std::ostream& err);

}  // namespace accel_intrinsics
