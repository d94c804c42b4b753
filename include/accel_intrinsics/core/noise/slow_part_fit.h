// The slow part of a noise model fitted to a whole run by restricted (REML) likelihood
// (docs/design.md section 12). One definition for the gimbal fit (discrepancy.h slow_part_from_run)
// and the hand tumble (tumble.h slow_part_from_tumble): both hand it the part of their
// normalized residuals outside their model's Jacobian (w = U^T z, U an orthonormal basis of the
// complement) and the slow kernels projected the same way (U^T K U), and keep the shape of
// highest likelihood with its amplitude's posterior mean (best_slow_amplitude).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace core {

// The shapes a run's slow part is chosen among (unit amplitude, white_std 0): Gauss-Markov of
// unit variance at correlation times from 0.5 s to 5 times the run's span (5 per decade), a
// random walk of unit density, and the rest's own slow part when it has one (its amplitude free).
std::vector<AxisNoiseModel> slow_part_shapes(double span_s, const AxisNoiseModel& rest_axis);

// An orthonormal basis of the complement of X's column space (n x (n - rank)); zero columns when
// X has full row rank.
Eigen::MatrixXd residual_complement(const Eigen::MatrixXd& X);

struct SlowAmplitude {
  // The amplitude's posterior mean under Jeffreys' prior (below); 0 when the kernel is null.
  double amplitude = 0.0;
  // The restricted log-likelihood's maximum over a >= 0, up to a constant that is the same for
  // every kernel against one base: compare values from one base only.
  double log_likelihood = 0.0;
  // Relative posterior variance of the amplitude (var(a) / mean(a)^2): how well the run pinned
  // the slow part's scale (AxisNoiseModel::slow_scale_rel_var).
  double relative_variance = 0.0;
};

// The amplitude a >= 0 of w ~ N(0, B + a M): w and M already projected (w = U^T z,
// M = U^T K U), B = base_L base_L^T (an empty base_L: B = I). Restricted likelihood on a
// logarithmic grid over twelve decades around 1 / mean eigenvalue; the amplitude reported is the
// posterior mean under Jeffreys' prior sqrt(I(a)), not the maximum. Why: one run often leaves a
// slow part barely seen (a random walk over a 6 min gimbal run: relative variance 0.5 to 3), and
// the maximum then sits at or near a = 0 on a third of the axes, so the uncertainties that rest
// on it (the offsets under a walk) came out several times too small (RMS z 2.3, seeds 900..959);
// the posterior mean keeps what the data do not exclude. Measured: offsets RMS z 0.91, the
// intrinsics' 0.96 (test/core/noise/correlated_noise_test.cpp). The price, on white data: the
// offsets' uncertainties about 4 times the white fit's (the walk the run cannot exclude), the
// responsivities' 1.1 times. Tried, to spare white data: no slow part on an axis unless the run
// shows one (log-likelihood above a = 0 by 2) where the rest's model had none: white data 1.1
// times, but random-walk offsets 1.72 (gimbal) and 1.40 (tumble), overconfident again; not kept.
SlowAmplitude best_slow_amplitude(const Eigen::VectorXd& w, const Eigen::MatrixXd& M,
                                  const Eigen::MatrixXd& base_L = Eigen::MatrixXd());

// Keep a random walk whose restricted log-likelihood is within this of the best shape's (a
// likelihood ratio of e^2, about the 95 % point of a one-parameter chi-square / 2).
constexpr double kWalkLikelihoodMargin = 2.0;

struct SlowShapeChoice {
  int shape = -1;  // index into the shapes; -1: no slow part (amplitude 0)
  SlowAmplitude fit;
};
// The shape of highest restricted likelihood among `shapes` (their kernels projected as for
// best_slow_amplitude), or the plain random walk (rw_density > 0, no Gauss-Markov part) when its
// log-likelihood is within kWalkLikelihoodMargin of the best. Why: one run cannot tell a random
// walk from a Gauss-Markov bias of long correlation time, whose level the offsets absorb (so the
// run never sees its variance), or from a shorter one of larger variance; the walk's variance
// keeps growing over the run, so the offsets' uncertainty does not rest on the bias having
// stopped wandering. Measured on random-walk runs: with the best shape alone the offsets' RMS
// z-score was 2.2 (tumble) and 2.8 (gimbal).
SlowShapeChoice choose_slow_shape(const Eigen::VectorXd& w,
                                  const std::vector<Eigen::MatrixXd>& projected_kernels,
                                  const std::vector<AxisNoiseModel>& shapes,
                                  const Eigen::MatrixXd& base_L = Eigen::MatrixXd());

// The time span of a run's rows: earliest t_start and latest t_end.
struct RunSpan {
  double t_first = 0.0;
  double t_last = 0.0;
  double length() const { return t_last - t_first; }
};
RunSpan run_span(const PositionTable& table);

// What a fit of the slow part chose, for NoiseModel::source: "; slow part fitted to <what>
// (restricted likelihood, ...): u: Gauss-Markov .. over .. s, random walk .. per sqrt(s)
// [relative std of the scale]; v ..." (a part that is zero left out; "no slow part" when both are).
std::string slow_part_note(const std::string& fitted_to, const NoiseModel& model);

// A shape scaled by a fitted amplitude (variance factor): the axis model it stands for, white_std
// 0, with the amplitude's relative variance as its slow_scale_rel_var.
AxisNoiseModel scaled_shape(const AxisNoiseModel& shape, const SlowAmplitude& fitted);

// The slow part refitted to a gimbal run's dwell means (discrepancy.h slow_part_from_run, which
// fits the base model and hands over its residuals, the dwells' white standard errors `se` and
// the Jacobian J of the base model by its parameters, rows 3 row + s, each divided by se):
// per accelerometer, the restricted likelihood of the residuals outside J's column space under
// each of slow_part_shapes; the long rest enters as its blocks (NoiseModel::rest_blocks) when
// `model` carries them. Returns `model` with its slow part replaced and the source noted.
NoiseModel slow_part_from_residuals(const PositionTable& table, NoiseModel model,
                                    const std::vector<Eigen::Vector3d>& residuals,
                                    const std::vector<Eigen::Vector3d>& se,
                                    const Eigen::MatrixXd& J);

}  // namespace core
}  // namespace accel_intrinsics
