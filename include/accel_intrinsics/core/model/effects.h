// The vocabulary of physical effects (docs/design.md section 3). An effect is a named term of the
// one rig model (model.h): switched on in the simulator, added to a fit, screened by the analysis.
#pragma once

#include <string>
#include <vector>

namespace accel_intrinsics {
namespace core {

enum class EffectKind {
  QuadraticNonlinearity,         // R_s += K2 L_s^2 / |s|          target u|v|w, 1/(m/s^2)
  CubicNonlinearity,             // R_s += K3 L_s^3 / |s|^2        target u|v|w, 1/(m/s^2)^2
  AngleOffset,                   // true angle = alpha + delta      target x|y|z, rad
  AngleScale,                    // true angle = alpha (1 + eps)    target x|y|z, 1
  AxisTilt,                      // rotation axis raised by tau     target x|y|z, rad
  OffsetDrift,                   // R_s += d (t - t0)               target u|v|w, (m/s^2)/s
  TimingLag,                     // IMU stamps late by lag          target all,   s
  Backlash,                      // angle error +-b/2 by approach   target x|y|z, rad
  OffsetTemperatureCoefficient,  // R_s += c (T - T_ref)     target u|v|w, (m/s^2)/K
  ScaleTemperatureCoefficient,   // R_s += c (T - T_ref) L_s target u|v|w, 1/K
};

enum class TargetKind { Accelerometer, Phase, All };

// What a run must contain before its dwell means can show an effect.
enum class Precondition {
  None,
  TwoWaySweep,  // the phase approached from both sides (ProtocolOptions::two_way)
  RawStreams,   // the samples and gimbal events themselves, not dwell means (a bag, a recording)
  // Every dwell has a mean temperature (imu/temperature, position table column temperature_c) and
  // they span at least AnalysisOptions::min_temperature_span_k.
  TemperatureVaries,
};

// The experiment that separates two effects whose signatures in a run are alike.
struct Separation {
  EffectKind other;
  const char* experiment;
};

struct EffectInfo {
  EffectKind kind;
  const char* name;  // as in docs/design.md, e.g. "quadratic_nonlinearity"
  TargetKind target_kind;
  const char* unit;
  const char* description;
  bool acts_on_gimbal;  // a term of the gimbal angle (true_angle), not of the sensor
  Precondition precondition;
  // Why the analysis cannot screen the effect when the precondition is not met; "{target}" stands
  // for the target's name. Empty when the precondition is None.
  const char* unmet_precondition_note;
  // The effect it cannot be told from while its precondition is unmet (same target), if any: the
  // analysis then reports a named `same_as_when_unmet` as ambiguous with this one.
  bool has_look_alike;
  EffectKind same_as_when_unmet;
  // Pairs with a specific separating experiment, and the experiment for any other partner
  // (nullptr: the generic advice).
  std::vector<Separation> separations;
  const char* separation_from_any_other;
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

// Effects that act on the gimbal angle rather than the sensor (EffectInfo::acts_on_gimbal).
bool is_gimbal_effect(EffectKind kind);

// The targets an effect of this kind can have: 0..2 (u/v/w or x/y/z), or {0} for "all".
std::vector<int> effect_targets(EffectKind kind);

// The catalog's experiment that separates effects `a` and `b` (in either order; a pair entry
// first, then an effect's experiment for any other partner, then the generic advice).
std::string separating_experiment(const Effect& a, const Effect& b);

// Noise-model entries of the vocabulary (docs/design.md section 12): names the discrepancy analysis
// may give a gap that NO physical term explains. They are not effect terms (no Effect, never
// simulated as a term nor fitted as one; make_effect refuses them with a pointer here).
//   correlated_noise: the dwell means' noise is not white (a slow bias: Gauss-Markov, random
//   walk); named when the residuals exceed the white prediction, the run's noise model (from its
//   long rest) explains them, and no catalog effect explains them better out of sample.
struct NoiseEntryInfo {
  const char* name;
  const char* description;
};
const std::vector<NoiseEntryInfo>& noise_entry_catalog();
constexpr const char* kCorrelatedNoise = "correlated_noise";

// EffectInfo::unmet_precondition_note of `effect`, for its target: "phase x was swept one way...".
std::string unmet_precondition_note(const Effect& effect);

}  // namespace core
}  // namespace accel_intrinsics
