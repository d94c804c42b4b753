#include "accel_intrinsics/core/model/constants.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace accel_intrinsics {
namespace core {

double normal_gravity(double latitude_deg, double height_m) {
  if (!std::isfinite(latitude_deg) || !std::isfinite(height_m)) {
    throw std::invalid_argument("normal_gravity: latitude and height must be finite");
  }
  if (latitude_deg < -90.0 || latitude_deg > 90.0) {
    throw std::invalid_argument("normal_gravity: latitude " + std::to_string(latitude_deg) +
                                " deg is outside [-90, 90]");
  }
  // WGS 84 defining and derived constants (NIMA TR8350.2, 3rd ed., tables 3.1 and 3.3).
  constexpr double kGammaEquator = 9.7803253359;       // m/s^2
  constexpr double kSomiglianaK = 0.00193185265241;    // (b gamma_p) / (a gamma_e) - 1
  constexpr double kEccentricity2 = 0.00669437999013;  // first eccentricity squared
  constexpr double kSemiMajorAxis = 6378137.0;         // m
  constexpr double kFlattening = 1.0 / 298.257223563;
  constexpr double kM = 0.00344978650684;  // omega^2 a^2 b / GM
  const double sin2 = std::pow(std::sin(deg_to_rad(latitude_deg)), 2);
  const double gamma =
      kGammaEquator * (1.0 + kSomiglianaK * sin2) / std::sqrt(1.0 - kEccentricity2 * sin2);
  // Second-order free-air reduction (TR8350.2 eq. 4-3).
  const double h = height_m;
  const double factor =
      1.0 - 2.0 / kSemiMajorAxis * (1.0 + kFlattening + kM - 2.0 * kFlattening * sin2) * h +
      3.0 * h * h / (kSemiMajorAxis * kSemiMajorAxis);
  return gamma * factor;
}

}  // namespace core
}  // namespace accel_intrinsics
