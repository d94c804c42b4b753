#include "accel_intrinsics/ros/export_calibration.h"

#include <ostream>

#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/exporters.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace accel_intrinsics {

int run_export_calibration(const ExportCalibrationArguments& args, std::ostream& err) {
  const std::string program = kExportCalibrationProgram;
  try {
    const io::ExportFormat format = io::parse_export_format(args.format);
    if (args.out.empty()) throw io::IoError("--out FILE is required");
    if (args.out == args.result) throw io::IoError("--out would overwrite the result file");
    const io::StoredResult result = io::read_result_file(args.result);
    const io::ExportText text =
        io::write_export(args.out, format, io::calibration_to_export(result, args.result));
    if (!text.notice.empty()) err << program << ": note: " << text.notice << std::endl;
    return 0;
  } catch (const std::exception& e) {
    err << program << ": error: " << as_one_line(e.what()) << std::endl;
    return 1;
  }
}

}  // namespace accel_intrinsics
