// The one model of the rig: outputs R = S f + O plus the effect terms of effects.h.
// The simulator, every fit and the discrepancy analysis evaluate this template; adding an
// effect to a fit means adding an Effect to the list, never a new code path.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <vector>

#include "accel_intrinsics/core/model/effects.h"
#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {

// A three-axis accelerometer: rows of S are the vectors u, v, w in the DUT frame
// (dimensionless with outputs in m/s^2); O the offsets in m/s^2; plus any effect terms.
struct Device {
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  Eigen::Vector3d O = Eigen::Vector3d::Zero();
  std::vector<Effect> effects;
};

// Where and when one dwell (or one sample) was taken, as far as the model cares.
struct DwellGeometry {
  Phase phase = Phase::X;
  double angle_rad = 0.0;  // commanded alpha
  double time_s = 0.0;     // time since t0 (first gimbal command); mid-dwell for a dwell mean
  int approach = +1;       // +1 approached with increasing angle, -1 decreasing (backlash)
  // T - T_ref in K: the dwell's (or sample's) temperature minus the run's mean temperature
  // (docs/design.md section 10); 0 when no temperature was recorded (has_temperature false).
  double temperature_offset_k = 0.0;
  bool has_temperature = false;
  // A known orientation (position table f_x,f_y,f_z): the unit specific force in the DUT frame,
  // whatever the phase and angle say; the gimbal's angle and axis effects do not apply to it.
  bool has_direction = false;
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();
};

// True gimbal angle for a commanded angle under the angle effects (scale, offset, backlash).
template <typename T>
T true_angle(const std::vector<Effect>& terms, const T* values, const DwellGeometry& geom) {
  T alpha = T(geom.angle_rad);
  const int p = index(geom.phase);
  for (std::size_t i = 0; i < terms.size(); ++i) {
    if (terms[i].target != p) continue;
    if (terms[i].kind == EffectKind::AngleScale) alpha = alpha * (T(1.0) + values[i]);
  }
  for (std::size_t i = 0; i < terms.size(); ++i) {
    if (terms[i].target != p) continue;
    if (terms[i].kind == EffectKind::AngleOffset) alpha = alpha + values[i];
    if (terms[i].kind == EffectKind::Backlash) alpha = alpha + T(0.5 * geom.approach) * values[i];
  }
  return alpha;
}

// Specific force in the DUT frame (m/s^2): eq. (4) at the true angle, with axis tilt tau
// (in-plane part scaled by cos tau, g sin tau along the rotation axis).
template <typename T>
Eigen::Matrix<T, 3, 1> specific_force(const std::vector<Effect>& terms, const T* values,
                                      const DwellGeometry& geom, double g) {
  using std::cos;
  using std::sin;
  if (geom.has_direction) return geom.direction.template cast<T>() * T(g);
  const T alpha = true_angle(terms, values, geom);
  Eigen::Matrix<T, 3, 1> f = in_plane_direction(geom.phase, alpha) * T(g);
  const int p = index(geom.phase);
  for (std::size_t i = 0; i < terms.size(); ++i) {
    if (terms[i].kind != EffectKind::AxisTilt || terms[i].target != p) continue;
    f = f * cos(values[i]);
    f(p) = f(p) + T(g) * sin(values[i]);
  }
  return f;
}

// Outputs R_u, R_v, R_w for the specific force f (DUT frame, m/s^2) under the sensor effects
// (non-linearity, drift, temperature: what acts on the outputs, not on the gimbal). A hand tumble
// (tumble_analysis.h) evaluates it with f a fitted unknown; predict_outputs() with the gimbal's f.
template <typename T>
Eigen::Matrix<T, 3, 1> outputs_for_force(const T* S_row_major, const T* offsets,
                                         const std::vector<Effect>& terms, const T* values,
                                         const Eigen::Matrix<T, 3, 1>& f,
                                         const DwellGeometry& geom) {
  using std::sqrt;
  Eigen::Matrix<T, 3, 1> R;
  for (int s = 0; s < 3; ++s) {
    const T* row = S_row_major + 3 * s;
    const T linear = row[0] * f(0) + row[1] * f(1) + row[2] * f(2);  // L_s = s . f
    T out = linear + offsets[s];
    for (std::size_t i = 0; i < terms.size(); ++i) {
      if (terms[i].target != s) continue;
      switch (terms[i].kind) {
        case EffectKind::QuadraticNonlinearity: {
          const T norm = sqrt(row[0] * row[0] + row[1] * row[1] + row[2] * row[2]);
          out = out + values[i] * linear * linear / norm;
          break;
        }
        case EffectKind::CubicNonlinearity: {
          const T norm2 = row[0] * row[0] + row[1] * row[1] + row[2] * row[2];
          out = out + values[i] * linear * linear * linear / norm2;
          break;
        }
        case EffectKind::OffsetDrift: out = out + values[i] * T(geom.time_s); break;
        case EffectKind::OffsetTemperatureCoefficient:
          out = out + values[i] * T(geom.temperature_offset_k);
          break;
        case EffectKind::ScaleTemperatureCoefficient:
          out = out + values[i] * T(geom.temperature_offset_k) * linear;
          break;
        default: break;
      }
    }
    R(s) = out;
  }
  return R;
}

// Outputs R_u, R_v, R_w (m/s^2). S_row_major: 9 values (u then v then w); offsets: 3 values;
// values[i] is the value of terms[i] (terms[i].value is ignored, so a fit can vary it).
// timing_lag has no term here: it moves IMU stamps, which only raw streams show (simulator.h).
template <typename T>
Eigen::Matrix<T, 3, 1> predict_outputs(const T* S_row_major, const T* offsets,
                                       const std::vector<Effect>& terms, const T* values,
                                       const DwellGeometry& geom, double g) {
  return outputs_for_force(S_row_major, offsets, terms, values,
                           specific_force(terms, values, geom, g), geom);
}

// Convenience for double evaluation of a Device (its effects carry their values).
Eigen::Vector3d predict_outputs(const Device& device, const DwellGeometry& geom, double g);

// Throws std::invalid_argument when S is singular or not finite, or O is not finite.
void validate(const Device& device);

}  // namespace core
}  // namespace accel_intrinsics
