// Dwell means: the streaming accumulator, the position table and its CSV form
// (DESIGN.md section 2:
// phase,step,angle_rad,t_start,t_end,n,mean_u,mean_v,mean_w,std_u,std_v,std_w, optionally
// followed by f_x,f_y,f_z: a known orientation, section 6, and/or temperature_c: the dwell's mean
// temperature, section 10).
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

#include "accel_intrinsics/core/model.h"
#include "accel_intrinsics/core/protocol.h"

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

// One row of the position table: the statistics of one dwell.
struct DwellRecord {
  Phase phase = Phase::X;
  std::uint32_t step = 0;
  double angle_rad = 0.0;
  double t_start_s = 0.0;
  double t_end_s = 0.0;
  std::uint64_t n = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();  // R_u, R_v, R_w, m/s^2
  Eigen::Vector3d std = Eigen::Vector3d::Zero();   // sample standard deviation, m/s^2
  // A known orientation instead of (phase, angle) (DESIGN.md section 6: position table columns
  // f_x,f_y,f_z, phase "-"): the unit specific force in the DUT frame. phase, step and angle are
  // then labels without meaning; only the joint fit takes such rows.
  bool has_direction = false;
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();
  // A rest of unknown orientation (DESIGN.md section 11: a hand tumble, or a gimbal run fitted
  // with --unknown-orientations): phase "-" without f_x,f_y,f_z. Only the tumble fit takes such
  // rows; phase, step and angle are labels without meaning.
  bool orientation_unknown = false;
  // Mean temperature of the dwell in degrees C (imu/temperature, column temperature_c); NaN when
  // none was recorded.
  double temperature_c = std::numeric_limits<double>::quiet_NaN();
  bool has_temperature() const { return std::isfinite(temperature_c); }
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
extern const char* const kDirectionColumns;    // ",f_x,f_y,f_z"
extern const char* const kTemperatureColumn;    // ",temperature_c" (after f_x,f_y,f_z if both)

// Reads a position table. Throws PositionTableError naming the line number and the field for a
// missing header, wrong column count, unparsable or non-finite number, unknown phase, n = 0.
PositionTable read_position_table(std::istream& in, const std::string& source_name = "CSV");
PositionTable read_position_table_file(const std::string& path);
// Writes with full double precision (round trip exact).
void write_position_table(std::ostream& out, const PositionTable& table);
void write_position_table_file(const std::string& path, const PositionTable& table);
// Appends one row (no header) and flushes: the checkpoint of a completed dwell. With
// `temperature_column` the row ends with the temperature_c field (empty when not recorded).
void write_position_row(std::ostream& out, const DwellRecord& row, bool temperature_column = false);

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

// T_ref of the temperature terms (DESIGN.md section 10): the mean of the dwell temperatures over
// the rows that have one; NaN when none has.
double reference_temperature_c(const PositionTable& table);
// Rows with a temperature (DwellRecord::has_temperature).
std::size_t rows_with_temperature(const PositionTable& table);

// The model's per-dwell inputs of one row (mid-dwell time relative to t0, angle, phase, approach,
// temperature relative to `reference_temperature_c` when the row has one).
DwellGeometry dwell_inputs(const DwellRecord& row, double time_origin_s, int approach,
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
