#include "accel_intrinsics/io/comparison_document.h"

#include <cmath>
#include <nlohmann/json.hpp>

#include "accel_intrinsics/core/model/constants.h"

namespace accel_intrinsics {
namespace io {
namespace {

nlohmann::json numbers(const std::vector<double>& values) {
  nlohmann::json out = nlohmann::json::array();
  for (double v : values) out.push_back(std::isfinite(v) ? nlohmann::json(v) : nlohmann::json());
  return out;
}

}  // namespace

core::ComparedResult compared_result(const StoredResult& stored, const std::string& name,
                                     bool type_a_only) {
  core::ComparedResult r;
  r.name = name;
  r.local_gravity = stored.local_gravity;
  for (int i = 0; i < 3; ++i) {
    r.value[i] = stored.intrinsics.responsivity(i);
    r.value[3 + i] = core::rad_to_deg(stored.intrinsics.angles_rad(i));
    r.value[6 + i] = stored.O(i);
  }
  if (type_a_only) {
    r.coverage_factor = 2.0;
    for (int i = 0; i < 3; ++i) {
      r.expanded[i] = 2.0 * stored.intrinsics.responsivity_std(i);
      r.expanded[3 + i] = 2.0 * core::rad_to_deg(stored.intrinsics.angles_std_rad(i));
      r.expanded[6 + i] = 2.0 * stored.O_std(i);
    }
    return r;
  }
  if (!stored.expanded)
    throw core::ComparisonError(
        name +
        " has no uncertainty_budget (make it with offline_fit --budget FILE, or pass "
        "--type-a-only to compare with U = 2 x the type-A uncertainties)");
  r.coverage_factor = stored.coverage_factor;
  for (int i = 0; i < 3; ++i) {
    r.expanded[i] = stored.expanded->responsivity(i);
    r.expanded[3 + i] = core::rad_to_deg(stored.expanded->angles_rad(i));
    r.expanded[6 + i] = stored.expanded->offset(i);
  }
  return r;
}

std::string comparison_json_text(const core::Comparison& c, bool type_a_only) {
  nlohmann::json parameters = nlohmann::json::object();
  for (const core::ParameterComparison& p : c.parameters) {
    nlohmann::json j = {
        {"values", numbers(p.values)}, {"U", numbers(p.expanded)}, {"E_n", numbers(p.E_n)}};
    if (c.results.size() >= 3) {
      j["reference_value"] = p.reference;
      j["reference_U"] = p.reference_expanded;
      j["degrees_of_equivalence"] = numbers(p.degrees_of_equivalence);
      j["degrees_of_equivalence_U"] = numbers(p.degrees_of_equivalence_expanded);
    }
    parameters[p.name] = j;
  }
  const nlohmann::json doc = {
      {"results", c.results},     {"local_gravity", c.local_gravity},
      {"k", c.coverage_factor},   {"uncertainty", type_a_only ? "type_a_only" : "budget"},
      {"parameters", parameters}, {"consistent", c.consistent}};
  return doc.dump(2) + "\n";
}

}  // namespace io
}  // namespace accel_intrinsics
