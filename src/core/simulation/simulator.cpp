#include "accel_intrinsics/core/simulation/simulator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

namespace accel_intrinsics {
namespace core {

double sample_noise_std(const SimulationOptions& options) {
  // White noise of density n_d over the Nyquist band fs/2.
  return options.noise_density * std::sqrt(0.5 * options.rate_hz);
}

Eigen::Vector3d sample_noise_stds(const SimulationOptions& options) {
  return sample_noise_std(options) * options.noise_scale;
}

std::vector<ScheduledPosition> simulation_schedule(const SimulationOptions& options) {
  std::vector<ScheduledPosition> schedule = build_schedule(options.protocol);
  if (options.dwell_s_pattern.empty()) return schedule;
  double shift = 0.0;  // accumulated (dwell - protocol.dwell_s) of the positions before
  for (std::size_t i = 0; i < schedule.size(); ++i) {
    ScheduledPosition& p = schedule[i];
    double dwell = options.dwell_s_pattern[i % options.dwell_s_pattern.size()];
    if (i == 0) dwell = std::max(dwell, options.protocol.initial_rest_s);
    const double scheduled = p.dwell_end_s - p.settled_s;
    p.move_start_s += shift;
    p.settled_s += shift;
    p.dwell_end_s = p.settled_s + dwell;
    shift += dwell - scheduled;
  }
  return schedule;
}

void validate(const SimulationOptions& options) {
  validate(options.truth);
  validate(options.protocol);
  if (!std::isfinite(options.rate_hz) || options.rate_hz <= 0.0) {
    throw std::invalid_argument("simulation: rate_hz must be positive, got " +
                                std::to_string(options.rate_hz));
  }
  if (!std::isfinite(options.noise_density) || options.noise_density < 0.0) {
    throw std::invalid_argument("simulation: noise_density must be non-negative, got " +
                                std::to_string(options.noise_density));
  }
  if (!std::isfinite(options.quantization) || options.quantization < 0.0) {
    throw std::invalid_argument("simulation: quantization must be non-negative");
  }
  if (!std::isfinite(options.local_gravity) || options.local_gravity <= 0.0) {
    throw std::invalid_argument("simulation: local_gravity must be positive");
  }
  const TemperatureProfile& temp = options.temperature;
  if (!std::isfinite(temp.start_c) || !std::isfinite(temp.rate_c_per_s) ||
      !std::isfinite(temp.sine_amplitude_c)) {
    throw std::invalid_argument(
        "simulation: temperature start_c, rate_c_per_s and sine_amplitude_c must be finite");
  }
  if (!std::isfinite(temp.sine_period_s) || temp.sine_period_s <= 0.0) {
    throw std::invalid_argument("simulation: temperature sine_period_s must be positive");
  }
  if (!std::isfinite(temp.noise_c) || temp.noise_c < 0.0) {
    throw std::invalid_argument("simulation: temperature noise_c must be non-negative");
  }
  if (!std::isfinite(temp.rate_hz) || temp.rate_hz <= 0.0) {
    throw std::invalid_argument("simulation: temperature rate_hz must be positive");
  }
  if (options.rate_hz * options.protocol.dwell_s < 2.0) {
    throw std::invalid_argument(
        "simulation: dwell_s * rate_hz must give at least two samples per dwell");
  }
  SlowBiasProcess::validate(options.bias_gm_sigma, options.bias_gm_tau_s, options.bias_random_walk,
                            "simulation: ", {"bias_gm_sigma", "bias_gm_tau_s", "bias_random_walk"});
  if (!options.noise_scale.allFinite() || options.noise_scale.minCoeff() < 0.0) {
    throw std::invalid_argument("simulation: noise_scale must be finite and non-negative");
  }
  for (double d : options.dwell_s_pattern) {
    if (!std::isfinite(d) || options.rate_hz * d < 2.0) {
      throw std::invalid_argument(
          "simulation: every dwell_s_pattern entry times rate_hz must give at least two "
          "samples per dwell, got " +
          std::to_string(d) + " s");
    }
  }
}

namespace {

// Number of sample stamps k / rate in [t_start, t_end).
std::uint64_t samples_in_window(double t_start, double t_end, double rate_hz) {
  const double first = std::ceil(t_start * rate_hz - 1e-9);
  const double end = std::ceil(t_end * rate_hz - 1e-9);
  return end > first ? static_cast<std::uint64_t>(end - first) : 0;
}

double timing_lag_s(const Device& device) {
  double lag = 0.0;
  for (const Effect& e : device.effects) {
    if (e.kind == EffectKind::TimingLag) lag += e.value;
  }
  return lag;
}

bool has_slow_bias(const SimulationOptions& o) {
  return o.bias_gm_sigma > 0.0 || o.bias_random_walk > 0.0;
}

// The slow bias at the sample times k / rate_hz, k = 0..count (exact discretization: the
// Gauss-Markov process starts from its stationary distribution, the random walk from 0), from
// its own random stream.
std::vector<Eigen::Vector3d> slow_bias_path(const SimulationOptions& o, std::uint64_t count) {
  std::vector<Eigen::Vector3d> path(count + 1, Eigen::Vector3d::Zero());
  if (!has_slow_bias(o)) return path;
  SlowBiasProcess bias(o.bias_gm_sigma, o.bias_gm_tau_s, o.bias_random_walk, o.seed);
  const double dt = 1.0 / o.rate_hz;
  path[0] = bias.value();
  for (std::uint64_t k = 1; k <= count; ++k) path[k] = bias.advance(dt);
  return path;
}

}  // namespace

SlowBiasProcess::SlowBiasProcess(double gm_sigma, double gm_tau_s, double random_walk,
                                 std::uint64_t seed)
    : gm_sigma_(gm_sigma),
      gm_tau_s_(gm_tau_s),
      random_walk_(random_walk),
      rng_(seed ^ 0x5bd1e9955bd1e995ull) {}

Eigen::Vector3d SlowBiasProcess::value() {
  if (!started_) {
    for (int s = 0; s < 3; ++s) gm_(s) = gm_sigma_ * normal_(rng_);
    started_ = true;
  }
  return gm_ + rw_;
}

Eigen::Vector3d SlowBiasProcess::advance(double dt_s) {
  value();
  if (!(dt_s > 0.0)) return gm_ + rw_;
  const double phi = gm_sigma_ > 0.0 ? std::exp(-dt_s / gm_tau_s_) : 0.0;
  const double gm_step = gm_sigma_ * std::sqrt(std::max(0.0, 1.0 - phi * phi));
  const double rw_step = random_walk_ * std::sqrt(dt_s);
  for (int s = 0; s < 3; ++s) {
    gm_(s) = phi * gm_(s) + gm_step * normal_(rng_);
    rw_(s) += rw_step * normal_(rng_);
  }
  return gm_ + rw_;
}

NoiseModel true_noise_model(const SimulationOptions& options) {
  return SlowBiasProcess::add_to(white_noise_model(sample_noise_stds(options), options.rate_hz),
                                 options.bias_gm_sigma, options.bias_gm_tau_s,
                                 options.bias_random_walk);
}

void SlowBiasProcess::validate(double gm_sigma, double gm_tau_s, double random_walk,
                               const std::string& prefix, const std::array<std::string, 3>& names) {
  for (double v : {gm_sigma, gm_tau_s, random_walk}) {
    if (!std::isfinite(v) || v < 0.0)
      throw std::invalid_argument(prefix + names[0] + ", " + names[1] + " and " + names[2] +
                                  " must be finite and >= 0");
  }
  if (gm_sigma > 0.0 && !(gm_tau_s > 0.0))
    throw std::invalid_argument(prefix + names[0] + " needs a positive " + names[1]);
}

NoiseModel SlowBiasProcess::add_to(NoiseModel white, double gm_sigma, double gm_tau_s,
                                   double random_walk) {
  for (int s = 0; s < 3; ++s) {
    white.axes[s].gm_sigma = gm_sigma;
    white.axes[s].gm_tau_s = gm_sigma > 0.0 ? gm_tau_s : 0.0;
    white.axes[s].rw_density = random_walk;
  }
  white.source = "simulation truth";
  return white;
}

double TemperatureProfile::at(double t_s) const {
  return start_c + rate_c_per_s * t_s +
         sine_amplitude_c * std::sin(2.0 * kPi * t_s / sine_period_s);
}

double TemperatureProfile::mean_over(double t0_s, double t1_s) const {
  const double span = t1_s - t0_s;
  if (!(span > 0.0)) return at(t0_s);
  const double w = 2.0 * kPi / sine_period_s;
  // Integral of sin(w t) over [t0, t1] = (cos(w t0) - cos(w t1)) / w.
  return start_c + rate_c_per_s * 0.5 * (t0_s + t1_s) +
         sine_amplitude_c * (std::cos(w * t0_s) - std::cos(w * t1_s)) / (w * span);
}

double simulated_reference_temperature_c(const SimulationOptions& options) {
  const std::vector<ScheduledPosition> schedule = simulation_schedule(options);
  if (schedule.empty()) return options.temperature.start_c;
  double sum = 0.0;
  for (const ScheduledPosition& p : schedule)
    sum += options.temperature.mean_over(p.settled_s, p.dwell_end_s);
  return sum / static_cast<double>(schedule.size());
}

PositionTable simulate_position_table(const SimulationOptions& options, RestSamples* first_dwell) {
  validate(options);
  const std::vector<ScheduledPosition> schedule = simulation_schedule(options);
  const std::vector<Eigen::Vector3d> bias =
      has_slow_bias(options)
          ? slow_bias_path(options,
                           samples_in_window(0.0, schedule.back().dwell_end_s, options.rate_hz))
          : std::vector<Eigen::Vector3d>();
  if (first_dwell) *first_dwell = RestSamples();
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Vector3d sigmas = sample_noise_stds(options);
  PositionTable table;
  table.time_origin_s = 0.0;
  table.rows.reserve(schedule.size());
  // Temperature readings draw from their own stream, so the output noise of a seed stays the
  // same whether a temperature is recorded or not.
  const TemperatureProfile& temp = options.temperature;
  std::mt19937_64 temperature_rng(options.seed ^ 0x7e3779b97f4a7c15ull);
  const double t_ref = simulated_reference_temperature_c(options);
  for (const ScheduledPosition& position : schedule) {
    DwellRecord row;
    row.phase = position.phase;
    row.step = position.step;
    row.angle_rad = position.angle_rad;
    row.t_start_s = position.settled_s;
    row.t_end_s = position.dwell_end_s;
    row.n = samples_in_window(row.t_start_s, row.t_end_s, options.rate_hz);
    // The true dwell-mean temperature drives the model; the row records the readings' mean.
    row.temperature_c = temp.mean_over(row.t_start_s, row.t_end_s);
    const DwellGeometry geom = dwell_inputs(row, table.time_origin_s, position.approach, t_ref);
    row.temperature_c = std::numeric_limits<double>::quiet_NaN();
    if (temp.recorded) {
      const std::uint64_t readings = samples_in_window(row.t_start_s, row.t_end_s, temp.rate_hz);
      if (readings > 0) {
        row.temperature_c =
            geom.temperature_offset_k + t_ref +
            temp.noise_c / std::sqrt(static_cast<double>(readings)) * normal(temperature_rng);
      }
    }
    Eigen::Vector3d truth = predict_outputs(options.truth, geom, options.local_gravity);
    const double n = static_cast<double>(row.n);
    const auto k0 = static_cast<std::uint64_t>(std::ceil(row.t_start_s * options.rate_hz - 1e-9));
    if (!bias.empty() && row.n > 0) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (std::uint64_t k = k0; k < k0 + row.n && k < bias.size(); ++k) sum += bias[k];
      if (!(first_dwell && table.rows.empty())) truth += sum / n;
    }
    if (first_dwell && table.rows.empty()) {
      // The samples one by one (white noise from the same stream, the bias per sample).
      Eigen::Vector3d sum = Eigen::Vector3d::Zero(), sum_sq = Eigen::Vector3d::Zero();
      for (std::uint64_t k = k0; k < k0 + row.n; ++k) {
        Eigen::Vector3d x = truth;
        if (!bias.empty() && k < bias.size()) x += bias[k];
        for (int s = 0; s < 3; ++s) x(s) += sigmas(s) * normal(rng);
        first_dwell->stamps_s.push_back(static_cast<double>(k) / options.rate_hz);
        first_dwell->outputs.push_back(x);
        sum += x;
      }
      row.mean = sum / n;
      for (const Eigen::Vector3d& x : first_dwell->outputs) sum_sq += (x - row.mean).cwiseAbs2();
      if (row.n >= 2) row.std = (sum_sq / (n - 1.0)).cwiseSqrt();
      table.rows.push_back(row);
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      const double sigma = sigmas(k);
      row.mean(k) = truth(k) + sigma / std::sqrt(n) * normal(rng);
      if (row.n >= 2 && sigma > 0.0) {
        std::chi_squared_distribution<double> chi2(n - 1.0);
        row.std(k) = sigma * std::sqrt(chi2(rng) / (n - 1.0));
      }
    }
    table.rows.push_back(row);
  }
  return table;
}

Recording simulate_recording(const SimulationOptions& options) {
  validate(options);
  const std::vector<ScheduledPosition> schedule = simulation_schedule(options);
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Vector3d sigma = sample_noise_stds(options);
  const double lag = timing_lag_s(options.truth);

  Recording recording;
  recording.commands.reserve(2 * schedule.size() + 1);
  for (const ScheduledPosition& position : schedule) {
    GimbalEvent event;
    event.phase = position.phase;
    event.step = position.step;
    event.steps = position.steps;
    event.angle_rad = position.angle_rad;
    event.stamp_s = position.move_start_s;
    event.state = GimbalState::Moving;
    recording.commands.push_back(event);
    event.stamp_s = position.settled_s;
    event.state = GimbalState::Settled;
    recording.commands.push_back(event);
  }
  GimbalEvent done = recording.commands.back();
  done.stamp_s = schedule.back().dwell_end_s;
  done.state = GimbalState::Done;
  recording.commands.push_back(done);

  const double end_s = schedule.back().dwell_end_s;
  const TemperatureProfile& temp = options.temperature;
  const double t_ref = simulated_reference_temperature_c(options);
  if (temp.recorded) {
    std::mt19937_64 temperature_rng(options.seed ^ 0x7e3779b97f4a7c15ull);
    const auto readings = static_cast<std::uint64_t>(std::floor(end_s * temp.rate_hz));
    for (std::uint64_t k = 0; k <= readings; ++k) {
      const double t_true = static_cast<double>(k) / temp.rate_hz;
      recording.temperatures.push_back(TemperatureSample{
          t_true + lag, temp.at(t_true) + temp.noise_c * normal(temperature_rng)});
    }
  }
  const auto count = static_cast<std::uint64_t>(std::floor(end_s * options.rate_hz));
  recording.samples.reserve(count + 1);
  const std::vector<Eigen::Vector3d> bias = slow_bias_path(options, count);
  for (std::uint64_t k = 0; k <= count; ++k) {
    const double t_true = static_cast<double>(k) / options.rate_hz;
    const GimbalPose pose = gimbal_pose_at(schedule, t_true);
    DwellGeometry geom = geometry_of(pose, t_true);
    geom.has_temperature = true;
    geom.temperature_offset_k = temp.at(t_true) - t_ref;
    ImuSample sample;
    sample.stamp_s = t_true + lag;  // timing_lag: the IMU stamps its samples late
    sample.outputs = predict_outputs(options.truth, geom, options.local_gravity);
    for (int i = 0; i < 3; ++i) {
      double value = sample.outputs(i) + bias[k](i) + sigma(i) * normal(rng);
      if (options.quantization > 0.0)
        value = options.quantization * std::round(value / options.quantization);
      sample.outputs(i) = value;
    }
    recording.samples.push_back(sample);
  }
  return recording;
}

void feed_in_stamp_order(const Recording& recording, DwellAssembler* assembler) {
  std::size_t c = 0, k = 0;
  for (const ImuSample& sample : recording.samples) {
    while (c < recording.commands.size() && recording.commands[c].stamp_s <= sample.stamp_s) {
      assembler->add_command(recording.commands[c++]);
    }
    while (k < recording.temperatures.size() &&
           recording.temperatures[k].stamp_s <= sample.stamp_s) {
      assembler->add_channel_sample(channel_sample(recording.temperatures[k++]));
    }
    assembler->add_sample(sample);
  }
  while (c < recording.commands.size()) assembler->add_command(recording.commands[c++]);
  while (k < recording.temperatures.size())
    assembler->add_channel_sample(channel_sample(recording.temperatures[k++]));
  assembler->flush();
}

}  // namespace core
}  // namespace accel_intrinsics
