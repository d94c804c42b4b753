// libFuzzer target for the position-table CSV reader (docs/design.md section 2): arbitrary bytes
// must either be rejected with PositionTableError or parse into a table that survives a write/read
// round trip unchanged. Built and run by tools/fuzz.sh.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <sstream>
#include <string>

#include "accel_intrinsics/core/dwells/position_table.h"

namespace core = accel_intrinsics::core;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  core::PositionTable table;
  try {
    table = core::read_position_table(in, "fuzz");
  } catch (const core::PositionTableError&) {
    return 0;
  }
  for (const core::DwellRecord& row : table.rows) {
    // The reader promises finite values, n > 0, std >= 0 and t_end >= t_start.
    if (!row.mean.allFinite() || !row.std.allFinite() || !std::isfinite(row.angle_rad) ||
        row.n == 0 || row.t_end_s < row.t_start_s || (row.std.array() < 0.0).any()) {
      std::abort();
    }
  }
  (void)core::dwell_geometries(table);
  (void)core::positions_per_phase(table);
  std::stringstream buffer;
  core::write_position_table(buffer, table);
  const core::PositionTable back = core::read_position_table(buffer, "round trip");
  if (back.rows.size() != table.rows.size()) std::abort();
  for (std::size_t i = 0; i < back.rows.size(); ++i) {
    const auto& a = table.rows[i];
    const auto& b = back.rows[i];
    if (a.phase != b.phase || a.step != b.step || a.n != b.n || a.angle_rad != b.angle_rad ||
        a.t_start_s != b.t_start_s || a.t_end_s != b.t_end_s || a.mean != b.mean ||
        a.std != b.std) {
      std::abort();
    }
  }
  return 0;
}
