// Noise figures (docs/design.md section 8).
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
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/position_table.h"

namespace accel_intrinsics {
namespace core {

// White noise from the dwells of a run: the sample standard deviations pooled over the dwells
// (weights n - 1), the sample rate from the dwells' counts and durations (sum n / sum (t_end -
// t_start)).
struct DwellNoise {
  Eigen::Vector3d density = Eigen::Vector3d::Zero();  // (m/s^2)/sqrt(Hz): sample_std / sqrt(rate)
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
AllanCurve overlapping_allan_deviation(const std::vector<Eigen::Vector3d>& samples, double rate_hz,
                                       int points_per_decade = 10);
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

// ---- Noise that is not white (docs/design.md section 12)
// -----------------------------------------
//
// The noise of one output as a sum of independent parts: a white noise of per-sample standard
// deviation white_std, a first-order Gauss-Markov bias (stationary, variance gm_sigma^2,
// correlation exp(-|dt| / gm_tau_s)), and a random-walk bias (variance growing as
// rw_density^2 t from the start of the run, rw_density in (m/s^2)/sqrt(s)). The slow parts
// make a dwell mean scatter more than std / sqrt(n) and make neighbouring dwell means err
// together; slow_covariance() gives their covariance exactly (closed forms of the double
// integral over the two dwells).
struct AxisNoiseModel {
  double white_std = 0.0;   // per-sample standard deviation, m/s^2
  double gm_sigma = 0.0;    // m/s^2
  double gm_tau_s = 0.0;    // s
  double rw_density = 0.0;  // (m/s^2)/sqrt(s)
  // How well the slow part's scale is known: the relative variance of the factor that multiplies
  // gm_sigma^2 and rw_density^2 together, as the fit that estimated it found it
  // (slow_part_fit.h); 0 = taken as known (a true or assumed model). A fit widens its covariance
  // by it (estimated_scale_covariance).
  double slow_scale_rel_var = 0.0;
  bool slow() const { return gm_sigma > 0.0 || rw_density > 0.0; }
};

struct NoiseModel {
  AxisNoiseModel axes[3];
  double rate_hz = 0.0;
  // Where it came from (the long rest): its time span and sample count; empty source = assumed
  // (white, or given by the caller).
  std::string source;
  double rest_t_start_s = 0.0;
  double rest_t_end_s = 0.0;
  std::size_t rest_samples = 0;
  // The long rest cut into consecutive blocks (noise_model_of_run: about 30 of at least 1 s;
  // mean, std and n of each): what the rest saw of the slow part along all three accelerometers,
  // for a fit of the slow part to the whole run (tumble.h slow_part_from_tumble). Empty when the
  // model did not come from a recorded rest.
  std::vector<DwellRecord> rest_blocks;

  // True when no axis has a slow part: every fit then weights by std / sqrt(n) exactly as
  // before.
  bool white() const;
  // True when the slow part is to be fitted to the whole run (slow_part_from_run,
  // slow_part_from_tumble): it has one, or it came from a recorded rest (rest_blocks), whose
  // white look does not rule out a slow part the run shows (a 120 s rest hides a walk whose
  // Allan deviation crosses the white noise's near 30 s).
  bool slow_part_to_fit() const { return !white() || !rest_blocks.empty(); }
  // "white", "gauss_markov", "random_walk" or "gauss_markov+random_walk".
  std::string kind() const;
  // Covariance of the means of axis `axis` over [a0, a1] and [b0, b1] from the slow parts
  // (the random walk counted from t_origin). Intervals of zero length are points.
  double slow_covariance(int axis, double a0, double a1, double b0, double b1,
                         double t_origin) const;
  // Variance of the mean of n samples over duration_s seconds (the random walk from the
  // dwell's start): white_std^2 / n + the slow part.
  double variance_of_mean(int axis, double duration_s, double n) const;
  // Allan variance the model predicts at cluster time tau_s.
  double allan_variance(int axis, double tau_s) const;
};

// A white model (kind "white") with the given per-sample stds.
NoiseModel white_noise_model(const Eigen::Vector3d& white_std, double rate_hz);

// The noise model of a static record (samples at rate_hz, at least 64 and 10 s): per axis,
// AVAR(tau) = white_std^2 / (rate tau) + AVAR_GM(tau; sigma, tau_c) + rw^2 tau / 3 fitted to its
// overlapping Allan variance by weighted least squares (weights from the Allan points' relative
// uncertainty; non-negative coefficients; tau_c on a logarithmic grid from 0.5 s to 5 times the
// record, the best one kept). A slow part that the fit does not resolve is set to zero.
// Throws std::invalid_argument for a record too short or a rate that is not positive.
NoiseModel estimate_noise_model(const std::vector<Eigen::Vector3d>& samples, double rate_hz);
// The same fit on a record's Allan curve at 10 points per decade (curve.samples and
// curve.rate_hz the record's): what the streamed long rest gives (rest_accumulator.h).
NoiseModel estimate_noise_model(const AllanCurve& curve);

// The long rest of a run (docs/design.md section 12), as a time span: on a gimbal run the first
// dwell (phase x, step 0) when it lasts at least `initial_rest_s` (> 0); in any recorded run a
// dwell at least 10 times the median dwell length (the first such); nothing otherwise.
struct LongRest {
  std::size_t row = 0;  // index in the table
  double t_start_s = 0.0;
  double t_end_s = 0.0;
  std::string reason;
};
std::optional<LongRest> find_long_rest(const PositionTable& table, double initial_rest_s = 0.0);

// The noise model of a run: its long rest found in the table, the raw samples (stamps, outputs)
// that fall inside it accumulated in stamp order (RestAccumulator, rest_accumulator.h: the
// model the live run's LongRestRecorder gives) and estimated with estimate_noise_model, and the
// rest's blocks (rest_blocks: the rest cut into kRestBlocks blocks of about equal duration, at
// least 1 s each, a block with fewer than 2 samples left out); nothing when the run has no long
// rest or fewer than 64 samples inside it.
constexpr int kRestBlocks = 30;
std::optional<NoiseModel> noise_model_of_run(const PositionTable& table,
                                             const std::vector<double>& stamps_s,
                                             const std::vector<Eigen::Vector3d>& outputs,
                                             double initial_rest_s = 0.0);

// LongRestRecorder (the live run's long rest, accumulated as it comes): rest_accumulator.h.

// The dwell means' covariance a noise model implies, per accelerometer s: C_s = D_s R_s D_s with
// D_s = diag(se_s) (the white standard errors the fit uses) and R_s = I + D_s^-1 K_s D_s^-1 (K_s:
// slow_covariance between the rows). Stores the lower Cholesky factor of each R_s; whiten()
// applies L_s^-1 to a vector of normalized values (residual / se), interleaved as 3 row + s, so
// that white and correlated noise alike give independent unit-variance entries.
struct DwellCorrelation {
  Eigen::MatrixXd L[3];
  std::size_t rows = 0;
  void whiten(Eigen::VectorXd& interleaved) const;
  // The same for a matrix whose rows are interleaved (each column whitened).
  void whiten_columns(Eigen::MatrixXd& interleaved) const;
};
// Nothing (white) when the model has no slow part.
std::shared_ptr<const DwellCorrelation> dwell_correlation(const PositionTable& table,
                                                          const std::vector<Eigen::Vector3d>& se,
                                                          const NoiseModel& model);

// The covariance of a generalized least-squares estimate whose noise model's slow parts were
// estimated from the same data (AxisNoiseModel::slow_scale_rel_var > 0): Kenward and Roger's
// adjusted covariance (Biometrics 53, 1997) for one variance parameter per accelerometer, the
// factor theta_s that scales its slow part (theta_s = 1 at the estimate, Var = slow_scale_rel_var):
//   Phi_A = Phi + 2 Phi [sum_s Var(theta_s) (Q_s - P_s Phi P_s)] Phi,
// P_s = J_s^T H_s J_s, Q_s = J_s^T H_s^2 J_s, H_s = L_s^-1 (R_s - I) L_s^-T (the slow part in
// the whitened frame), J_s the rows of accelerometer s of the whitened Jacobian, Phi its
// unscaled (J^T J)^-1. Why: the plug-in Phi treats the estimated slow part as known; a 2 s dwell
// run pins a random walk's density only to tens of percent (measured under a random walk, with
// the likelihood's maximum as the amplitude: offsets' RMS z 2.27 with Phi, 1.98 widened;
// test/core/noise/correlated_noise_test.cpp). The widening is
// large where the slow part is both poorly known and what the parameter's uncertainty rests on
// (the offsets under a walk), small elsewhere. `whitened_jacobian`: 3 rows per dwell (u, v, w
// interleaved, as DwellCorrelation::whiten_columns leaves them), one column per parameter.
Eigen::MatrixXd estimated_scale_covariance(const NoiseModel& model, const DwellCorrelation& corr,
                                           const Eigen::MatrixXd& whitened_jacobian,
                                           const Eigen::MatrixXd& phi);
// True when some axis's slow part carries an estimated scale (slow_scale_rel_var > 0).
bool has_estimated_scale(const NoiseModel& model);

// The flat floor of a bias instability B: sqrt(2 ln 2 / pi) B.
constexpr double kBiasInstabilityFloor = 0.66428;

}  // namespace core
}  // namespace accel_intrinsics
