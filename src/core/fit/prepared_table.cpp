// The prepared view of a position table (prepared_table.h).
#include "accel_intrinsics/core/fit/prepared_table.h"

#include <atomic>

#include "fit_internal.h"

namespace accel_intrinsics {
namespace core {

namespace {

std::atomic<std::uint64_t> builds{0};

}  // namespace

PreparedTable::PreparedTable(const PositionTable& table)
    : table_(&table), geometries_(dwell_geometries(table)) {
  ++builds;
  standard_errors_ = dwell_standard_errors(table, &unit_weights_);
  directions_.reserve(table.rows.size());
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    const DwellRecord& row = table.rows[i];
    rows_with_direction_ += row.has_direction ? 1 : 0;
    rows_with_unknown_orientation_ += row.orientation_unknown ? 1 : 0;
    const bool known = row.has_direction || !row.orientation_unknown;
    directions_.push_back(known ? specific_force_direction(row) : Eigen::Vector3d::Zero());
    if (row.has_direction || row.orientation_unknown) continue;
    ++positions_per_phase_[index(row.phase)];
    phase_rows_[index(row.phase)].push_back(i);
  }
}

std::uint64_t prepared_table_builds() {
  return builds.load();
}

}  // namespace core
}  // namespace accel_intrinsics
