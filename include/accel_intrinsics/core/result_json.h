// FitResult as JSON: the keys of the offline tool's contract (DESIGN.md section 2, "Offline tool").
//
//   model, responsivity {u,v,w}, responsivity_std {u,v,w}, angles_deg {uv,vw,wu},
//   angles_std_deg {uv,vw,wu}, vectors {u,v,w: [x,y,z]}, offset {u,v,w},
//   offset_per_phase {u,v,w: {x,y,z}}, cross_sensitivity (3x3, row-major list of rows),
//   local_gravity, reduced_chi2, residual_rms, positions {x,y,z}
//
// plus, beyond the contract: model_label, vectors_std, offset_std, offset_per_phase_std,
// cross_sensitivity_std, chi2, dof, fitted_effects [{name, target, value, std}] (terms fitted
// with FitOptions::effects; named so that the discrepancy analysis can own "effects").
//
// Units: as in the result (SI, m/s^2; angles in degrees as the key says). Non-finite numbers
// become JSON null. The discrepancy analysis extends the object returned by to_json with its own
// keys (effects, ambiguous, gap): build on this function, don't copy it.
#pragma once

#include <nlohmann/json.hpp>

#include "accel_intrinsics/core/fit.h"

namespace accel_intrinsics {
namespace core {

nlohmann::json to_json(const FitResult& result);

// {"u": v(0), "v": v(1), "w": v(2)} and {"x": ..., "y": ..., "z": ...}: the building blocks,
// exported so that extensions name axes the same way.
nlohmann::json accelerometer_object(const Eigen::Vector3d& values);
nlohmann::json phase_object(const Eigen::Vector3d& values);

}  // namespace core
}  // namespace accel_intrinsics
