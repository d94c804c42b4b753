// Noise figures (DESIGN.md section 8).
//
// Conventions. A white noise of continuous-time (two-sided, Kalibr's) density N, in
// (m/s^2)/sqrt(Hz), sampled at rate f gives samples of standard deviation sigma = N sqrt(f); so
// N = sigma / sqrt(f). (A datasheet's one-sided density over the band 0..f/2 is sqrt(2) N; the
// simulator's noise_density is that one: sample std = noise_density sqrt(f/2).) On the Allan
// deviation the white noise is the line N / sqrt(tau), read at tau = 1 s; a random walk of
// density K, in (m/s^3)/sqrt(Hz), is the line K sqrt(tau / 3), read at tau = 3 s; a bias
// instability (flicker) B, in m/s^2, is the flat floor sqrt(2 ln 2 / pi) B = 0.664 B, read at
// the curve's minimum.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "accel_intrinsics/core/position_table.h"

namespace accel_intrinsics {
namespace core {

// White noise from the dwells of a run: the sample standard deviations pooled over the dwells
// (weights n - 1), the sample rate from the dwells' counts and durations (sum n / sum (t_end -
// t_start)).
struct DwellNoise {
  Eigen::Vector3d density = Eigen::Vector3d::Zero();      // (m/s^2)/sqrt(Hz): sample_std / sqrt(rate)
  Eigen::Vector3d density_std = Eigen::Vector3d::Zero();  // its standard uncertainty
  Eigen::Vector3d sample_std = Eigen::Vector3d::Zero();   // pooled per-sample std, m/s^2
  double rate_hz = 0.0;
  std::uint64_t dof = 0;  // sum (n - 1)
};
// Nothing when the dwells hold fewer than two samples each or no duration.
std::optional<DwellNoise> dwell_noise(const PositionTable& table);

// Overlapping Allan deviation of the three outputs of a static record sampled at rate_hz, from
// the cumulative sums of the samples (one pass per tau, no loop per cluster), at cluster sizes m
// spaced about `points_per_decade` per decade from 1 to n / 4. For m > 16 the clusters start m /
// 16 samples apart instead of every sample: neighbouring overlapping clusters are nearly the same
// (94 % shared), so this keeps the estimator's precision (test: within 2 % of every-sample starts)
// and makes the cost about 30 n for any record length.
struct AllanCurve {
  std::vector<double> tau_s;
  std::vector<Eigen::Vector3d> adev;  // m/s^2, per tau
  // Relative standard uncertainty of each adev: 1 / sqrt(2 (n / m - 1)) (the clusters that do not
  // overlap; conservative for the overlapping estimator).
  std::vector<double> relative_std;
  std::size_t samples = 0;
  double rate_hz = 0.0;
};
// Throws std::invalid_argument for fewer than 16 samples or a rate that is not positive.
AllanCurve overlapping_allan_deviation(const std::vector<Eigen::Vector3d>& samples,
                                       double rate_hz, int points_per_decade = 10);
// The same for one series (the benchmark and the curve of one axis).
std::vector<double> overlapping_allan_deviation(const std::vector<double>& x, double rate_hz,
                                                const std::vector<std::size_t>& cluster_sizes,
                                                std::size_t max_stride_divisor = 16);

// N, B (with its tau) and K of one output from its Allan curve. First AVAR(tau) = a / tau + b +
// c tau (white, flat, random walk) is fitted by weighted least squares (terms that come out
// negative are dropped); then N is the -1/2 line through the points where a / tau makes 90 % of
// the model, read at tau = 1 s, and K the +1/2 line through the points where c tau makes 70 % of
// it, read at tau = 3 s (when c is not significant, K comes from c alone: sqrt(3 c), and its
// uncertainty is at least sqrt(3 u(c)), the smallest random walk the record resolves); B is the
// minimum of the curve / 0.664, with its tau. The uncertainty of a value read on a line is the
// RMS relative uncertainty of its points; of B, that of the minimum's point.
struct NoiseParameters {
  double white_density = 0.0;  // N, (m/s^2)/sqrt(Hz)
  double white_density_std = 0.0;
  double bias_instability = 0.0;  // B, m/s^2
  double bias_instability_std = 0.0;
  double bias_instability_tau_s = 0.0;
  // False when the minimum is the curve's last point (no floor in the record: B is then only an
  // upper bound).
  bool bias_instability_floor_seen = false;
  double random_walk = 0.0;  // K, (m/s^3)/sqrt(Hz)
  double random_walk_std = 0.0;
  int white_points = 0;        // points on the -1/2 line (0: N from the model's a)
  int random_walk_points = 0;  // points on the +1/2 line (0: K from the model's c)
};
NoiseParameters noise_parameters(const AllanCurve& curve, int axis);

// A static record analysed (noise_report): the rate from the stamps ((n - 1) / (t_last -
// t_first)), the Allan curve of the three outputs and N, B, K of each.
struct StaticRecordNoise {
  AllanCurve curve;
  NoiseParameters axes[3];
  double rate_hz = 0.0;
  double duration_s = 0.0;
};
// Throws std::invalid_argument naming what is wrong: fewer than 100 samples, stamps not
// increasing (the index of the first one that is not), non-finite outputs.
StaticRecordNoise analyze_static_record(const std::vector<double>& stamps_s,
                                        const std::vector<Eigen::Vector3d>& outputs);

// The flat floor of a bias instability B: sqrt(2 ln 2 / pi) B.
constexpr double kBiasInstabilityFloor = 0.66428;

}  // namespace core
}  // namespace accel_intrinsics
