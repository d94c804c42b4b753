// Numbers for people (docs/design.md section 15, "One result document"): a text report rounds
// each value to its uncertainty, the uncertainty to two significant digits and the value to the
// same decimal place (GUM 7.2.6); JSON and YAML keep full precision. The one rounding of the
// package's C++ text (scripts/certificate_report does the same in Python).
#pragma once

#include <string>

namespace accel_intrinsics {
namespace io {

struct Rounded {
  std::string value;        // e.g. "414.908"
  std::string uncertainty;  // e.g. "0.016"; "n/a" when the uncertainty is not finite and > 0
};

// value and uncertainty rounded together: 414.90812, 0.016437 -> {"414.908", "0.016"};
// 0.0995 rounds to "0.10" (two digits at the new place); 1234.5, 56.7 -> {"1235", "57"};
// 1234.5, 567 -> {"1230", "570"}. Without a usable uncertainty (not finite, <= 0) the value
// keeps 7 significant digits. A non-finite value is "n/a".
Rounded round_to_uncertainty(double value, double uncertainty);
// "414.908 +- 0.016"
std::string with_uncertainty(double value, double uncertainty);
// x to two significant digits, fixed notation between 1e-3 and 1e5, else scientific:
// 0.053123 -> "0.053", 5.2e-5 -> "5.2e-05", 1234 -> "1200". Non-finite: "n/a".
std::string two_significant(double x);

}  // namespace io
}  // namespace accel_intrinsics
