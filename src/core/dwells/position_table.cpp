#include "accel_intrinsics/core/dwells/position_table.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <istream>
#include <limits>
#include <ostream>
#include <sstream>

namespace accel_intrinsics {
namespace core {

// ---- DwellAccumulator (Welford) ----------------------------------------------------------------

void DwellAccumulator::add(const Eigen::Vector3d& outputs) {
  ++n_;
  const Eigen::Vector3d delta = outputs - mean_;
  mean_ += delta / static_cast<double>(n_);
  m2_ += delta.cwiseProduct(outputs - mean_);
}

void DwellAccumulator::reset() {
  n_ = 0;
  mean_.setZero();
  m2_.setZero();
}

Eigen::Vector3d DwellAccumulator::sample_std() const {
  if (n_ < 2) return Eigen::Vector3d::Zero();
  return (m2_ / static_cast<double>(n_ - 1)).cwiseMax(0.0).cwiseSqrt();
}

// ---- CSV ---------------------------------------------------------------------------------------

const char* const kPositionTableHeader =
    "phase,step,angle_rad,t_start,t_end,n,mean_u,mean_v,mean_w,std_u,std_v,std_w";
const char* const kDirectionColumns = ",f_x,f_y,f_z";

namespace {

constexpr int kColumns = 12;
const char* const kColumnNames[15] = {"phase", "step",   "angle_rad", "t_start", "t_end",
                                      "n",     "mean_u", "mean_v",    "mean_w",  "std_u",
                                      "std_v", "std_w",  "f_x",       "f_y",     "f_z"};

std::string trim(const std::string& s) {
  const auto begin = s.find_first_not_of(" \t\r\n");
  if (begin == std::string::npos) return "";
  const auto end = s.find_last_not_of(" \t\r\n");
  return s.substr(begin, end - begin + 1);
}

[[noreturn]] void fail(const std::string& source, std::size_t line, const std::string& what) {
  throw PositionTableError(source + " line " + std::to_string(line) + ": " + what);
}

double parse_double(const std::string& field, const std::string& source, std::size_t line,
                    const char* column) {
  const std::string text = trim(field);
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(text.c_str(), &end);
  // ERANGE alone is not an error: an underflow to a denormal or zero is still a number, and an
  // overflow comes back as infinity, which the finiteness check below rejects.
  if (text.empty() || end != text.c_str() + text.size()) {
    fail(source, line, std::string("field ") + column + " is not a number: '" + text + "'");
  }
  if (!std::isfinite(value)) fail(source, line, std::string("field ") + column + " is not finite");
  return value;
}

std::uint64_t parse_count(const std::string& field, const std::string& source, std::size_t line,
                          const char* column) {
  const std::string text = trim(field);
  if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos) {
    fail(source, line,
         std::string("field ") + column + " must be a non-negative integer, got '" + text + "'");
  }
  errno = 0;
  const unsigned long long value = std::strtoull(text.c_str(), nullptr, 10);
  if (errno == ERANGE) fail(source, line, std::string("field ") + column + " is too large");
  return value;
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  std::istringstream stream(line);
  while (std::getline(stream, field, ',')) fields.push_back(field);
  if (!line.empty() && line.back() == ',') fields.emplace_back();
  return fields;
}

std::string expected_header() {
  std::string channels;
  for (const ChannelSpec& spec : kChannels) channels += std::string(" ,") + spec.column;
  return std::string("expected the header '") + kPositionTableHeader + "' (optionally + '" +
         kDirectionColumns + "', then any of the channel columns:" + channels + ")";
}

// Where each optional column stands among the fields of a row.
struct FieldLayout {
  TableColumns columns;
  int count = kColumns;
  int direction = -1;               // index of f_x
  PerChannel<int> channel_field{};  // index of each channel's column, -1 without
};

FieldLayout layout_of(const std::string& header, const std::string& source, std::size_t line) {
  FieldLayout layout;
  layout.channel_field.fill(-1);
  const std::string base = kPositionTableHeader;
  if (header.compare(0, base.size(), base) != 0 ||
      (header.size() > base.size() && header[base.size()] != ','))
    fail(source, line, expected_header());
  std::vector<std::string> names = split(header.substr(base.size()));
  if (!names.empty()) names.erase(names.begin());  // before the first ','
  std::size_t k = 0;
  if (names.size() >= 3 && trim(names[0]) == "f_x" && trim(names[1]) == "f_y" &&
      trim(names[2]) == "f_z") {
    layout.columns.directions = true;
    layout.direction = kColumns;
    k = 3;
  }
  // The channel columns follow, in any order, each at most once.
  for (; k < names.size(); ++k) {
    const ChannelSpec* spec = channel_by_column(trim(names[k]));
    if (spec == nullptr)
      fail(source, line, "unknown column '" + trim(names[k]) + "'; " + expected_header());
    const std::size_t c = channel_index(spec->id);
    if (layout.columns.channels[c])
      fail(source, line, std::string("column ") + spec->column + " twice");
    layout.columns.channels[c] = true;
    layout.channel_field[c] = kColumns + static_cast<int>(k);
  }
  layout.count = kColumns + static_cast<int>(names.size());
  return layout;
}

}  // namespace

std::string TableColumns::header() const {
  std::string line = kPositionTableHeader;
  if (directions) line += kDirectionColumns;
  for (const ChannelSpec& spec : kChannels)
    if (channels[channel_index(spec.id)]) line += std::string(",") + spec.column;
  return line;
}

bool TableColumns::covers(const TableColumns& other) const {
  if (other.directions && !directions) return false;
  for (std::size_t c = 0; c < kChannelCount; ++c)
    if (other.channels[c] && !channels[c]) return false;
  return true;
}

TableColumns columns_needed(const DwellRecord& row) {
  TableColumns columns;
  columns.directions = row.has_direction;
  for (const ChannelSpec& spec : kChannels)
    columns.channels[channel_index(spec.id)] = has_value(row, spec);
  return columns;
}

TableColumns columns_needed(const PositionTable& table) {
  TableColumns columns;
  for (const DwellRecord& row : table.rows) {
    const TableColumns of_row = columns_needed(row);
    columns.directions = columns.directions || of_row.directions;
    for (std::size_t c = 0; c < kChannelCount; ++c)
      columns.channels[c] = columns.channels[c] || of_row.channels[c];
  }
  return columns;
}

TableColumns parse_header(const std::string& line, const std::string& source_name) {
  return layout_of(trim(line), source_name, 1).columns;
}

PositionTable read_position_table(std::istream& in, const std::string& source_name) {
  PositionTable table;
  std::string line;
  std::size_t line_number = 0;
  bool have_header = false;
  FieldLayout layout;
  while (std::getline(in, line)) {
    ++line_number;
    // A UTF-8 byte-order mark, as spreadsheet programs write, is not part of the header.
    if (line_number == 1 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);
    const std::string text = trim(line);
    if (text.empty() || text[0] == '#') continue;
    if (!have_header) {
      layout = layout_of(text, source_name, line_number);
      have_header = true;
      continue;
    }
    const std::vector<std::string> fields = split(text);
    if (static_cast<int>(fields.size()) != layout.count) {
      fail(source_name, line_number,
           "expected " + std::to_string(layout.count) + " fields, found " +
               std::to_string(fields.size()));
    }
    DwellRecord row;
    // Known orientation: f_x,f_y,f_z all given (all empty: a gimbal row).
    if (layout.direction >= 0) {
      const int d = layout.direction;
      const bool any =
          !trim(fields[d]).empty() || !trim(fields[d + 1]).empty() || !trim(fields[d + 2]).empty();
      if (any) {
        for (int k = 0; k < 3; ++k)
          row.direction(k) =
              parse_double(fields[d + k], source_name, line_number, kColumnNames[12 + k]);
        const double norm = row.direction.norm();
        if (std::abs(norm - 1.0) > 0.01) {
          std::ostringstream m;
          m << "f_x,f_y,f_z must be a unit vector (the direction of the specific force), its "
               "norm is "
            << norm;
          fail(source_name, line_number, m.str());
        }
        row.direction /= norm;
        row.has_direction = true;
      }
    }
    const std::string phase = trim(fields[0]);
    if (phase == "-" && !row.has_direction) {
      // A rest of unknown orientation (hand tumble): angle_rad may be empty.
      row.orientation_unknown = true;
    } else if (phase != "-" && !parse_phase(phase, &row.phase)) {
      fail(source_name, line_number,
           "field phase must be x, y or z (or - for a known direction f_x,f_y,f_z or a rest of "
           "unknown orientation), got '" +
               phase + "'");
    }
    const std::uint64_t step = parse_count(fields[1], source_name, line_number, kColumnNames[1]);
    if (step > std::numeric_limits<std::uint32_t>::max())
      fail(source_name, line_number, "field step is too large");
    row.step = static_cast<std::uint32_t>(step);
    row.angle_rad = (row.has_direction || row.orientation_unknown) && trim(fields[2]).empty()
                        ? 0.0
                        : parse_double(fields[2], source_name, line_number, kColumnNames[2]);
    row.t_start_s = parse_double(fields[3], source_name, line_number, kColumnNames[3]);
    row.t_end_s = parse_double(fields[4], source_name, line_number, kColumnNames[4]);
    if (row.t_end_s < row.t_start_s)
      fail(source_name, line_number, "field t_end is before t_start");
    row.n = parse_count(fields[5], source_name, line_number, kColumnNames[5]);
    if (row.n == 0)
      fail(source_name, line_number, "field n is 0: a dwell without samples has no mean");
    for (int k = 0; k < 3; ++k)
      row.mean(k) = parse_double(fields[6 + k], source_name, line_number, kColumnNames[6 + k]);
    for (int k = 0; k < 3; ++k) {
      row.std(k) = parse_double(fields[9 + k], source_name, line_number, kColumnNames[9 + k]);
      if (row.std(k) < 0.0)
        fail(source_name, line_number,
             std::string("field ") + kColumnNames[9 + k] + " is negative");
    }
    // A channel's empty field: no reading during this dwell (allowed when the channel is
    // optional per row).
    for (const ChannelSpec& spec : kChannels) {
      const int f = layout.channel_field[channel_index(spec.id)];
      if (f < 0) continue;
      if (trim(fields[f]).empty()) {
        if (!spec.optional_per_row)
          fail(source_name, line_number, std::string("field ") + spec.column + " is empty");
        continue;
      }
      row.*spec.value = parse_double(fields[f], source_name, line_number, spec.column);
    }
    table.rows.push_back(row);
  }
  if (!have_header)
    throw PositionTableError(source_name + ": empty, expected the header '" + kPositionTableHeader +
                             "'");
  return table;
}

PositionTable read_position_table_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw PositionTableError("cannot open position table '" + path + "'");
  return read_position_table(in, path);
}

void write_position_row(std::ostream& out, const DwellRecord& row, const TableColumns& columns) {
  const auto precision = out.precision(std::numeric_limits<double>::max_digits10);
  out << (row.has_direction || row.orientation_unknown ? "-" : phase_name(row.phase)) << ','
      << row.step << ',' << row.angle_rad << ',' << row.t_start_s << ',' << row.t_end_s << ','
      << row.n;
  for (int k = 0; k < 3; ++k) out << ',' << row.mean(k);
  for (int k = 0; k < 3; ++k) out << ',' << row.std(k);
  if (columns.directions) {
    for (int k = 0; k < 3; ++k) {
      out << ',';
      if (row.has_direction) out << row.direction(k);
    }
  }
  for (const ChannelSpec& spec : kChannels) {
    if (!columns.channels[channel_index(spec.id)]) continue;
    out << ',';
    if (has_value(row, spec)) out << row.*spec.value;
  }
  out << '\n';
  out.flush();
  out.precision(precision);
}

void write_position_table(std::ostream& out, const PositionTable& table,
                          const TableColumns& columns) {
  out << columns.header() << '\n';
  for (const DwellRecord& row : table.rows) write_position_row(out, row, columns);
}

void write_position_table(std::ostream& out, const PositionTable& table) {
  write_position_table(out, table, columns_needed(table));
}

void write_position_table_file(const std::string& path, const PositionTable& table) {
  std::ofstream out(path);
  if (!out) throw PositionTableError("cannot write position table '" + path + "'");
  write_position_table(out, table);
  if (!out) throw PositionTableError("error while writing position table '" + path + "'");
}

// ---- Geometry ----------------------------------------------------------------------------------

double effective_time_origin(const PositionTable& table) {
  if (std::isfinite(table.time_origin_s)) return table.time_origin_s;
  double t0 = std::numeric_limits<double>::infinity();
  for (const DwellRecord& row : table.rows) t0 = std::min(t0, row.t_start_s);
  return std::isfinite(t0) ? t0 : 0.0;
}

int ApproachTracker::approach_of(Phase phase, double angle_rad) const {
  const int p = index(phase);
  if (!seen_[p] || angle_rad > previous_angle_[p]) return +1;
  if (angle_rad < previous_angle_[p]) return -1;
  return -previous_approach_[p];
}

int ApproachTracker::visit(Phase phase, double angle_rad) {
  const int approach = approach_of(phase, angle_rad);
  const int p = index(phase);
  seen_[p] = true;
  previous_angle_[p] = angle_rad;
  previous_approach_[p] = approach;
  return approach;
}

Eigen::Vector3d specific_force_direction(const DwellRecord& row) {
  return row.has_direction ? row.direction : in_plane_direction(row.phase, row.angle_rad);
}

double reference_temperature_c(const PositionTable& table) {
  double sum = 0.0;
  std::size_t n = 0;
  for (const DwellRecord& row : table.rows) {
    if (!row.has_temperature()) continue;
    sum += row.temperature_c;
    ++n;
  }
  return n > 0 ? sum / static_cast<double>(n) : std::numeric_limits<double>::quiet_NaN();
}

std::size_t rows_with_temperature(const PositionTable& table) {
  std::size_t n = 0;
  for (const DwellRecord& row : table.rows) n += row.has_temperature() ? 1 : 0;
  return n;
}

DwellGeometry dwell_inputs(const DwellRecord& row, double time_origin_s, int approach,
                           double reference_temperature_c) {
  DwellGeometry inputs;
  inputs.has_direction = row.has_direction;
  inputs.direction = row.direction;
  inputs.phase = row.phase;
  inputs.angle_rad = row.angle_rad;
  inputs.time_s = 0.5 * (row.t_start_s + row.t_end_s) - time_origin_s;
  inputs.approach = approach;
  inputs.has_temperature = row.has_temperature() && std::isfinite(reference_temperature_c);
  inputs.temperature_offset_k =
      inputs.has_temperature ? row.temperature_c - reference_temperature_c : 0.0;
  return inputs;
}

std::vector<DwellGeometry> dwell_geometries(const PositionTable& table) {
  const double t0 = effective_time_origin(table);
  const double t_ref = reference_temperature_c(table);
  std::vector<DwellGeometry> geometries;
  geometries.reserve(table.rows.size());
  ApproachTracker approach;
  for (const DwellRecord& row : table.rows) {
    const int a = row.has_direction ? +1 : approach.visit(row.phase, row.angle_rad);
    geometries.push_back(dwell_inputs(row, t0, a, t_ref));
  }
  return geometries;
}

int approach_of_appended_row(const PositionTable& table, Phase phase, double angle_rad) {
  ApproachTracker approach;
  for (const DwellRecord& row : table.rows) {
    if (!row.has_direction) approach.visit(row.phase, row.angle_rad);
  }
  return approach.approach_of(phase, angle_rad);
}

SupersededRows find_remeasured_rows(const PositionTable& table) {
  SupersededRows out;
  const std::vector<DwellRecord>& rows = table.rows;
  auto gimbal = [&](std::size_t i) {
    return !rows[i].has_direction && !rows[i].orientation_unknown;
  };
  auto same_position = [&](std::size_t i, std::size_t j) {
    return gimbal(i) && gimbal(j) && rows[i].phase == rows[j].phase && rows[i].step == rows[j].step;
  };
  std::size_t a = 0;
  while (a < rows.size()) {
    std::size_t b = a;  // [a, b]: consecutive visits of one position
    while (b + 1 < rows.size() && same_position(a, b + 1)) ++b;
    const std::size_t visits = b - a + 1;
    if (visits > 1) {
      const std::uint32_t step = rows[a].step;
      const bool lower_before =
          a == 0 || !gimbal(a - 1) || rows[a - 1].phase != rows[a].phase || rows[a - 1].step < step;
      const bool lower_after = b + 1 < rows.size() && gimbal(b + 1) &&
                               rows[b + 1].phase == rows[a].phase && rows[b + 1].step < step;
      const std::size_t kept = lower_before && lower_after ? 2 : 1;  // the turn: up and down
      if (kept == 1) {
        for (std::size_t i = a; i < b; ++i) out.rows.push_back(i);  // the last one is the retry
      } else if (visits > kept) {
        // The last visit is the return sweep's; of the others, all but the one with the most
        // samples were cut short.
        std::vector<std::size_t> earlier;
        for (std::size_t i = a; i < b; ++i) earlier.push_back(i);
        std::stable_sort(earlier.begin(), earlier.end(),
                         [&](std::size_t i, std::size_t j) { return rows[i].n < rows[j].n; });
        earlier.pop_back();
        out.rows.insert(out.rows.end(), earlier.begin(), earlier.end());
        out.by_samples += earlier.size();
      }
    }
    a = b + 1;
  }
  std::sort(out.rows.begin(), out.rows.end());
  return out;
}

PositionTable without_rows(PositionTable table, const std::vector<std::size_t>& rows) {
  std::size_t k = 0, kept = 0;
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    if (k < rows.size() && rows[k] == i) {
      ++k;
      continue;
    }
    table.rows[kept++] = table.rows[i];
  }
  table.rows.resize(kept);
  return table;
}

std::array<int, 3> positions_per_phase(const PositionTable& table) {
  std::array<int, 3> counts{{0, 0, 0}};
  for (const DwellRecord& row : table.rows) {
    if (!row.has_direction && !row.orientation_unknown) ++counts[index(row.phase)];
  }
  return counts;
}

std::size_t rows_with_direction(const PositionTable& table) {
  std::size_t n = 0;
  for (const DwellRecord& row : table.rows) n += row.has_direction ? 1 : 0;
  return n;
}

std::size_t rows_with_unknown_orientation(const PositionTable& table) {
  std::size_t n = 0;
  for (const DwellRecord& row : table.rows) n += row.orientation_unknown ? 1 : 0;
  return n;
}

PositionTable forget_orientations(PositionTable table) {
  for (DwellRecord& row : table.rows) {
    row.orientation_unknown = true;
    row.has_direction = false;
    row.direction.setZero();
  }
  return table;
}

}  // namespace core
}  // namespace accel_intrinsics
