#include "accel_intrinsics/core/model/text_format.h"

#include <cmath>
#include <cstdio>

namespace accel_intrinsics {
namespace core {

std::string fixed(double value, int decimals) {
  if (!std::isfinite(value)) {
    char buffer[16];
    std::snprintf(buffer, sizeof(buffer), "%f", value);  // "nan", "inf", "-inf"
    return buffer;
  }
  const double scale = std::pow(10.0, decimals);
  double rounded = value;
  if (std::isfinite(value * scale)) rounded = std::round(value * scale) / scale;
  if (rounded == 0.0) rounded = 0.0;  // no "-0.000"
  char buffer[400];                   // DBL_MAX has 309 digits before the point
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals > 0 ? decimals : 0, rounded);
  return buffer;
}

}  // namespace core
}  // namespace accel_intrinsics
