// Every run keeps its own directory (docs/design.md section 15, "Every run keeps its own
// directory"): output_dir/<device>/<UTC time, ISO 8601 basic>/ holds the run's result.json,
// intrinsics.yaml, position_table.csv, checkpoint, exports and certificate, and
// output_dir/<device>/latest is a symbolic link to the newest run, replaced atomically (a new
// link renamed over the old one). Nothing here deletes an earlier run.
#pragma once

#include <string>

namespace accel_intrinsics {
namespace io {

// The serial used when none is given (the calibration node's device_serial default).
constexpr const char* kUnnamedDevice = "unnamed";

// UTC time of `unix_s` in ISO 8601 basic format, whole seconds: "20261127T141502Z".
std::string utc_basic_time(double unix_s);
// UTC time of `unix_s` in ISO 8601 extended format, whole seconds: "2026-11-27T14:15:02Z".
std::string utc_iso_time(double unix_s);
// The device serial as one directory name: characters other than letters, digits, '-', '_',
// '.' and '+' become '_'; an empty serial, "." and ".." become kUnnamedDevice. The serial itself
// is written unchanged into the outputs; only the directory name is sanitized.
std::string device_directory_name(const std::string& serial);

class RunDirectories {
 public:
  // An empty base disables every call (returns empty paths).
  explicit RunDirectories(std::string base) : base_(std::move(base)) {}

  bool enabled() const { return !base_.empty(); }
  // base/<device>
  std::string device_dir(const std::string& serial) const;
  // base/<device>/latest (the link's own path)
  std::string latest_link(const std::string& serial) const;
  // Creates base/<device>/<utc_basic_time(unix_s)>/ (with a suffix "-2", "-3"... when a run of
  // the same second exists: an existing directory is never reused) and points `latest` at it.
  // Returns the new directory. Throws IoError naming the path.
  std::string start_run(const std::string& serial, double unix_s) const;
  // The directory `latest` points to, or "" when there is none (or it points nowhere).
  std::string latest_run(const std::string& serial) const;

 private:
  std::string base_;
};

}  // namespace io
}  // namespace accel_intrinsics
