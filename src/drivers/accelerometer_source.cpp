// Simulated accelerometer backend: truth device of model.h at the orientation from tf.
#include "accel_intrinsics/drivers/accelerometer_source.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "accel_intrinsics/core/model/gimbal_kinematics.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {

void SimulatedAccelerometerOptions::validate() const {
  try {
    core::validate(truth);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("device: ") + e.what());
  }
  for (const core::Effect& e : truth.effects) {
    if (core::is_gimbal_effect(e.kind)) {
      throw std::invalid_argument("device/effects: " + e.label() +
                                  " acts on the gimbal; configure it on the gimbal controller");
    }
    if (!std::isfinite(e.value))
      throw std::invalid_argument("device/effects: " + e.label() + " is not finite");
    if (e.kind == core::EffectKind::TimingLag && (e.value < 0.0 || e.value > 10.0)) {
      throw std::invalid_argument("device/effects: timing_lag must be in [0, 10] s");
    }
  }
  if (!std::isfinite(rate_hz) || rate_hz <= 0.0 || rate_hz > 100000.0)
    throw std::invalid_argument("rate_hz must be in (0, 100000] Hz");
  if (!std::isfinite(noise_density) || noise_density < 0.0)
    throw std::invalid_argument("noise_density must be finite and >= 0");
  if (!std::isfinite(quantization) || quantization < 0.0)
    throw std::invalid_argument("quantization must be finite and >= 0");
  if (!std::isfinite(local_gravity) || local_gravity <= 0.0 || local_gravity > 100.0)
    throw std::invalid_argument("local_gravity must be in (0, 100] m/s^2");
  if (!std::isfinite(temperature_reference_c))
    throw std::invalid_argument("temperature/reference_c must be finite");
  core::SlowBiasProcess::validate(bias_gm_sigma, bias_gm_tau_s, bias_random_walk, "",
                                  {"bias/gm_sigma", "bias/gm_tau_s", "bias/random_walk"});
  // The profile's own checks (simulator.h), with a run that satisfies the others.
  core::SimulationOptions sim;
  sim.temperature = temperature;
  try {
    core::validate(sim);
  } catch (const std::invalid_argument& e) {
    std::string what = e.what();
    const std::string prefix = "simulation: temperature ";
    if (what.compare(0, prefix.size(), prefix) == 0)
      what = "temperature/" + what.substr(prefix.size());
    throw std::invalid_argument(what);
  }
}

double SimulatedAccelerometerOptions::noise_std() const {
  core::SimulationOptions sim;
  sim.rate_hz = rate_hz;
  sim.noise_density = noise_density;
  return core::sample_noise_std(sim);
}

double SimulatedAccelerometerOptions::timing_lag_s() const {
  double lag = 0.0;
  for (const core::Effect& e : truth.effects) {
    if (e.kind == core::EffectKind::TimingLag) lag += e.value;
  }
  return lag;
}

SimulatedAccelerometer::SimulatedAccelerometer(const SimulatedAccelerometerOptions& options,
                                               OrientationProvider orientation)
    : options_(options),
      orientation_(std::move(orientation)),
      rng_(options.seed),
      temperature_rng_(options.seed ^ 0x7e3779b97f4a7c15ull),
      bias_(options.bias_gm_sigma, options.bias_gm_tau_s, options.bias_random_walk, options.seed) {
  options_.validate();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) S_row_major_.push_back(options_.truth.S(r, c));
  for (const core::Effect& e : options_.truth.effects) {
    if (e.kind == core::EffectKind::TimingLag) continue;  // acts on stamps, below
    terms_.push_back(e);
    values_.push_back(e.value);
  }
  core::Effect tilt;
  tilt.kind = core::EffectKind::AxisTilt;
  tilt.target = core::index(core::Phase::X);
  terms_.push_back(tilt);
  values_.push_back(0.0);
  noise_std_ = options_.noise_std();
  lag_s_ = options_.timing_lag_s();
}

Eigen::Vector3d SimulatedAccelerometer::specific_force(const Eigen::Matrix3d& R_world_dut) const {
  return core::specific_force_in_dut(R_world_dut, options_.local_gravity);
}

Eigen::Vector3d SimulatedAccelerometer::outputs(const Eigen::Vector3d& f_dut, double time_s,
                                                double temperature_offset_k) const {
  const double g = f_dut.norm();
  core::DwellGeometry geom;
  geom.phase = core::Phase::X;
  geom.time_s = time_s;
  geom.has_temperature = true;
  geom.temperature_offset_k = temperature_offset_k;
  if (g > 0.0) {
    geom.angle_rad = std::atan2(f_dut.y(), f_dut.z());
    values_.back() = std::asin(std::max(-1.0, std::min(1.0, f_dut.x() / g)));
  } else {
    geom.angle_rad = 0.0;
    values_.back() = 0.0;
  }
  return core::predict_outputs(S_row_major_.data(), options_.truth.O.data(), terms_, values_.data(),
                               geom, g);
}

void SimulatedAccelerometer::poll(double now_s, std::vector<core::ImuSample>* out) {
  const double period = 1.0 / options_.rate_hz;
  if (next_index_ < 0) next_index_ = static_cast<std::int64_t>(std::ceil(now_s / period - 1e-9));
  // Bounded work per poll: at most 10 s of samples (a stalled clock cannot make us spin).
  const std::int64_t max_batch = static_cast<std::int64_t>(10.0 * options_.rate_hz) + 1;
  for (std::int64_t n = 0; n < max_batch; ++n) {
    const double t = static_cast<double>(next_index_) * period;  // true sample time
    if (t > now_s) break;
    Eigen::Matrix3d R;
    const OrientationStatus status = orientation_(t, &R);
    if (status == OrientationStatus::NotYet) break;
    ++next_index_;
    if (status == OrientationStatus::Never) {
      ++skipped_;
      continue;
    }
    const double since_t0 = std::isfinite(time_origin_s_) ? t - time_origin_s_ : 0.0;
    Eigen::Vector3d R_out = outputs(specific_force(R), since_t0,
                                    temperature_c(since_t0) - options_.temperature_reference_c);
    if (bias_.active()) R_out += slow_bias(t);
    if (noise_std_ > 0.0) {
      for (int i = 0; i < 3; ++i) R_out(i) += noise_std_ * normal_(rng_);
    }
    if (options_.quantization > 0.0) {
      for (int i = 0; i < 3; ++i)
        R_out(i) = options_.quantization * std::round(R_out(i) / options_.quantization);
    }
    core::ImuSample sample;
    sample.stamp_s = t + lag_s_;  // timing_lag: the stamp is late
    sample.outputs = R_out;
    out->push_back(sample);
  }
}

void SimulatedAccelerometer::poll_temperatures(double now_s,
                                               std::vector<core::TemperatureSample>* out) {
  if (!options_.temperature.recorded) return;
  const double period = 1.0 / options_.temperature.rate_hz;
  if (next_temperature_index_ < 0)
    next_temperature_index_ = static_cast<std::int64_t>(std::ceil(now_s / period - 1e-9));
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int n = 0; n < 1000; ++n) {
    const double t = static_cast<double>(next_temperature_index_) * period;
    if (t > now_s) break;
    ++next_temperature_index_;
    const double since_t0 = std::isfinite(time_origin_s_) ? t - time_origin_s_ : 0.0;
    out->push_back(core::TemperatureSample{
        t + lag_s_,
        temperature_c(since_t0) + options_.temperature.noise_c * normal(temperature_rng_)});
  }
}

double SimulatedAccelerometer::variance_per_axis() const {
  const double q = options_.quantization;
  return noise_std_ * noise_std_ + q * q / 12.0;
}

// The bias at the sample time t_s: the one slow-bias process (core::SlowBiasProcess) moved on by
// the time since the last sample.
Eigen::Vector3d SimulatedAccelerometer::slow_bias(double t_s) {
  if (!std::isfinite(bias_t_s_)) bias_t_s_ = t_s;
  const double dt = std::max(0.0, t_s - bias_t_s_);
  bias_t_s_ = std::max(bias_t_s_, t_s);
  return bias_.advance(dt);
}

void SimulatedAccelerometer::restart() {
  next_index_ = -1;
  next_temperature_index_ = -1;
}

}  // namespace accel_intrinsics
