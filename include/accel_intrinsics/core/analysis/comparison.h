// Inter-laboratory comparison of intrinsic parameters (docs/design.md section 9): normalized errors
// E_n for two results, and for three or more the weighted reference value and each result's
// degree of equivalence. All uncertainties are EXPANDED (U = k u, k = 2).
//
//   two results:    E_n = (x_A - x_B) / sqrt(U_A^2 + U_B^2)
//   three or more:  x_ref = sum(x_i / u_i^2) / sum(1 / u_i^2),  u_ref^2 = 1 / sum(1 / u_i^2)
//                   (the weighted mean; u_i = U_i / k), degree of equivalence d_i = x_i - x_ref
//                   with U(d_i) = k sqrt(u_i^2 - u_ref^2) (result i is part of the reference, so
//                   d_i and x_i are correlated: the minus sign), and E_n,i = d_i / U(d_i).
//   consistent:     every |E_n| <= 1.
// The nine parameters: responsivity_u|v|w (1), angle_uv|vw|wu (degrees), offset_u|v|w (m/s^2).
#pragma once

#include <array>
#include <stdexcept>
#include <string>
#include <vector>

namespace accel_intrinsics {
namespace core {

constexpr int kComparedParameters = 9;
extern const char* const kComparisonParameterNames[kComparedParameters];

// One result as compared: its name (file), g, and the nine values with expanded uncertainties.
struct ComparedResult {
  std::string name;
  double local_gravity = 0.0;  // m/s^2
  std::array<double, kComparedParameters> value{};
  std::array<double, kComparedParameters> expanded{};  // U, k = coverage_factor
  double coverage_factor = 2.0;
};

struct ParameterComparison {
  std::string name;
  std::vector<double> values, expanded, E_n;
  // Three or more results: the weighted reference value and the degrees of equivalence.
  double reference = 0.0, reference_expanded = 0.0;
  std::vector<double> degrees_of_equivalence, degrees_of_equivalence_expanded;
};

struct Comparison {
  std::vector<std::string> results;
  double local_gravity = 0.0;
  double coverage_factor = 2.0;
  std::vector<ParameterComparison> parameters;  // in kComparisonParameterNames order
  bool consistent = true;
};

// Bad input for a comparison; the message is one line naming the result and what is wrong.
class ComparisonError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Throws ComparisonError: fewer than two results; a result without uncertainties (an expanded
// uncertainty missing, non-finite or not positive); results made with different g (relative
// difference above 1e-9: the responsivities scale with g, so they are not comparable); different
// coverage factors.
Comparison compare(const std::vector<ComparedResult>& results);

}  // namespace core
}  // namespace accel_intrinsics
