#include "accel_intrinsics/io/checkpoint.h"

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <iterator>
#include <sstream>

#include "accel_intrinsics/io/atomic_file.h"

namespace accel_intrinsics {
namespace io {

CheckpointFiles::CheckpointFiles(std::string output_dir, std::string file_prefix)
    : dir_(std::move(output_dir)), prefix_(std::move(file_prefix)) {}

std::string CheckpointFiles::path(const char* name) const {
  if (dir_.empty()) return "";
  return (std::filesystem::path(dir_) / (prefix_ + name)).string();
}

void CheckpointFiles::append_row(const core::DwellRecord& row) {
  if (!enabled()) return;
  const core::TableColumns needed = core::columns_needed(row);
  if (!table_.is_open()) {
    std::error_code ec;
    const bool has_content = std::filesystem::exists(table_path()) &&
                             std::filesystem::file_size(table_path(), ec) > 0 && !ec;
    const bool continued = append_ && has_content;
    columns_ = needed;
    if (continued) {
      std::ifstream existing(table_path());
      std::string header;
      std::getline(existing, header);
      try {
        columns_ = core::parse_header(header, table_path());
      } catch (const std::exception& e) {
        throw IoError(e.what());
      }
    }
    table_.open(table_path(),
                append_ ? std::ios::out | std::ios::app : std::ios::out | std::ios::trunc);
    if (!table_) throw IoError("cannot write '" + table_path() + "'");
    if (!continued) table_ << columns_.header() << '\n';
  }
  if (!columns_.covers(needed)) widen(needed);
  // flushed: the checkpoint of this dwell
  core::write_position_row(table_, row, columns_);
  if (!table_) throw IoError("cannot write '" + table_path() + "' (disk full?)");
}

void CheckpointFiles::widen(const core::TableColumns& needed) {
  // A channel that starts late (no reading in the first dwells): the table so far is rewritten
  // with its column (empty in the earlier rows), so the later values are kept.
  table_.close();
  core::PositionTable so_far;
  try {
    so_far = core::read_position_table_file(table_path());
  } catch (const std::exception& e) {
    throw IoError(e.what());
  }
  columns_.directions = columns_.directions || needed.directions;
  for (std::size_t c = 0; c < core::kChannelCount; ++c)
    columns_.channels[c] = columns_.channels[c] || needed.channels[c];
  std::ostringstream text;
  core::write_position_table(text, so_far, columns_);
  write_file_atomically(table_path(), text.str());
  table_.open(table_path(), std::ios::out | std::ios::app);
  if (!table_) throw IoError("cannot write '" + table_path() + "'");
}

void CheckpointFiles::write_state(const core::CheckpointState& state) {
  if (!enabled()) return;
  YAML::Emitter y;
  y << YAML::BeginMap;
  y << YAML::Key << "time_origin_s" << YAML::Value << YAML::Precision(17) << state.time_origin_s;
  y << YAML::Key << "steps" << YAML::Value << state.steps;
  y << YAML::Key << "rows" << YAML::Value << state.rows;
  y << YAML::Key << "done" << YAML::Value << state.done;
  y << YAML::Key << "fault" << YAML::Value << state.fault;
  y << YAML::EndMap;
  write_file_atomically(state_path(), std::string("# accel_intrinsics calibration checkpoint (with "
                                                  "position_table.csv)\n") +
                                          y.c_str() + "\n");
}

void CheckpointFiles::clear() {
  if (table_.is_open()) table_.close();
  append_ = false;
  if (!enabled()) return;
  std::error_code ec;
  std::filesystem::remove(state_path(), ec);
  std::filesystem::remove(table_path(), ec);
}

std::optional<CheckpointFiles::Restored> CheckpointFiles::load() {
  if (!enabled() || !std::filesystem::exists(state_path())) return std::nullopt;
  Restored r;
  try {
    const YAML::Node state = YAML::LoadFile(state_path());
    r.state.time_origin_s = state["time_origin_s"].as<double>();
    r.state.steps = state["steps"].as<std::uint32_t>();
    r.state.done = state["done"] && state["done"].as<bool>();
    r.state.fault = state["fault"] ? state["fault"].as<std::string>() : "";
  } catch (const std::exception& e) {
    throw IoError("cannot read the checkpoint '" + state_path() + "': " + e.what());
  }
  if (std::filesystem::exists(table_path())) {
    std::string text;
    {
      std::ifstream in(table_path(), std::ios::binary);
      text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    if (!text.empty() && text.back() != '\n') {
      // Killed in the middle of a line: drop it (its dwell is measured again).
      const std::size_t last_newline = text.rfind('\n');
      text.erase(last_newline == std::string::npos ? 0 : last_newline + 1);
      write_file_atomically(table_path(), text);
      r.dropped_torn_line = true;
    }
    if (!text.empty()) {
      std::istringstream in(text);
      try {
        r.table = core::read_position_table(in, table_path());
      } catch (const std::exception& e) {
        throw IoError(e.what());
      }
    }
  }
  r.table.time_origin_s = r.state.time_origin_s;
  r.state.rows = r.table.rows.size();
  append_ = true;
  return r;
}

}  // namespace io
}  // namespace accel_intrinsics
