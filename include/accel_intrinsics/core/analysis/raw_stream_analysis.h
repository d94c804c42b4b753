// Analyses that need the raw streams (gimbal events and every IMU sample, e.g. from a bag), not
// just the dwell means of the position table.
//
// timing_lag (docs/design.md section 3): the IMU stamps its samples late by `lag` seconds relative
// to the gimbal. During a dwell the gimbal is at rest, so the dwell means cannot show it; during a
// move the outputs change, and with late stamps the change appears `lag` seconds late relative to
// the MOVING/SETTLED commands. The estimator rebuilds the commanded trajectory from the events
// (schedule_from_commands + gimbal_pose_at of simulator.h: the one motion model shared with the
// simulator and the gimbal controller), evaluates the fitted device along it at stamp - lag, and
// fits lag by weighted least squares on the samples taken while the gimbal moved.
//
// Time axes. GimbalEvent and ImuSample stamps are absolute (ROS time, seconds). Everything inside
// the estimator runs on ONE relative axis t = stamp - time_origin_s, where time_origin_s is the
// t0 of the drift term: the table's time origin (the first gimbal command, as the DwellAssembler
// and the simulator set it), or, when that is unknown (NaN), the stamp of the first command. The
// schedule is expressed on that axis, so gimbal_pose_at(schedule, t - lag) and the drift time
// DwellGeometry::time_s = t - lag (the true time of the sample since t0) use the same clock.
//
// The library prints nothing; everything is in the returned structures.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <deque>
#include <limits>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/effects.h"
#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {

// Stamp of the earliest command (NaN when there is none).
double first_command_stamp(const std::vector<GimbalEvent>& commands);

// The timeline of a run rebuilt from its gimbal events, on the axis t = stamp - time_origin_s:
// one entry per position that has both its MOVING and its SETTLED; move_start_s = MOVING stamp,
// settled_s = SETTLED stamp, dwell_end_s = stamp of the next MOVING or DONE (+infinity when the
// recording ends before either). Events are taken in stamp order (stable for equal stamps), so
// bag receive order does not matter. `approach` follows dwell_geometries(): per phase, the first
// visit is +1, an increasing angle +1, a decreasing one -1, a repeated angle reverses the
// previous approach (the turn of a two-way sweep). A MOVING without SETTLED (aborted move) ends
// the previous dwell and yields no position; a SETTLED that does not match the pending MOVING
// (phase and step) is ignored. On simulated events (simulate_recording) this reproduces
// build_schedule() exactly, so gimbal_pose_at() evaluates measured data with the same profile.
std::vector<ScheduledPosition> schedule_from_commands(const std::vector<GimbalEvent>& commands,
                                                      double time_origin_s);
// Same, relative to the first command's stamp (the convention of build_schedule: t = 0 at the
// first MOVING).
std::vector<ScheduledPosition> schedule_from_commands(const std::vector<GimbalEvent>& commands);

// Per-sample noise standard deviation of each accelerometer pooled over the dwells of a table:
// sqrt(sum (n_i - 1) std_i^2 / sum (n_i - 1)) over rows with n >= 2, leaving out dwells whose
// variance exceeds the median one by more than 5 times its chi-square spread sqrt(2 / (n_i - 1))
// (a dwell that caught a few samples of a move or a remount, e.g. with IMU stamps early, would
// otherwise dominate the pool); zero when no row has a usable std.
Eigen::Vector3d pooled_sample_std(const PositionTable& table);

struct TimingLagEstimateOptions {
  // Samples whose stamp lies in [MOVING - margin, SETTLED + margin] of a move within a phase
  // (clipped to the neighbouring dwells) are used. The set is chosen by stamp, once, so it does
  // not change with the trial lag and chi2(lag) vs chi2(0) is a proper likelihood ratio. The
  // margin only costs a few samples at rest; it should exceed the largest plausible |lag| so that
  // the samples taken at the end of a move but stamped after SETTLED are kept.
  double margin_s = 0.1;
  // The estimate is confined to [-max_abs_lag_s, max_abs_lag_s]. Keep it below the shortest
  // dwell minus margin_s: the trajectory at stamp - lag then never enters a phase change (where
  // the DUT is remounted and no trajectory is known). result.at_bound tells when it was hit.
  double max_abs_lag_s = 0.25;
  // Fewer usable move samples than this: result.ok = false with a message.
  std::size_t min_move_samples = 50;
  // Central-difference step for d(output)/d(lag), seconds. The raised-cosine profile has a time
  // scale (move + settle)/pi ~ 0.5 s; with h = 1e-4 s the truncation error h^2 R'''/6 is ~1e-8 of
  // the derivative, and the round-off (eps |R| / h, plus the ulp of stamps of a few hundred s)
  // is ~1e-9 of it; h is far below the sample period, so only a sample within h of a move's
  // start or end (where the acceleration jumps) sees an O(h) error, of a derivative that is ~0.
  double derivative_step_s = 1e-4;
  int max_iterations = 30;       // Gauss-Newton steps (with step halving)
  double alpha = 0.05;           // `detected` when p_value <= alpha
  double detection_power = 0.9;  // for detection_threshold_s
};

struct TimingLagEstimate {
  bool ok = false;  // enough move samples, a finite estimate inside the bounds; else see `message`
  std::string message;  // one line: the summary, or why the estimate is not available
  double lag_s = 0.0;   // IMU stamps late by lag_s (negative: early), the WLS estimate
  double std_s = 0.0;   // standard uncertainty (see below)
  // Likelihood ratio of lag = lag_s against lag = 0: chi2(0) - chi2(lag_s) over the move samples,
  // corrected for the uncertainty of the base fit (see `base_fit_leak`); ~chi2(1) without a lag.
  double lr_chi2 = 0.0;
  double score_chi2 = 0.0;  // score statistic at lag = 0, same correction; ~chi2(1) too
  double p_value = 1.0;     // P(chi2(1) >= lr_chi2)
  bool detected = false;    // ok && p_value <= alpha
  // |lag| the test at `alpha` detects with probability `detection_power` (normal theory).
  double detection_threshold_s = 0.0;
  double chi2 = 0.0;          // of the move samples at lag_s (normalized by sample_sigma)
  double reduced_chi2 = 0.0;  // chi2 / (3 samples_used - 1)
  // Relative variance added by the base fit's covariance: var = (1 + base_fit_leak) / J^T W J.
  double base_fit_leak = 0.0;
  std::size_t samples_total = 0;  // samples given
  std::size_t samples_used = 0;   // samples in the move windows, finite outputs
  std::size_t moves_used = 0;     // moves within a phase with a non-zero travel
  int iterations = 0;
  bool converged = false;
  bool at_bound = false;              // the estimate hit +-max_abs_lag_s (then ok = false)
  bool sigma_from_residuals = false;  // no usable sample_sigma: unit weights, scale from residuals
  Eigen::Vector3d sample_sigma = Eigen::Vector3d::Zero();  // per accelerometer, m/s^2
  double time_origin_s = 0.0;  // absolute stamp of t0 used (drift term and schedule)

  // The result as an effect of the vocabulary: timing_lag[all] with value lag_s.
  Effect effect() const;
};

// What estimate_timing_lag needs of a live run, in bounded memory: every gimbal event, and the
// samples near the moves within a phase ([MOVING - margin_s, SETTLED + margin_s]), not the
// dwells' samples in between. Fed in stamp order (DwellAssembler::set_release_observers). Keeps
// at most max_samples samples; later ones are counted in samples_dropped (the estimate then
// uses the moves recorded before).
class MoveSampleRecorder {
 public:
  explicit MoveSampleRecorder(double margin_s = TimingLagEstimateOptions().margin_s,
                              std::size_t max_samples = 1000000);
  void add_command(const GimbalEvent& event);
  void add_sample(const ImuSample& sample);
  void clear();

  const std::vector<GimbalEvent>& commands() const { return commands_; }
  const std::vector<ImuSample>& samples() const { return samples_; }
  std::size_t samples_dropped() const { return dropped_; }

 private:
  double margin_s_;
  std::size_t max_samples_;
  std::vector<GimbalEvent> commands_;
  std::vector<ImuSample> samples_;
  std::deque<ImuSample> recent_;  // the last margin_s of dwell samples, for the next MOVING
  bool in_move_ = false;          // between a within-phase MOVING and its SETTLED
  double keep_until_s_ = -std::numeric_limits<double>::infinity();  // SETTLED + margin
  bool have_phase_ = false;
  Phase last_phase_ = Phase::X;
  std::size_t dropped_ = 0;
  void keep(const ImuSample& sample);
};

// The estimator. `base_fit` supplies the device (S, O and any fitted effect terms; its 12x12
// covariance of S and O enters the uncertainty and the test); `time_origin_s` is t0 of the drift
// term (NaN: the first command); `sample_sigma` the per-sample noise of u, v, w (e.g.
// pooled_sample_std of the table; zeros: estimated from the residuals).
//
// Method: weighted least squares in the single parameter lag, Gauss-Newton with step halving
// (one parameter: a solver library adds nothing), derivative by central differences (see
// derivative_step_s; the trajectory is evaluated by gimbal_pose_at, which is not templated, so
// autodiff is not available). Uncertainty: var(lag) = (J^T W J + u^T C u) / (J^T W J)^2 with
// u = F^T W J, F = d(outputs)/d(S, O) along the samples and C the base fit's covariance: the
// error of S and O leaks into the move residuals; it is then scaled by the reduced chi-square of
// the move samples when that is above 1 (the convention of fit()). Never throws for data
// problems: they come back as ok = false with a message. Throws std::invalid_argument for bad
// options.
//
// A gimbal that moves otherwise than the motion model
// (test/core/analysis/timing_lag_profile_test.cpp, streams made there without gimbal_pose_at): a
// symmetric profile of another shape (trapezoidal velocity) leaves the lag unbiased (9.87 to 10.1
// ms for 10 ms) and raises the reduced chi-square of the move samples (1.21 to 1.23), which
// inflates std_s; a damped oscillation after SETTLED (20 mrad, 4 Hz, 0.1 s) biases the lag late by
// about 3 of its inflated std (0.36 ms at std 0.12 ms for 10 ms, mean of three runs) at reduced
// chi-square 1.14 to 1.17; the 2 mrad ringing of the shipped simulated gimbal changes nothing
// visible. The reduced chi-square is the sign of such a mismatch, but it is no gate: on lag-free
// data with short dwells it reaches 1.07 from the base fit's own error, so a 99.9 % chi-square
// bound would withhold honest estimates.
TimingLagEstimate estimate_timing_lag(const std::vector<GimbalEvent>& commands,
                                      const std::vector<ImuSample>& samples,
                                      const FitResult& base_fit, double time_origin_s,
                                      const Eigen::Vector3d& sample_sigma,
                                      const TimingLagEstimateOptions& options = {});

// Convenience for calibrate() (core/calibrate.h): t0 = effective_time_origin(table), the origin
// fit() used for the drift term (the first command when the table came from the assembler; the
// first command of `commands` for an empty table), sample_sigma = pooled_sample_std(table),
// base_fit = the fit of that table (e.g. fit(table) or AnalysisResult::after_fit).
TimingLagEstimate estimate_timing_lag(const std::vector<GimbalEvent>& commands,
                                      const std::vector<ImuSample>& samples,
                                      const PositionTable& table, const FitResult& base_fit,
                                      const TimingLagEstimateOptions& options = {});

// The options of the timing lag beside the discrepancy analysis of the dwells (core::calibrate
// with analyze, i.e. offline_fit --analyze on a bag and the calibration node's analysis): the lag
// is estimated with the analysis's refit (AnalysisResult::after_fit) at
// alpha = kTimingLagAlphaBesideScreen; io/analysis_report.h writes it under the key "timing_lag"
// ({ok, message, value, std, p_value, detected, lr_chi2, samples_used, detection_threshold}) and
// appends it to "effects" ({name: timing_lag, target: all, value, std, p_value}) when detected.
// False alarms: the dwell screen spends AnalysisOptions::alpha (2.5 %) family-wise and this test
// 1 %, so an effect-free run names anything in at most 3.5 % of runs (the requirement is 5 %; the
// margin keeps a check on 200 runs from failing by chance).
constexpr double kTimingLagAlphaBesideScreen = 0.01;
TimingLagEstimateOptions timing_lag_options_beside_screen();

}  // namespace core
}  // namespace accel_intrinsics
