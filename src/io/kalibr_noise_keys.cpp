#include "kalibr_noise_keys.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>

namespace accel_intrinsics {
namespace io {
namespace detail {

std::string round_trip_text(double v) {
  v += 0.0;  // no "-0"
  char buf[40];
  for (int precision = 15; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

namespace {

double largest_finite(const Eigen::Vector3d& v) {
  double m = std::numeric_limits<double>::quiet_NaN();
  for (int i = 0; i < 3; ++i) {
    if (std::isfinite(v(i)) && !(m >= v(i))) m = v(i);
  }
  return m;
}

}  // namespace

KalibrNoiseKeys kalibr_noise_keys(const Eigen::Vector3d& density, const Eigen::Vector3d& walk,
                                  double rate_hz, const std::string& indent) {
  KalibrNoiseKeys out;
  auto key = [&](const char* name, double value) {
    if (std::isfinite(value))
      out.lines += indent + name + ": " + round_trip_text(value) + "\n";
    else
      out.missing.push_back(name);
  };
  key("update_rate", rate_hz);
  key("accelerometer_noise_density", largest_finite(density));
  key("accelerometer_random_walk", largest_finite(walk));
  return out;
}

}  // namespace detail
}  // namespace io
}  // namespace accel_intrinsics
