// The uncertainty budget file (docs/design.md section 9; config/uncertainty_budget.yaml is the
// commented template): the standard uncertainties of the rig's error sources (core::BudgetSpec)
// and a `certificate:` block of lab fields (lab, device, serial, operator, ...) printed on the
// certificate. Read by offline_fit --budget and the calibration node's budget_file.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "accel_intrinsics/core/analysis/uncertainty_budget.h"

namespace accel_intrinsics {
namespace io {

struct BudgetFile {
  std::string path;
  core::BudgetSpec spec;
  // The certificate block, in file order: (key, text). Scalars only.
  std::vector<std::pair<std::string, std::string>> certificate;
};

// Reads and validates (core::validate). Throws IoError with one line naming the path and the key
// for an unreadable file, an unknown key (a typo would otherwise silently leave a source at 0), a
// value that is not a number, a non-scalar certificate field, or an invalid value.
BudgetFile read_budget_file(const std::string& path);

}  // namespace io
}  // namespace accel_intrinsics
