#include "accel_intrinsics/core/model/effects.h"

#include <stdexcept>

#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {

const std::vector<EffectInfo>& effect_catalog() {
  // Separating experiments (docs/design.md section 3): the protocol options that decouple two
  // terms.
  static const char* const kTwoWayVsOffset =
      "a two-way sweep (ProtocolOptions::two_way: up, then back down) separates backlash from an "
      "angle offset: backlash flips sign with the direction of approach, an offset does not";
  static const char* const kClosingVsDrift =
      "a closing position at 360 deg (ProtocolOptions::closing_position, "
      "closing_position: true in config/protocol.yaml: repeat alpha = 0 at the end of each "
      "phase) separates drift from an angle-scale error: at the repeated position drift "
      "changes every output by d * dt, an angle-scale error by eps * 2 pi times the slope of "
      "that output (zero at its extremum); a two-way sweep, which decouples time from angle, "
      "also separates them";
  static const char* const kClosingVsOffset =
      "a closing position at 360 deg (closing_position: true in config/protocol.yaml) "
      "separates an angle-scale error from an angle offset: it is the 0 deg position again, "
      "so an offset reads the same there while a scale error has grown to eps * 2 pi";
  static const char* const kTemperatureVsDrift =
      "a temperature that does not follow time separates a temperature coefficient of offset "
      "from drift: let the DUT warm up and cool down again during the run, soak it at a second "
      "temperature and repeat, or cycle the temperature in a chamber; while the temperature is "
      "linear in time both terms are the same function of the dwell and no analysis can tell "
      "them apart";
  static const char* const kDriftVsAny =
      "repeating the run in another phase order or with a closing position "
      "(closing_position: true in config/protocol.yaml) decouples time from position and "
      "separates drift from the other term";

  static const std::vector<EffectInfo> kCatalog = {
      {EffectKind::QuadraticNonlinearity,
       "quadratic_nonlinearity",
       TargetKind::Accelerometer,
       "1/(m/s^2)",
       "R_s += K2 L_s^2 / |s|",
       false,
       Precondition::None,
       "",
       false,
       EffectKind::QuadraticNonlinearity,
       {},
       nullptr},
      {EffectKind::CubicNonlinearity,
       "cubic_nonlinearity",
       TargetKind::Accelerometer,
       "1/(m/s^2)^2",
       "R_s += K3 L_s^3 / |s|^2",
       false,
       Precondition::None,
       "",
       false,
       EffectKind::CubicNonlinearity,
       {},
       nullptr},
      {EffectKind::AngleOffset,
       "angle_offset",
       TargetKind::Phase,
       "rad",
       "true angle = alpha + delta",
       true,
       Precondition::None,
       "",
       false,
       EffectKind::AngleOffset,
       {},
       nullptr},
      {EffectKind::AngleScale,
       "angle_scale",
       TargetKind::Phase,
       "1",
       "true angle = alpha (1 + eps)",
       true,
       Precondition::None,
       "",
       false,
       EffectKind::AngleScale,
       {{EffectKind::OffsetDrift, kClosingVsDrift}, {EffectKind::AngleOffset, kClosingVsOffset}},
       nullptr},
      {EffectKind::AxisTilt,
       "axis_tilt",
       TargetKind::Phase,
       "rad",
       "rotation axis raised by tau from horizontal",
       true,
       Precondition::None,
       "",
       false,
       EffectKind::AxisTilt,
       {},
       nullptr},
      {EffectKind::OffsetDrift,
       "offset_drift",
       TargetKind::Accelerometer,
       "(m/s^2)/s",
       "R_s += d (t - t0)",
       false,
       Precondition::None,
       "",
       false,
       EffectKind::OffsetDrift,
       {},
       kDriftVsAny},
      {EffectKind::TimingLag,
       "timing_lag",
       TargetKind::All,
       "s",
       "IMU stamps late by lag",
       false,
       Precondition::RawStreams,
       "moves IMU stamps relative to the gimbal; dwell means taken after settling do not show it, "
       "only raw "
       "streams (a bag, or simulate_recording) do: estimate_timing_lag() in raw_stream_analysis.h",
       false,
       EffectKind::TimingLag,
       {},
       nullptr},
      {EffectKind::Backlash,
       "backlash",
       TargetKind::Phase,
       "rad",
       "angle error +b/2 or -b/2 by direction of approach",
       true,
       Precondition::TwoWaySweep,
       "phase {target} was swept one way only, where backlash is identical to "
       "angle_offset[{target}] (b/2); "
       "a two-way sweep reveals it",
       true,
       EffectKind::AngleOffset,
       {{EffectKind::AngleOffset, kTwoWayVsOffset}},
       nullptr},
      {EffectKind::OffsetTemperatureCoefficient,
       "offset_temperature_coefficient",
       TargetKind::Accelerometer,
       "(m/s^2)/K",
       "R_s += c (T - T_ref), T the dwell's mean temperature, T_ref the run's mean",
       false,
       Precondition::TemperatureVaries,
       "needs dwell temperatures that vary (imu/temperature, position table column "
       "temperature_c)",
       // Without recorded temperatures, a temperature that changed with time looks like drift.
       true,
       EffectKind::OffsetDrift,
       {{EffectKind::OffsetDrift, kTemperatureVsDrift}},
       nullptr},
      {EffectKind::ScaleTemperatureCoefficient,
       "scale_temperature_coefficient",
       TargetKind::Accelerometer,
       "1/K",
       "R_s += c (T - T_ref) L_s, T the dwell's mean temperature, T_ref the run's mean",
       false,
       Precondition::TemperatureVaries,
       "needs dwell temperatures that vary (imu/temperature, position table column "
       "temperature_c)",
       false,
       EffectKind::ScaleTemperatureCoefficient,
       {},
       nullptr},
  };
  return kCatalog;
}

const EffectInfo& effect_info(EffectKind kind) {
  return effect_catalog().at(static_cast<std::size_t>(kind));
}

std::string Effect::name() const {
  return effect_info(kind).name;
}

std::string Effect::target_name() const {
  switch (effect_info(kind).target_kind) {
    case TargetKind::Accelerometer: return accelerometer_name(target);
    case TargetKind::Phase:
      return (target >= 0 && target < 3) ? phase_name(static_cast<Phase>(target)) : "?";
    case TargetKind::All: return "all";
  }
  return "?";
}

std::string Effect::label() const {
  return name() + "[" + target_name() + "]";
}

const std::vector<NoiseEntryInfo>& noise_entry_catalog() {
  static const std::vector<NoiseEntryInfo> catalog = {
      {kCorrelatedNoise,
       "the noise of the dwell means is not white: a slow bias (bias instability, Gauss-Markov, "
       "random walk) makes neighbouring dwells err together; a noise-model entry estimated from "
       "the run's long rest, not a physical effect"},
  };
  return catalog;
}

Effect make_effect(const std::string& name, const std::string& target, double value) {
  for (const NoiseEntryInfo& info : noise_entry_catalog()) {
    if (name == info.name)
      throw std::invalid_argument(
          name +
          " is a noise-model entry, not an effect term: it is not simulated or fitted as "
          "a term; set the simulator's bias_gm_sigma / bias_gm_tau_s / bias_random_walk, "
          "or give the run a long rest (protocol initial_rest_s) for the noise model");
  }
  for (const EffectInfo& info : effect_catalog()) {
    if (name != info.name) continue;
    Effect effect;
    effect.kind = info.kind;
    effect.value = value;
    switch (info.target_kind) {
      case TargetKind::Accelerometer:
        if (target == "u")
          effect.target = 0;
        else if (target == "v")
          effect.target = 1;
        else if (target == "w")
          effect.target = 2;
        else
          throw std::invalid_argument("effect " + name + ": target must be u, v or w, got '" +
                                      target + "'");
        break;
      case TargetKind::Phase: {
        Phase phase;
        if (!parse_phase(target, &phase)) {
          throw std::invalid_argument("effect " + name + ": target must be x, y or z, got '" +
                                      target + "'");
        }
        effect.target = index(phase);
        break;
      }
      case TargetKind::All:
        if (target != "all" && !target.empty()) {
          throw std::invalid_argument("effect " + name + ": target must be 'all', got '" + target +
                                      "'");
        }
        effect.target = 0;
        break;
    }
    return effect;
  }
  std::string known;
  for (const EffectInfo& info : effect_catalog())
    known += std::string(known.empty() ? "" : ", ") + info.name;
  throw std::invalid_argument("unknown effect '" + name + "' (known: " + known + ")");
}

bool is_gimbal_effect(EffectKind kind) {
  return effect_info(kind).acts_on_gimbal;
}

std::vector<int> effect_targets(EffectKind kind) {
  if (effect_info(kind).target_kind == TargetKind::All) return {0};
  return {0, 1, 2};
}

std::string separating_experiment(const Effect& a, const Effect& b) {
  for (const Separation& s : effect_info(a.kind).separations) {
    if (s.other == b.kind) return s.experiment;
  }
  for (const Separation& s : effect_info(b.kind).separations) {
    if (s.other == a.kind) return s.experiment;
  }
  if (const char* any = effect_info(a.kind).separation_from_any_other) return any;
  if (const char* any = effect_info(b.kind).separation_from_any_other) return any;
  return "a protocol that decouples the two terms (more positions, other phase order, a two-way "
         "sweep) separates them; compare the per-harmonic residual power of both models";
}

std::string unmet_precondition_note(const Effect& effect) {
  std::string note = effect_info(effect.kind).unmet_precondition_note;
  const std::string placeholder = "{target}";
  const std::string target = effect.target_name();
  for (std::size_t at = note.find(placeholder); at != std::string::npos;
       at = note.find(placeholder, at)) {
    note.replace(at, placeholder.size(), target);
    at += target.size();
  }
  return note;
}

}  // namespace core
}  // namespace accel_intrinsics
