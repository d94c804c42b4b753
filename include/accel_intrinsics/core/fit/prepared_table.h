// A position table prepared for fitting: what the fit's validators and solvers read of the table
// (per-row geometry, standard errors, per-phase counts and rows), derived from the rows once.
// fit() builds one per call; a caller that fits one table many times (the discrepancy analysis)
// builds it once and passes it to fit(const PreparedTable&, ...). The view depends on the table
// alone: what a fit's options change (the slow part's inflation or correlation of the weights,
// fit.cpp) is derived from it by the fit.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/model/model.h"

namespace accel_intrinsics {
namespace core {

class PreparedTable {
 public:
  // Reads `table`, which must outlive the view (it is referred to, not copied).
  explicit PreparedTable(const PositionTable& table);
  PreparedTable(PositionTable&&) = delete;  // a view of a temporary would dangle

  const PositionTable& table() const { return *table_; }
  std::size_t size() const { return table_->rows.size(); }
  const DwellRecord& row(std::size_t i) const { return table_->rows[i]; }

  // Unit specific force of row i in the DUT frame (specific_force_direction): its f_x,f_y,f_z,
  // or the gimbal's in_plane_direction(phase, angle). Zero for a rest of unknown orientation.
  const Eigen::Vector3d& direction(std::size_t i) const { return directions_[i]; }
  // The model's per-dwell inputs of each row (dwell_geometries: time, approach, temperature).
  const std::vector<DwellGeometry>& geometries() const { return geometries_; }
  // Standard error of each dwell mean (dwell_standard_errors), and whether some accelerometer
  // had no row with a usable std and fell back to unit weights (noise-free or std-less data).
  const std::vector<Eigen::Vector3d>& standard_errors() const { return standard_errors_; }
  bool unit_weights() const { return unit_weights_; }

  // Gimbal dwells per phase (positions_per_phase) and their row indices, in table order.
  const std::array<int, 3>& positions_per_phase() const { return positions_per_phase_; }
  const std::vector<std::size_t>& phase_rows(Phase p) const { return phase_rows_[index(p)]; }
  std::size_t rows_with_direction() const { return rows_with_direction_; }
  std::size_t rows_with_unknown_orientation() const { return rows_with_unknown_orientation_; }

 private:
  const PositionTable* table_;
  std::vector<Eigen::Vector3d> directions_;
  std::vector<DwellGeometry> geometries_;
  std::vector<Eigen::Vector3d> standard_errors_;
  bool unit_weights_ = false;
  std::array<int, 3> positions_per_phase_{{0, 0, 0}};
  std::array<std::vector<std::size_t>, 3> phase_rows_;
  std::size_t rows_with_direction_ = 0;
  std::size_t rows_with_unknown_orientation_ = 0;
};

// How many PreparedTable views this process has built: a test's check that a fit prepares its
// table once.
std::uint64_t prepared_table_builds();

}  // namespace core
}  // namespace accel_intrinsics
