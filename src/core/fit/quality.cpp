#include "accel_intrinsics/core/fit/quality.h"

#include <boost/math/distributions/chi_squared.hpp>
#include <cmath>
#include <sstream>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {

std::string Quality::summary() const {
  if (pass) return "passed";
  std::string s;
  for (const std::string& r : reasons) s += (s.empty() ? "" : "; ") + r;
  return s;
}

double reduced_chi2_upper(int dof, double band) {
  if (dof <= 0) return HUGE_VAL;
  const boost::math::chi_squared_distribution<double> chi2(dof);
  return boost::math::quantile(chi2, 0.5 + 0.5 * band) / dof;
}

Quality assess_quality(const FitResult& fit, const PositionTable& table,
                       const QualityOptions& options) {
  Quality q;
  auto fail = [&q](const std::string& reason) {
    q.pass = false;
    q.reasons.push_back(reason);
  };
  // Noise-free tables (every std zero) are fitted with unit weights: chi-square has no band.
  bool weighted = false;
  std::uint64_t fewest = 0;
  std::size_t fewest_row = 0;
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    const DwellRecord& row = table.rows[i];
    if ((row.std.array() > 0.0).any()) weighted = true;
    if (i == 0 || row.n < fewest) {
      fewest = row.n;
      fewest_row = i;
    }
  }
  const double upper = reduced_chi2_upper(fit.dof, options.chi2_band);
  if (weighted && fit.dof > 0 && !(fit.reduced_chi2 <= options.chi2_far_factor * upper)) {
    std::ostringstream s;
    s << "reduced chi-square " << fit.reduced_chi2 << " is far above its "
      << 100.0 * options.chi2_band << " % band (upper end " << upper << " for " << fit.dof
      << " degrees of freedom): the model does not describe the data (a wrong clock, table or "
         "unit, or a large effect the model lacks: the analysis names it, certificate_model "
         "refit fits it)";
    fail(s.str());
  }
  const Eigen::Vector3d r = fit.intrinsics.responsivity;
  const double mean = r.mean();
  for (int s = 0; s < 3; ++s) {
    std::ostringstream m;
    m << "responsivity |" << accelerometer_name(s) << "| = " << r(s);
    if (!std::isfinite(r(s)) || r(s) <= 0.0) {
      fail(m.str() + " is not a responsivity");
    } else if (options.outputs_in_si &&
               (r(s) < options.min_responsivity_si || r(s) > options.max_responsivity_si)) {
      m << " is outside [" << options.min_responsivity_si << ", " << options.max_responsivity_si
        << "] for outputs in m/s^2 (wrong g or units? set output_unit for counts or volts)";
      fail(m.str());
    } else if (std::abs(r(s) - mean) > options.max_responsivity_spread * mean) {
      m << " differs from the mean of the three (" << mean << ") by more than "
        << 100.0 * options.max_responsivity_spread << " %";
      fail(m.str());
    }
  }
  const Eigen::Vector3d a = fit.intrinsics.angles_rad;
  const char* pairs[3] = {"uv", "vw", "wu"};
  for (int i = 0; i < 3; ++i) {
    const double deg = rad_to_deg(a(i));
    if (!std::isfinite(deg) || deg < options.min_angle_deg || deg > options.max_angle_deg) {
      std::ostringstream m;
      m << "angle theta_" << pairs[i] << " = " << deg
        << " deg is implausible for a triad (outside [" << options.min_angle_deg << ", "
        << options.max_angle_deg << "] deg)";
      fail(m.str());
    }
  }
  if (!table.rows.empty() && fewest < options.min_samples_per_dwell) {
    const DwellRecord& row = table.rows[fewest_row];
    std::ostringstream m;
    m << "dwell (phase " << phase_name(row.phase) << ", step " << row.step << ") has " << fewest
      << " samples, fewer than " << options.min_samples_per_dwell;
    fail(m.str());
  }
  return q;
}

}  // namespace core
}  // namespace accel_intrinsics
