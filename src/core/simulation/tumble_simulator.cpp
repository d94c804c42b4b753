#include "accel_intrinsics/core/simulation/tumble_simulator.h"

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

Eigen::Vector3d random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Vector3d v;
  do {
    v = Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  } while (v.norm() < 1e-6);
  return v.normalized();
}

// Up direction along the great circle from a to b, fraction s in [0, 1].
Eigen::Vector3d slerp(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double s) {
  const double cosine = std::max(-1.0, std::min(1.0, a.dot(b)));
  const double angle = std::acos(cosine);
  if (angle < 1e-9) return a;
  if (M_PI - angle < 1e-6) {
    // Opposite: turn through any perpendicular axis.
    Eigen::Vector3d axis = a.unitOrthogonal();
    return Eigen::AngleAxisd(angle * s, axis) * a;
  }
  return (std::sin((1.0 - s) * angle) * a + std::sin(s * angle) * b) / std::sin(angle);
}

// The white noise's standard deviation per sample and axis: a one-sided density over the
// Nyquist band rate_hz / 2, scaled per axis.
Eigen::Vector3d sample_noise_stds(const TumbleSimulationOptions& o) {
  return o.noise_scale * (o.noise_density * std::sqrt(o.rate_hz / 2.0));
}

}  // namespace

void validate(const TumbleSimulationOptions& o) {
  validate(o.truth);
  auto positive = [](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0.0))
      throw std::invalid_argument(std::string("tumble simulation: ") + name + " must be > 0");
  };
  positive(o.rate_hz, "rate_hz");
  positive(o.local_gravity, "local_gravity");
  positive(o.rest_min_s, "rest_min_s");
  positive(o.turn_min_s, "turn_min_s");
  positive(o.initial_rest_s, "initial_rest_s");
  if (!(o.noise_density >= 0.0) || !(o.quantization >= 0.0) ||
      !(o.turn_linear_acceleration >= 0.0) || !o.noise_scale.allFinite() ||
      o.noise_scale.minCoeff() < 0.0)
    throw std::invalid_argument(
        "tumble simulation: noise_density, noise_scale, quantization and "
        "turn_linear_acceleration must be >= 0");
  if (o.rest_max_s < o.rest_min_s || o.turn_max_s < o.turn_min_s)
    throw std::invalid_argument("tumble simulation: a max below its min (rest or turn seconds)");
  if (!(o.min_turn_deg >= 0.0 && o.min_turn_deg <= 150.0))
    throw std::invalid_argument("tumble simulation: min_turn_deg must be in [0, 150]");
  if (o.poses < 1) throw std::invalid_argument("tumble simulation: poses must be >= 1");
  SlowBiasProcess::validate(
      o.bias_gm_sigma, o.bias_gm_tau_s, o.bias_random_walk,
      "tumble simulation: ", {"bias_gm_sigma", "bias_gm_tau_s", "bias_random_walk"});
  for (const Eigen::Vector3d& u : o.up_directions)
    if (!(u.norm() > 0.0) || !u.allFinite())
      throw std::invalid_argument("tumble simulation: an up direction is zero or not finite");
}

TumbleRecording simulate_hand_tumble(const TumbleSimulationOptions& o) {
  validate(o);
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const Eigen::Vector3d sigma = sample_noise_stds(o);
  const double dt = 1.0 / o.rate_hz;
  const int poses = o.up_directions.empty() ? o.poses : static_cast<int>(o.up_directions.size());

  SlowBiasProcess bias(o.bias_gm_sigma, o.bias_gm_tau_s, o.bias_random_walk, o.seed);
  bool first_sample = true;

  TumbleRecording rec;
  std::vector<double> effect_values;
  for (const Effect& e : o.truth.effects) effect_values.push_back(e.value);
  auto emit = [&](double t, const Eigen::Vector3d& specific_force) {
    DwellGeometry geom;
    geom.has_direction = true;
    const double magnitude = specific_force.norm();
    geom.direction = specific_force / magnitude;
    geom.time_s = t - o.start_time_s;
    Eigen::Vector3d out = predict_outputs(o.truth, geom, magnitude);
    if (bias.active()) {
      out += first_sample ? bias.value() : bias.advance(dt);
      first_sample = false;
    }
    for (int k = 0; k < 3; ++k) {
      out(k) += sigma(k) * normal(rng);
      if (o.quantization > 0.0) out(k) = std::round(out(k) / o.quantization) * o.quantization;
    }
    rec.samples.push_back(ImuSample{t, out});
  };

  double t = o.start_time_s;
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  // the device lies flat first
  auto rest = [&](double duration) {
    TrueRest r;
    r.t_start_s = t;
    r.up = up;
    const long samples = std::lround(duration * o.rate_hz);
    for (long i = 0; i < samples; ++i) {
      emit(t, o.local_gravity * up);
      t += dt;
    }
    r.t_end_s = t - dt;
    rec.rests.push_back(r);
  };
  rest(o.initial_rest_s);
  for (int k = 0; k < poses; ++k) {
    Eigen::Vector3d next;
    if (o.up_directions.empty()) {
      do {
        next = random_unit(rng);
      } while (std::acos(std::max(-1.0, std::min(1.0, next.dot(up)))) <
               o.min_turn_deg * M_PI / 180.0);
    } else {
      next = o.up_directions[k].normalized();
    }
    const double turn_s = o.turn_min_s + (o.turn_max_s - o.turn_min_s) * uniform(rng);
    const Eigen::Vector3d push = random_unit(rng) * o.turn_linear_acceleration;
    const long samples = std::lround(turn_s * o.rate_hz);
    for (long i = 0; i < samples; ++i) {
      const double s = static_cast<double>(i) / static_cast<double>(samples);
      // Raised-cosine progress; the hand's push rises and falls with the turn.
      const double progress = 0.5 - 0.5 * std::cos(M_PI * s);
      const Eigen::Vector3d direction = slerp(up, next, progress);
      emit(t, o.local_gravity * direction + std::sin(M_PI * s) * push);
      t += dt;
    }
    up = next;
    rest(o.rest_min_s + (o.rest_max_s - o.rest_min_s) * uniform(rng));
  }
  return rec;
}

NoiseModel true_noise_model(const TumbleSimulationOptions& o) {
  const Eigen::Vector3d sigma = sample_noise_stds(o);
  return SlowBiasProcess::add_to(white_noise_model(sigma, o.rate_hz), o.bias_gm_sigma,
                                 o.bias_gm_tau_s, o.bias_random_walk);
}

Device random_tumble_device(std::uint64_t seed, double responsivity_spread, double misalignment_rad,
                            double offset_max, bool random_mounting) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  Device d;
  for (int s = 0; s < 3; ++s) {
    Eigen::Vector3d axis = Eigen::Vector3d::Unit(s);
    for (int k = 0; k < 3; ++k) axis(k) += misalignment_rad * uniform(rng);
    d.S.row(s) = axis.normalized().transpose() * (1.0 + responsivity_spread * uniform(rng));
    d.O(s) = offset_max * uniform(rng);
  }
  if (!random_mounting) return d;
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Quaterniond mount(normal(rng), normal(rng), normal(rng), normal(rng));
  mount.normalize();
  d.S = d.S * mount.toRotationMatrix();
  return d;
}

}  // namespace core
}  // namespace accel_intrinsics
