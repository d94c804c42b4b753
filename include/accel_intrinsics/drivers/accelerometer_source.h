// The accelerometer behind an interface: the accelerometer node publishes whatever an
// AccelerometerSource produces. SimulatedAccelerometer (the default backend) evaluates the truth
// device of model.h at the DUT orientation the gimbal reports (tf), sample by sample.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {

class AccelerometerSource {
 public:
  virtual ~AccelerometerSource() = default;
  virtual std::string name() const = 0;
  // Appends every sample that is ready with a stamp up to about now_s (seconds, node clock).
  virtual void poll(double now_s, std::vector<core::ImuSample>* out) = 0;
  // Appends the DUT temperature readings (degrees C) ready up to about now_s; none by default.
  virtual void poll_temperatures(double /*now_s*/, std::vector<core::TemperatureSample>* /*out*/) {}
  virtual bool publishes_temperature() const { return false; }
  // Variance of one temperature reading, K^2; 0 = unknown.
  virtual double temperature_variance() const { return 0.0; }
  // Variance of one output sample, (m/s^2)^2, for the message covariance; 0 = unknown.
  virtual double variance_per_axis() const { return 0.0; }
  // Forgets the sample clock (after the node's clock jumped backwards).
  virtual void restart() {}
};

// Where the simulated sensor learns its orientation: R_world_dut at a time.
enum class OrientationStatus {
  Available,
  NotYet,  // later than anything known so far: retry at the next poll
  Never,   // older than anything still known: skip the sample
};
using OrientationProvider =
    std::function<OrientationStatus(double t_s, Eigen::Matrix3d* R_world_dut)>;

struct SimulatedAccelerometerOptions {
  // Truth: S (rows u, v, w), O and the sensor-side effects quadratic_nonlinearity,
  // cubic_nonlinearity, offset_drift and timing_lag (gimbal effects belong to the gimbal).
  core::Device truth;
  double rate_hz = 100.0;                                  // sample rate, Hz
  double noise_density = 300e-6 * core::kStandardGravity;  // (m/s^2)/sqrt(Hz), white
  double quantization = 0.0;                               // LSB, m/s^2; 0 = none
  double local_gravity = core::kStandardGravity;           // m/s^2, the simulated site
  std::uint64_t seed = 1;                                  // noise seed (reproducible runs)
  // The DUT's temperature, t since the first gimbal command (core::TemperatureProfile); with
  // temperature.recorded the source also publishes readings. The temperature effects
  // (offset_/scale_temperature_coefficient) act on T - temperature_reference_c: the truth S and O
  // hold at that temperature (a fit reports them at the run's mean temperature instead).
  core::TemperatureProfile temperature;
  double temperature_reference_c = 25.0;
  // Slow bias per accelerometer (core::SimulationOptions, docs/design.md section 12): Gauss-Markov
  // (bias_gm_sigma m/s^2, correlation time bias_gm_tau_s s) and a random walk (bias_random_walk,
  // (m/s^2)/sqrt(s)); 0 = none. Device YAML keys bias/gm_sigma, bias/gm_tau_s, bias/random_walk.
  double bias_gm_sigma = 0.0;
  double bias_gm_tau_s = 0.0;
  double bias_random_walk = 0.0;

  // Throws std::invalid_argument naming the field.
  void validate() const;
  // Per-sample noise standard deviation (simulator.h: noise_density * sqrt(rate_hz / 2)).
  double noise_std() const;
  // Timing lag in seconds (0 without a timing_lag effect).
  double timing_lag_s() const;
};

class SimulatedAccelerometer : public AccelerometerSource {
 public:
  SimulatedAccelerometer(const SimulatedAccelerometerOptions& options,
                         OrientationProvider orientation);

  std::string name() const override { return "simulated"; }
  void poll(double now_s, std::vector<core::ImuSample>* out) override;
  double variance_per_axis() const override;
  void restart() override;

  // t0 of the offset_drift term: the first gimbal command (docs/design.md section 3). Until it is
  // known the drift term is zero.
  void set_time_origin(double t0_s) { time_origin_s_ = t0_s; }

  // Noise-free outputs for a specific force f in the DUT frame at time_s since t0, evaluated
  // with predict_outputs() of model.h (f is written as phase x at angle atan2(f_y, f_z) with an
  // axis tilt asin(f_x / |f|) and g = |f|, which reproduces S f exactly).
  Eigen::Vector3d outputs(const Eigen::Vector3d& f_dut, double time_s,
                          double temperature_offset_k = 0.0) const;
  // The true DUT temperature at time_s since t0, degrees C.
  double temperature_c(double time_s) const { return options_.temperature.at(time_s); }
  // At most 1000 readings per call (bounded work after a long gap); the rest follow, in order,
  // in the next calls, none lost.
  void poll_temperatures(double now_s, std::vector<core::TemperatureSample>* out) override;
  bool publishes_temperature() const override { return options_.temperature.recorded; }
  double temperature_variance() const override {
    return options_.temperature.noise_c * options_.temperature.noise_c;
  }
  // f_dut = R_world_dut^T (0, 0, g): +g on the upward axis (REP 103).
  Eigen::Vector3d specific_force(const Eigen::Matrix3d& R_world_dut) const;

  std::uint64_t skipped_samples() const { return skipped_; }

 private:
  SimulatedAccelerometerOptions options_;
  OrientationProvider orientation_;
  std::vector<double> S_row_major_;
  std::vector<core::Effect> terms_;  // sensor effects, then the axis tilt used to place f
  mutable std::vector<double> values_;
  double noise_std_ = 0.0;
  double lag_s_ = 0.0;
  double time_origin_s_ = std::numeric_limits<double>::quiet_NaN();
  std::int64_t next_index_ = -1;              // sample k is taken at k / rate_hz
  std::int64_t next_temperature_index_ = -1;  // reading k at k / temperature.rate_hz
  std::uint64_t skipped_ = 0;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  std::mt19937_64 temperature_rng_;  // readings: their own stream (the samples' stay the same)
  // The slow bias: its own stream, its state and the true time it was last advanced to.
  core::SlowBiasProcess bias_;
  double bias_t_s_ = std::numeric_limits<double>::quiet_NaN();  // time of the last bias value
  Eigen::Vector3d slow_bias(double t_s);
};

}  // namespace accel_intrinsics
