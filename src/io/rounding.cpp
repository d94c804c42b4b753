#include "accel_intrinsics/io/rounding.h"

#include <cmath>
#include <cstdio>

#include "accel_intrinsics/core/model/text_format.h"

namespace accel_intrinsics {
namespace io {
namespace {

// Decimal places that keep two significant digits of u (negative: tens, hundreds...).
int decimals_for(double u) {
  return 1 - static_cast<int>(std::floor(std::log10(std::abs(u))));
}

using core::fixed;  // x rounded to d decimal places (d < 0: to tens, hundreds...)

std::string significant(double x, int digits) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*g", digits, x);
  return buffer;
}

}  // namespace

Rounded round_to_uncertainty(double value, double uncertainty) {
  if (!std::isfinite(value)) return {"n/a", std::isfinite(uncertainty) ? "" : "n/a"};
  if (!std::isfinite(uncertainty) || !(uncertainty > 0.0)) return {significant(value, 7), "n/a"};
  int d = decimals_for(uncertainty);
  // 0.0995 -> 0.10: two digits at the new place.
  const double u_rounded = std::round(uncertainty * std::pow(10.0, d)) / std::pow(10.0, d);
  if (decimals_for(u_rounded) != d) d = decimals_for(u_rounded);
  return {fixed(value, d), fixed(uncertainty, d)};
}

std::string with_uncertainty(double value, double uncertainty) {
  const Rounded r = round_to_uncertainty(value, uncertainty);
  return r.value + " +- " + r.uncertainty;
}

std::string two_significant(double x) {
  if (!std::isfinite(x)) return "n/a";
  if (x == 0.0) return "0";
  const double a = std::abs(x);
  if (a >= 1e-3 && a < 1e5) return fixed(x, decimals_for(x));
  return significant(x, 2);
}

}  // namespace io
}  // namespace accel_intrinsics
