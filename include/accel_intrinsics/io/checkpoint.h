// The calibration run's checkpoint in output_dir, so that nothing measured is lost when the node
// dies (docs/design.md section 4, "io"):
//   <prefix>position_table.csv      the accepted rows, one flushed line per dwell (the contract's
//                                   position table); a channel that starts late widens it
//   <prefix>calibration_state.yaml  time_origin_s, steps, rows, done, fault; atomic rewrite
// and the names of the node's other files there (result YAML, analysis JSON).
#pragma once

#include <fstream>
#include <optional>
#include <string>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/run/calibration_run.h"

namespace accel_intrinsics {
namespace io {

class CheckpointFiles {
 public:
  // An empty directory disables every file (all calls do nothing, paths are empty).
  CheckpointFiles(std::string output_dir, std::string file_prefix);

  bool enabled() const { return !dir_.empty(); }
  std::string table_path() const { return path("position_table.csv"); }
  std::string state_path() const { return path("calibration_state.yaml"); }
  std::string result_path() const { return path("intrinsics.yaml"); }
  // The same document as JSON (io::write_result_json; supervise --json prints it).
  std::string result_json_path() const { return path("result.json"); }
  std::string analysis_path() const { return path("analysis.json"); }
  // Any other file of the run in output_dir, e.g. an export (io::export_file_name).
  std::string file_path(const char* name) const { return path(name); }

  // Appends one row and flushes it. The first row after construction or clear() starts a new
  // file with the header; after load() rows are appended to the restored table. Throws IoError.
  void append_row(const core::DwellRecord& row);
  // Rewrites the state file atomically. Throws IoError.
  void write_state(const core::CheckpointState& state);
  // Removes both files (a new run starts).
  void clear();

  struct Restored {
    core::PositionTable table;
    core::CheckpointState state;
    bool dropped_torn_line = false;  // a kill mid-line left an incomplete last row: dropped
  };
  // The checkpoint, or nothing when there is no state file. An incomplete last line of the
  // table (killed while writing) is dropped from the file. Throws IoError naming the file when
  // it cannot be read: a broken checkpoint is never silently replaced by a fresh run.
  std::optional<Restored> load();

 private:
  std::string path(const char* name) const;
  // Rewrites the table so far with the columns of `needed` added.
  void widen(const core::TableColumns& needed);

  std::string dir_, prefix_;
  std::ofstream table_;
  bool append_ = false;  // after load(): continue the restored table
  // The table's columns: the header of a continued table, else those of the first row; widened
  // when a later row has a value in a column the table lacks.
  core::TableColumns columns_;
};

}  // namespace io
}  // namespace accel_intrinsics
