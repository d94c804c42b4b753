// The vocabulary of physical effects (DESIGN.md section 3). An effect is a named term of the one
// rig model (model.h): switched on in the simulator, added to a fit, screened by the analysis.
#pragma once

#include <string>
#include <vector>

namespace accel_intrinsics {
namespace core {

enum class EffectKind {
  QuadraticNonlinearity,  // R_s += K2 L_s^2 / |s|          target u|v|w, 1/(m/s^2)
  CubicNonlinearity,      // R_s += K3 L_s^3 / |s|^2        target u|v|w, 1/(m/s^2)^2
  AngleOffset,            // true angle = alpha + delta      target x|y|z, rad
  AngleScale,             // true angle = alpha (1 + eps)    target x|y|z, 1
  AxisTilt,               // rotation axis raised by tau     target x|y|z, rad
  OffsetDrift,            // R_s += d (t - t0)               target u|v|w, (m/s^2)/s
  TimingLag,              // IMU stamps late by lag          target all,   s
  Backlash,               // angle error +-b/2 by approach   target x|y|z, rad
};

enum class TargetKind { Accelerometer, Phase, All };

struct EffectInfo {
  EffectKind kind;
  const char* name;  // as in DESIGN.md, e.g. "quadratic_nonlinearity"
  TargetKind target_kind;
  const char* unit;
  const char* description;
};

// Every effect kind, in the order of EffectKind.
const std::vector<EffectInfo>& effect_catalog();
const EffectInfo& effect_info(EffectKind kind);

// One effect term: kind, target (0..2 for u/v/w or x/y/z; 0 for "all") and value in SI units.
struct Effect {
  EffectKind kind = EffectKind::QuadraticNonlinearity;
  int target = 0;
  double value = 0.0;

  std::string name() const;         // "quadratic_nonlinearity"
  std::string target_name() const;  // "u", "x" or "all"
  std::string label() const;        // "quadratic_nonlinearity[u]"
};

// Parses a name and a target ("u", "x", "all"); throws std::invalid_argument naming what is
// wrong (unknown name, or a target that does not fit the effect's kind).
Effect make_effect(const std::string& name, const std::string& target, double value = 0.0);

// Effects that act on the gimbal angle rather than the sensor.
bool is_gimbal_effect(EffectKind kind);

}  // namespace core
}  // namespace accel_intrinsics
