// Comparison inputs and output (docs/design.md section 9): result files read into the nine
// parameters with expanded uncertainties, and the comparison JSON:
//   {"results": [names], "local_gravity", "k", "uncertainty": "budget" | "type_a_only",
//    "parameters": {"responsivity_u": {"values": [...], "U": [...], "E_n": [...],
//                   (three or more:) "reference_value", "reference_U",
//                   "degrees_of_equivalence": [...], "degrees_of_equivalence_U": [...]}, ...},
//    "consistent": true|false}
// Angles in degrees, offsets in m/s^2, responsivities dimensionless.
#pragma once

#include <string>

#include "accel_intrinsics/core/analysis/comparison.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {
namespace io {

// The nine values of a stored result and their expanded uncertainties: the result's
// uncertainty_budget.expanded, or with type_a_only 2 x its type-A standard uncertainties (all
// results of a comparison then use type A). Throws core::ComparisonError (one line, naming the
// file) when the result has no budget and type_a_only is false.
core::ComparedResult compared_result(const StoredResult& stored, const std::string& name,
                                     bool type_a_only);

std::string comparison_json_text(const core::Comparison& comparison, bool type_a_only);

}  // namespace io
}  // namespace accel_intrinsics
