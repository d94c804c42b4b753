#include "accel_intrinsics/io/residuals_csv.h"

#include <iomanip>
#include <ostream>

#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/io/atomic_file.h"

namespace accel_intrinsics {
namespace io {

void write_residuals_csv(std::ostream& out, const core::PositionTable& table,
                         const core::FitResult& before_fit, const core::FitResult& after_fit) {
  const std::vector<core::DwellGeometry> geoms = core::dwell_geometries(table);
  // The weights of the fit (its standard errors when it kept them).
  const std::vector<Eigen::Vector3d> se = before_fit.standard_errors.size() == table.rows.size()
                                              ? before_fit.standard_errors
                                              : core::dwell_standard_errors(table);
  const core::Device before = core::device_from_fit(before_fit);
  const core::Device after = core::device_from_fit(after_fit);
  out << "phase,step,angle_rad,time_s,approach,accelerometer,measured,sigma,"
         "model_before,residual_before,z_before,model_after,residual_after,z_after\n";
  out << std::setprecision(12);
  for (std::size_t r = 0; r < table.rows.size(); ++r) {
    const core::DwellRecord& row = table.rows[r];
    const Eigen::Vector3d mb = core::predict_outputs(before, geoms[r], before_fit.local_gravity);
    const Eigen::Vector3d ma = core::predict_outputs(after, geoms[r], after_fit.local_gravity);
    for (int s = 0; s < 3; ++s) {
      const double rb = row.mean(s) - mb(s);
      const double ra = row.mean(s) - ma(s);
      out << (row.has_direction ? "-" : core::phase_name(row.phase)) << ',' << row.step << ','
          << row.angle_rad << ',' << geoms[r].time_s << ',' << geoms[r].approach << ','
          << core::accelerometer_name(s) << ',' << row.mean(s) << ',' << se[r](s) << ',' << mb(s)
          << ',' << rb << ',' << rb / se[r](s) << ',' << ma(s) << ',' << ra << ',' << ra / se[r](s)
          << '\n';
    }
  }
}

void write_residuals_csv(const std::string& path, const core::PositionTable& table,
                         const core::FitResult& before_fit, const core::FitResult& after_fit) {
  AtomicFile file(path);
  write_residuals_csv(file.stream(), table, before_fit, after_fit);
  file.commit();
}

}  // namespace io
}  // namespace accel_intrinsics
