// Dwell means: the streaming accumulator, the position table and its CSV form
// (docs/design.md section 2:
// phase,step,angle_rad,t_start,t_end,n,mean_u,mean_v,mean_w,std_u,std_v,std_w, optionally
// followed by f_x,f_y,f_z: a known orientation, section 6, and by the columns of the per-dwell
// channels, dwell_record.h: temperature_c, the dwell's mean temperature, section 10).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdint>
#include <iosfwd>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_record.h"
#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {

// Numerically stable running mean and variance (Welford), constant memory.
class DwellAccumulator {
 public:
  void add(const Eigen::Vector3d& outputs);
  void reset();
  std::uint64_t count() const { return n_; }
  Eigen::Vector3d mean() const { return mean_; }
  // Sample standard deviation (n - 1 denominator); zero for fewer than two samples.
  Eigen::Vector3d sample_std() const;

 private:
  std::uint64_t n_ = 0;
  Eigen::Vector3d mean_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d m2_ = Eigen::Vector3d::Zero();
};

// The unit specific force of a row in the DUT frame: its direction, or the gimbal's
// in_plane_direction(phase, angle).
Eigen::Vector3d specific_force_direction(const DwellRecord& row);

struct PositionTable {
  std::vector<DwellRecord> rows;
  // t0 of the drift term: the first gimbal command when known (bags, the node, the simulator);
  // NaN means "unknown", and the earliest t_start is used instead (a CSV from elsewhere).
  double time_origin_s = std::numeric_limits<double>::quiet_NaN();
};

class PositionTableError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The CSV header line, exactly as in the contract, and its extension for known orientations.
extern const char* const kPositionTableHeader;
extern const char* const kDirectionColumns;  // ",f_x,f_y,f_z"

// The optional columns of a table: f_x,f_y,f_z, then one column per channel (kChannels order).
struct TableColumns {
  bool directions = false;
  PerChannel<bool> channels{};
  // The header line (without newline): kPositionTableHeader, then the optional columns.
  std::string header() const;
  // Every column of `other` is here too.
  bool covers(const TableColumns& other) const;
  bool operator==(const TableColumns& other) const {
    return directions == other.directions && channels == other.channels;
  }
};
// The columns a table needs: directions when a row has one, a channel when a row has a value.
TableColumns columns_needed(const PositionTable& table);
TableColumns columns_needed(const DwellRecord& row);
// The columns of a header line; throws PositionTableError for any other header.
TableColumns parse_header(const std::string& line, const std::string& source_name = "CSV");

// Reads a position table. Throws PositionTableError naming the line number and the field for a
// missing header, wrong column count, unparsable or non-finite number, unknown phase, n = 0.
PositionTable read_position_table(std::istream& in, const std::string& source_name = "CSV");
PositionTable read_position_table_file(const std::string& path);
// Writes with full double precision (round trip exact), with the columns the rows need.
void write_position_table(std::ostream& out, const PositionTable& table);
void write_position_table(std::ostream& out, const PositionTable& table,
                          const TableColumns& columns);
void write_position_table_file(const std::string& path, const PositionTable& table);
// Appends one row (no header) in `columns` and flushes: the checkpoint of a completed dwell.
// Values of columns not in `columns` are not written.
void write_position_row(std::ostream& out, const DwellRecord& row, const TableColumns& columns);

// The one rule for the direction of approach of a visit, from the order of visits per phase: the
// first visit of a phase is +1, a higher angle than the previous visit +1, a lower one -1, and
// the same angle again means the sweep turned there (the opposite of the previous approach).
class ApproachTracker {
 public:
  // The approach of a visit to `angle_rad` in `phase` after the visits seen so far.
  int approach_of(Phase phase, double angle_rad) const;
  // approach_of(), and records the visit.
  int visit(Phase phase, double angle_rad);

 private:
  bool seen_[3] = {false, false, false};
  double previous_angle_[3] = {0.0, 0.0, 0.0};
  int previous_approach_[3] = {+1, +1, +1};
};

// Dwells of a retried position (docs/design.md section 4, the calibration run): after a fault in a
// dwell, the calibration node has the controller measure the position again and discards the
// dwell the fault cut short. A table assembled from the commands alone (a bag) holds both, one
// after the other at the same (phase, step). The earlier of such a pair is superseded, except at
// the turn of a two-way sweep, where the same step is visited twice in a row by design (the
// previous dwell of the phase lies below it and the next one below too); a run of more than two
// visits there leaves it open which was cut short (the commands do not carry the approach): the
// visits with the fewest samples are taken as cut short (`by_samples` counts those).
struct SupersededRows {
  std::vector<std::size_t> rows;  // indices into the table, ascending
  std::size_t by_samples = 0;
};
SupersededRows find_remeasured_rows(const PositionTable& table);
// The table without the rows `rows` (indices, ascending).
PositionTable without_rows(PositionTable table, const std::vector<std::size_t>& rows);

// T_ref of the temperature terms (docs/design.md section 10): the mean of the dwell temperatures
// over the rows that have one; NaN when none has.
double reference_temperature_c(const PositionTable& table);
// Rows with a temperature (DwellRecord::has_temperature).
std::size_t rows_with_temperature(const PositionTable& table);

// The model's per-dwell inputs of one row (mid-dwell time relative to t0, angle, phase, approach,
// temperature relative to `reference_temperature_c` when the row has one).
DwellGeometry dwell_inputs(
    const DwellRecord& row, double time_origin_s, int approach,
    double reference_temperature_c = std::numeric_limits<double>::quiet_NaN());

// The model's per-dwell inputs of each row (dwell_inputs), the approach from ApproachTracker.
std::vector<DwellGeometry> dwell_geometries(const PositionTable& table);

// The approach of a row at `angle_rad` in `phase` that would be appended to `table`.
int approach_of_appended_row(const PositionTable& table, Phase phase, double angle_rad);
double effective_time_origin(const PositionTable& table);

// Gimbal dwells per phase (rows with a direction of their own are not counted).
std::array<int, 3> positions_per_phase(const PositionTable& table);
// Rows that give their orientation as a direction (f_x,f_y,f_z).
std::size_t rows_with_direction(const PositionTable& table);
// Rows of unknown orientation (rests of a hand tumble).
std::size_t rows_with_unknown_orientation(const PositionTable& table);
// The same dwells with their orientations forgotten (--unknown-orientations): every row becomes a
// rest of unknown orientation, so only the tumble fit (|P (mean - O)| = g) can take them.
PositionTable forget_orientations(PositionTable table);

}  // namespace core
}  // namespace accel_intrinsics
