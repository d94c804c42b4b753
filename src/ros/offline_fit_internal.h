// What accel_intrinsics_fit reads and how it fails, shared by the readers (offline_fit_input.cpp)
// and the command (offline_fit.cpp). Not installed.
#pragma once

#include <optional>
#include <ostream>
#include <string>

#include "accel_intrinsics/core/analysis/raw_stream_analysis.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace accel_intrinsics {
namespace offline_fit_detail {

// A failure with its exit status; the message is printed as one line.
struct Failure {
  int status;
  std::string message;
};

// What was read, whatever the source.
struct Input {
  core::PositionTable table;
  io::ResultContext context;  // input description, complete, warnings
  bool from_bag = false;
  core::RawStreams raw;  // bag with --analyze: for the timing-lag estimate
  // From the run's long rest (docs/design.md section 12: a dwell at least 10 times the median),
  // when the input has raw samples (a bag): what the fit and the analysis weight the dwells with.
  std::optional<core::NoiseModel> noise_model;
  std::string read_as;  // how the input was taken, when not obvious (prefixes a fit failure)
};

// offline_fit_input.cpp: the three inputs (a position table CSV, a samples file, bags).
Input read_csv_input(const OfflineFitArguments& args);
Input read_samples_input(const OfflineFitArguments& args);
Input read_bag_input(const OfflineFitArguments& args, std::ostream& err);

}  // namespace offline_fit_detail
}  // namespace accel_intrinsics
