// The simulated test stand: a truth device on the schedule of protocol.h, evaluated with the
// rig model of model.h, with white noise and optional quantization. Seeded and reproducible.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/gimbal_kinematics.h"
#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace core {

// The DUT's temperature during a simulated run (docs/design.md section 10), t in seconds since the
// first gimbal command: T(t) = start_c + rate_c_per_s t + sine_amplitude_c sin(2 pi t /
// sine_period_s). The temperature effects act on the true T; what is recorded (imu/temperature,
// the position table's temperature_c) adds white reading noise. A sinusoid (warm-up and cool-down)
// makes temperature and time differ, so drift and a temperature coefficient can be separated; a
// linear ramp alone cannot separate them.
struct TemperatureProfile {
  bool recorded = false;  // record the readings (temperature_c, Recording::temperatures)
  double start_c = 25.0;  // degrees C at t = 0
  double rate_c_per_s = 0.0;
  double sine_amplitude_c = 0.0;
  double sine_period_s = 600.0;
  double noise_c = 0.0;  // standard deviation of one reading, K
  double rate_hz = 1.0;  // readings per second

  double at(double t_s) const;
  // Mean of T over [t0_s, t1_s] (exact); T(t0_s) for an empty interval.
  double mean_over(double t0_s, double t1_s) const;
};

struct SimulationOptions {
  Device truth;  // S, O and effect terms (all of them, incl. gimbal side)
  ProtocolOptions protocol;
  double rate_hz = 100.0;                            // IMU sample rate
  double noise_density = 300e-6 * kStandardGravity;  // (m/s^2)/sqrt(Hz), white
  double quantization = 0.0;                         // LSB in m/s^2; 0 = none
  // Unequal accelerometers and dwells (tests of the weighting): accelerometer s has noise
  // density noise_density * noise_scale(s); position i of the schedule (build_schedule order)
  // dwells dwell_s_pattern[i % size] seconds instead of protocol.dwell_s (empty: all equal),
  // the later positions shifted in time accordingly.
  Eigen::Vector3d noise_scale = Eigen::Vector3d::Ones();
  std::vector<double> dwell_s_pattern;
  double local_gravity = kStandardGravity;
  std::uint64_t seed = 1;
  TemperatureProfile temperature;  // constant 25 C and not recorded by default
  // Slow bias (docs/design.md section 12), independent per accelerometer, added to every sample: a
  // first-order Gauss-Markov process (stationary, standard deviation bias_gm_sigma in m/s^2,
  // correlation exp(-|dt| / bias_gm_tau_s), the usual model of bias instability) and a random
  // walk from 0 at the first gimbal command (standard deviation bias_random_walk sqrt(t), in
  // (m/s^2)/sqrt(s)). Drawn from their own random stream: the white noise of a seed is the same
  // with or without them. 0 (default): none.
  double bias_gm_sigma = 0.0;
  double bias_gm_tau_s = 0.0;
  double bias_random_walk = 0.0;
};

// The noise model the options imply (white_std = sample_noise_stds, and the slow bias): what an
// estimate from a long rest should find.
NoiseModel true_noise_model(const SimulationOptions& options);

// The slow bias of docs/design.md section 12, one independent process per accelerometer: a
// first-order Gauss-Markov process (stationary standard deviation gm_sigma, correlation time
// gm_tau_s, started from its stationary distribution) plus a random walk from 0 (standard
// deviation random_walk sqrt(t)), advanced by the exact discretization over any step. Its own
// random stream (from seed), so switching it on leaves the other draws of a simulation as they
// were. One definition for the simulators (simulate_position_table, simulate_recording) and the
// stand's simulated accelerometer.
class SlowBiasProcess {
 public:
  SlowBiasProcess(double gm_sigma, double gm_tau_s, double random_walk, std::uint64_t seed);
  bool active() const { return gm_sigma_ > 0.0 || random_walk_ > 0.0; }
  // The bias now; the first call draws the stationary start.
  Eigen::Vector3d value();
  // Moves the processes on by dt_s >= 0 seconds and returns the bias then.
  Eigen::Vector3d advance(double dt_s);

  // The parameters' checks, one definition for every place that configures a slow bias: each
  // finite and >= 0, a Gauss-Markov sigma with a positive time. Throws std::invalid_argument
  // starting with `prefix` and naming the parameters as the caller's users spell them
  // ({"bias_gm_sigma", ...} in a simulation, {"bias/gm_sigma", ...} as ROS parameters).
  static void validate(double gm_sigma, double gm_tau_s, double random_walk,
                       const std::string& prefix, const std::array<std::string, 3>& names);
  // `white` with this bias's slow part on every axis: what an estimate from a long rest should
  // find (the simulators' true_noise_model).
  static NoiseModel add_to(NoiseModel white, double gm_sigma, double gm_tau_s, double random_walk);

 private:
  double gm_sigma_, gm_tau_s_, random_walk_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  bool started_ = false;
  Eigen::Vector3d gm_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d rw_ = Eigen::Vector3d::Zero();
};

// Raw samples of the first dwell, for the noise model (simulate_position_table fills it when
// asked): stamps in seconds since the first gimbal command and the outputs.
struct RestSamples {
  std::vector<double> stamps_s;
  std::vector<Eigen::Vector3d> outputs;
};

// T_ref of the simulated run: the mean over the schedule's dwells of the true dwell-mean
// temperature (what reference_temperature_c() gives for noise-free readings).
double simulated_reference_temperature_c(const SimulationOptions& options);

// Per-sample noise standard deviation: noise_density * sqrt(rate_hz / 2) (noise_scale = 1).
double sample_noise_std(const SimulationOptions& options);
// Per accelerometer: sample_noise_std * noise_scale(s).
Eigen::Vector3d sample_noise_stds(const SimulationOptions& options);
// build_schedule(protocol) with the dwells of dwell_s_pattern: the timeline both simulators use.
std::vector<ScheduledPosition> simulation_schedule(const SimulationOptions& options);

// Throws std::invalid_argument naming the field.
void validate(const SimulationOptions& options);

// Dwell means drawn directly from their exact distributions (mean: normal with sigma/sqrt(n);
// sample std: sigma * sqrt(chi2(n-1)/(n-1))), model evaluated at mid-dwell. Fast: use for Monte
// Carlo. Quantization and timing lag are ignored here (use simulate_recording).
// With `first_dwell`, the first dwell's samples are drawn one by one and returned there (its mean
// and std are theirs), so a test can estimate the noise model from the long rest as a recorded
// run would.
PositionTable simulate_position_table(const SimulationOptions& options,
                                      RestSamples* first_dwell = nullptr);

// Raw streams: gimbal events and IMU samples as the nodes would publish them, including the
// samples taken while moving (angle interpolated along the move) and timing lag (stamps late).
struct Recording {
  std::vector<GimbalEvent> commands;
  std::vector<ImuSample> samples;
  std::vector<TemperatureSample> temperatures;  // when options.temperature.recorded
};
Recording simulate_recording(const SimulationOptions& options);

// Feeds a recording to an assembler in stamp order (a command before a sample at equal stamps),
// as a recorded run would arrive, then flushes it.
void feed_in_stamp_order(const Recording& recording, DwellAssembler* assembler);

}  // namespace core
}  // namespace accel_intrinsics
