#include "accel_intrinsics/core/effects.h"

#include <stdexcept>

#include "accel_intrinsics/core/protocol.h"

namespace accel_intrinsics {
namespace core {

const std::vector<EffectInfo>& effect_catalog() {
  static const std::vector<EffectInfo> kCatalog = {
      {EffectKind::QuadraticNonlinearity, "quadratic_nonlinearity", TargetKind::Accelerometer, "1/(m/s^2)",
       "R_s += K2 L_s^2 / |s|"},
      {EffectKind::CubicNonlinearity, "cubic_nonlinearity", TargetKind::Accelerometer, "1/(m/s^2)^2",
       "R_s += K3 L_s^3 / |s|^2"},
      {EffectKind::AngleOffset, "angle_offset", TargetKind::Phase, "rad", "true angle = alpha + delta"},
      {EffectKind::AngleScale, "angle_scale", TargetKind::Phase, "1", "true angle = alpha (1 + eps)"},
      {EffectKind::AxisTilt, "axis_tilt", TargetKind::Phase, "rad",
       "rotation axis raised by tau from horizontal"},
      {EffectKind::OffsetDrift, "offset_drift", TargetKind::Accelerometer, "(m/s^2)/s", "R_s += d (t - t0)"},
      {EffectKind::TimingLag, "timing_lag", TargetKind::All, "s", "IMU stamps late by lag"},
      {EffectKind::Backlash, "backlash", TargetKind::Phase, "rad",
       "angle error +b/2 or -b/2 by direction of approach"},
  };
  return kCatalog;
}

const EffectInfo& effect_info(EffectKind kind) { return effect_catalog().at(static_cast<std::size_t>(kind)); }

std::string Effect::name() const { return effect_info(kind).name; }

std::string Effect::target_name() const {
  switch (effect_info(kind).target_kind) {
    case TargetKind::Accelerometer: return accelerometer_name(target);
    case TargetKind::Phase: return (target >= 0 && target < 3) ? phase_name(static_cast<Phase>(target)) : "?";
    case TargetKind::All: return "all";
  }
  return "?";
}

std::string Effect::label() const { return name() + "[" + target_name() + "]"; }

Effect make_effect(const std::string& name, const std::string& target, double value) {
  for (const EffectInfo& info : effect_catalog()) {
    if (name != info.name) continue;
    Effect effect;
    effect.kind = info.kind;
    effect.value = value;
    switch (info.target_kind) {
      case TargetKind::Accelerometer:
        if (target == "u") effect.target = 0;
        else if (target == "v") effect.target = 1;
        else if (target == "w") effect.target = 2;
        else throw std::invalid_argument("effect " + name + ": target must be u, v or w, got '" + target + "'");
        break;
      case TargetKind::Phase: {
        Phase phase;
        if (!parse_phase(target, &phase)) {
          throw std::invalid_argument("effect " + name + ": target must be x, y or z, got '" + target + "'");
        }
        effect.target = index(phase);
        break;
      }
      case TargetKind::All:
        if (target != "all" && !target.empty()) {
          throw std::invalid_argument("effect " + name + ": target must be 'all', got '" + target + "'");
        }
        effect.target = 0;
        break;
    }
    return effect;
  }
  std::string known;
  for (const EffectInfo& info : effect_catalog()) known += std::string(known.empty() ? "" : ", ") + info.name;
  throw std::invalid_argument("unknown effect '" + name + "' (known: " + known + ")");
}

bool is_gimbal_effect(EffectKind kind) {
  return kind == EffectKind::AngleOffset || kind == EffectKind::AngleScale || kind == EffectKind::AxisTilt ||
         kind == EffectKind::Backlash;
}

}  // namespace core
}  // namespace accel_intrinsics
