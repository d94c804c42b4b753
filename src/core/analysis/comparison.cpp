#include "accel_intrinsics/core/analysis/comparison.h"

#include <cmath>
#include <sstream>

namespace accel_intrinsics {
namespace core {

const char* const kComparisonParameterNames[kComparedParameters] = {
    "responsivity_u", "responsivity_v", "responsivity_w", "angle_uv", "angle_vw",
    "angle_wu",       "offset_u",       "offset_v",       "offset_w"};

namespace {

std::string text(double x) {
  std::ostringstream out;
  out.precision(10);
  out << x;
  return out.str();
}

void check(const std::vector<ComparedResult>& results) {
  if (results.size() < 2)
    throw ComparisonError("a comparison needs at least two results, got " +
                          std::to_string(results.size()));
  const ComparedResult& first = results.front();
  for (const ComparedResult& r : results) {
    for (int p = 0; p < kComparedParameters; ++p) {
      if (!std::isfinite(r.value[p]))
        throw ComparisonError(r.name + ": " + kComparisonParameterNames[p] + " has no value");
      if (!std::isfinite(r.expanded[p]) || !(r.expanded[p] > 0.0))
        throw ComparisonError(r.name + ": " + kComparisonParameterNames[p] +
                              " has no uncertainty (expanded uncertainty " + text(r.expanded[p]) +
                              "); compare results that state their uncertainties");
    }
    if (!std::isfinite(r.local_gravity) ||
        std::abs(r.local_gravity - first.local_gravity) > 1e-9 * std::abs(first.local_gravity))
      throw ComparisonError(r.name + " was computed with g = " + text(r.local_gravity) +
                            " m/s^2 but " + first.name + " with g = " + text(first.local_gravity) +
                            " m/s^2; responsivities scale with g, refit with the same --gravity");
    if (r.coverage_factor != first.coverage_factor)
      throw ComparisonError(r.name + " states k = " + text(r.coverage_factor) + " but " +
                            first.name + " k = " + text(first.coverage_factor));
  }
}

}  // namespace

Comparison compare(const std::vector<ComparedResult>& results) {
  check(results);
  Comparison c;
  c.local_gravity = results.front().local_gravity;
  c.coverage_factor = results.front().coverage_factor;
  const double k = c.coverage_factor;
  for (const ComparedResult& r : results) c.results.push_back(r.name);
  const std::size_t n = results.size();
  for (int p = 0; p < kComparedParameters; ++p) {
    ParameterComparison pc;
    pc.name = kComparisonParameterNames[p];
    for (const ComparedResult& r : results) {
      pc.values.push_back(r.value[p]);
      pc.expanded.push_back(r.expanded[p]);
    }
    if (n == 2) {
      pc.E_n.push_back((pc.values[0] - pc.values[1]) / std::hypot(pc.expanded[0], pc.expanded[1]));
    } else {
      double sum_w = 0.0, sum_wx = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        const double u = pc.expanded[i] / k;
        sum_w += 1.0 / (u * u);
        sum_wx += pc.values[i] / (u * u);
      }
      pc.reference = sum_wx / sum_w;
      const double u_ref2 = 1.0 / sum_w;
      pc.reference_expanded = k * std::sqrt(u_ref2);
      for (std::size_t i = 0; i < n; ++i) {
        const double u = pc.expanded[i] / k;
        const double d = pc.values[i] - pc.reference;
        const double U_d = k * std::sqrt(std::max(0.0, u * u - u_ref2));
        pc.degrees_of_equivalence.push_back(d);
        pc.degrees_of_equivalence_expanded.push_back(U_d);
        pc.E_n.push_back(U_d > 0.0 ? d / U_d : 0.0);
      }
    }
    for (double e : pc.E_n) c.consistent = c.consistent && std::abs(e) <= 1.0;
    c.parameters.push_back(pc);
  }
  return c;
}

}  // namespace core
}  // namespace accel_intrinsics
