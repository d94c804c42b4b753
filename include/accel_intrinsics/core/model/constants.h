// Physical constants and local gravity, defined once for the whole package.
#pragma once

namespace accel_intrinsics {
namespace core {

// Standard gravity (CGPM 1901), m/s^2. The default local_gravity.
constexpr double kStandardGravity = 9.80665;
constexpr double kPi = 3.14159265358979323846;

inline double deg_to_rad(double deg) {
  return deg * kPi / 180.0;
}
inline double rad_to_deg(double rad) {
  return rad * 180.0 / kPi;
}

// Normal gravity of the WGS 84 ellipsoid (Somigliana closed formula) at geodetic latitude
// `latitude_deg`, reduced to `height_m` above the ellipsoid with the second-order free-air
// gradient (NIMA TR8350.2, eq. 4-1 and 4-3). m/s^2. Throws std::invalid_argument for a latitude
// outside [-90, 90] or a non-finite input.
double normal_gravity(double latitude_deg, double height_m = 0.0);

}  // namespace core
}  // namespace accel_intrinsics
