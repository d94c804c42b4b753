#include "accel_intrinsics/core/analysis/raw_stream_analysis.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/model/gimbal_kinematics.h"
#include "accel_intrinsics/core/model/model.h"

namespace accel_intrinsics {
namespace core {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// P(chi2(1) >= x).
double chi2_1_sf(double x) {
  return x > 0.0 ? std::erfc(std::sqrt(0.5 * x)) : 1.0;
}

// Standard normal upper quantile by bisection on erfc (no dependency, 1e-12 accurate).
double normal_upper_quantile(double p) {
  double lo = -40.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (0.5 * std::erfc(mid / std::sqrt(2.0)) > p)
      lo = mid;
    else
      hi = mid;
  }
  return 0.5 * (lo + hi);
}

// Shift d (in units of the estimate's standard deviation) at which a two-sided test at `alpha`
// (|Z + d| > z_{alpha/2}) rejects with probability `power`.
double detectable_shift(double alpha, double power) {
  const double z = normal_upper_quantile(0.5 * alpha);
  auto rejection = [z](double d) {
    return 0.5 * std::erfc((z - d) / std::sqrt(2.0)) + 0.5 * std::erfc((z + d) / std::sqrt(2.0));
  };
  double lo = 0.0, hi = 50.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (rejection(mid) < power)
      lo = mid;
    else
      hi = mid;
  }
  return 0.5 * (lo + hi);
}

// A stretch of the relative time axis in which the gimbal travels within a phase (plus margins).
struct MoveWindow {
  double begin = 0.0;
  double end = 0.0;
};

}  // namespace

Effect TimingLagEstimate::effect() const {
  return Effect{EffectKind::TimingLag, 0, lag_s};
}

double first_command_stamp(const std::vector<GimbalEvent>& commands) {
  double first = kInf;
  for (const GimbalEvent& e : commands) {
    if (std::isfinite(e.stamp_s)) first = std::min(first, e.stamp_s);
  }
  return std::isfinite(first) ? first : kNaN;
}

std::vector<ScheduledPosition> schedule_from_commands(const std::vector<GimbalEvent>& commands) {
  return schedule_from_commands(commands, first_command_stamp(commands));
}

std::vector<ScheduledPosition> schedule_from_commands(const std::vector<GimbalEvent>& commands,
                                                      double time_origin_s) {
  std::vector<ScheduledPosition> schedule;
  if (commands.empty()) return schedule;
  const double origin =
      std::isfinite(time_origin_s) ? time_origin_s : first_command_stamp(commands);
  if (!std::isfinite(origin)) return schedule;

  std::vector<std::size_t> order(commands.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&commands](std::size_t a, std::size_t b) {
    return commands[a].stamp_s < commands[b].stamp_s;
  });

  ApproachTracker approach;  // the rule of dwell_geometries()

  bool pending = false;      // a MOVING waits for its SETTLED
  ScheduledPosition moving;  // that MOVING
  bool dwelling = false;     // schedule.back() is in its dwell (end not yet known)
  for (std::size_t k : order) {
    const GimbalEvent& e = commands[k];
    if (!std::isfinite(e.stamp_s)) continue;
    const double t = e.stamp_s - origin;
    switch (e.state) {
      case GimbalState::Moving: {
        if (dwelling) schedule.back().dwell_end_s = t;
        dwelling = false;
        pending = true;
        moving = ScheduledPosition();
        moving.phase = e.phase;
        moving.step = e.step;
        moving.steps = e.steps;
        moving.angle_rad = e.angle_rad;
        moving.move_start_s = t;
        break;
      }
      case GimbalState::Settled: {
        if (!pending || e.phase != moving.phase || e.step != moving.step) break;  // out of protocol
        pending = false;
        moving.settled_s = t;
        moving.dwell_end_s = kInf;
        moving.approach = approach.visit(moving.phase, moving.angle_rad);
        schedule.push_back(moving);
        dwelling = true;
        break;
      }
      case GimbalState::Done: {
        if (dwelling) schedule.back().dwell_end_s = t;
        dwelling = false;
        pending = false;
        break;
      }
    }
  }
  return schedule;
}

Eigen::Vector3d pooled_sample_std(const PositionTable& table) {
  Eigen::Vector3d pooled = Eigen::Vector3d::Zero();
  for (int s = 0; s < 3; ++s) {
    std::vector<double> variances;
    for (const DwellRecord& row : table.rows) {
      if (row.n >= 2 && std::isfinite(row.std(s))) variances.push_back(row.std(s) * row.std(s));
    }
    if (variances.empty()) continue;
    std::nth_element(variances.begin(), variances.begin() + variances.size() / 2, variances.end());
    const double median = variances[variances.size() / 2];
    double sum_sq = 0.0, dof = 0.0;
    for (const DwellRecord& row : table.rows) {
      if (row.n < 2 || !std::isfinite(row.std(s))) continue;
      const double d = static_cast<double>(row.n - 1);
      const double var = row.std(s) * row.std(s);
      // s^2 / sigma^2 ~ chi2(d) / d has relative spread sqrt(2 / d): keep dwells within 5 of it.
      if (var > median * (1.0 + 5.0 * std::sqrt(2.0 / d))) continue;
      sum_sq += d * var;
      dof += d;
    }
    if (dof > 0.0) pooled(s) = std::sqrt(sum_sq / dof);
  }
  return pooled;
}

TimingLagEstimate estimate_timing_lag(const std::vector<GimbalEvent>& commands,
                                      const std::vector<ImuSample>& samples,
                                      const PositionTable& table, const FitResult& base_fit,
                                      const TimingLagEstimateOptions& options) {
  const double origin = (table.rows.empty() && !std::isfinite(table.time_origin_s))
                            ? kNaN
                            : effective_time_origin(table);
  return estimate_timing_lag(commands, samples, base_fit, origin, pooled_sample_std(table),
                             options);
}

TimingLagEstimate estimate_timing_lag(const std::vector<GimbalEvent>& commands,
                                      const std::vector<ImuSample>& samples,
                                      const FitResult& base_fit, double time_origin_s,
                                      const Eigen::Vector3d& sample_sigma,
                                      const TimingLagEstimateOptions& options) {
  if (!(options.margin_s >= 0.0) || !std::isfinite(options.margin_s)) {
    throw std::invalid_argument("estimate_timing_lag: margin_s must be finite and non-negative");
  }
  if (!(options.max_abs_lag_s > 0.0) || !std::isfinite(options.max_abs_lag_s)) {
    throw std::invalid_argument("estimate_timing_lag: max_abs_lag_s must be finite and positive");
  }
  if (!(options.derivative_step_s > 0.0) || !(options.derivative_step_s < 0.1)) {
    throw std::invalid_argument("estimate_timing_lag: derivative_step_s must be in (0, 0.1) s");
  }
  if (options.max_iterations < 1) {
    throw std::invalid_argument("estimate_timing_lag: max_iterations must be at least 1");
  }
  if (!(options.alpha > 0.0 && options.alpha < 1.0) ||
      !(options.detection_power > 0.0 && options.detection_power < 1.0)) {
    throw std::invalid_argument("estimate_timing_lag: alpha and detection_power must be in (0, 1)");
  }

  TimingLagEstimate result;
  result.samples_total = samples.size();
  const double origin =
      std::isfinite(time_origin_s) ? time_origin_s : first_command_stamp(commands);
  if (!std::isfinite(origin)) {
    result.message = "timing_lag: no gimbal commands with a finite stamp";
    return result;
  }
  result.time_origin_s = origin;
  const std::vector<ScheduledPosition> schedule = schedule_from_commands(commands, origin);

  // Moves within a phase with a non-zero travel, right after the previous dwell (no aborted move
  // in between), as windows [MOVING - margin, SETTLED + margin] clipped to the two dwells.
  std::vector<MoveWindow> windows;
  for (std::size_t i = 1; i < schedule.size(); ++i) {
    const ScheduledPosition& from = schedule[i - 1];
    const ScheduledPosition& to = schedule[i];
    if (from.phase != to.phase || from.angle_rad == to.angle_rad) continue;
    if (from.dwell_end_s != to.move_start_s || !(to.settled_s > to.move_start_s)) continue;
    MoveWindow w;
    w.begin = std::max(to.move_start_s - options.margin_s, from.settled_s);
    w.end = std::min(to.settled_s + options.margin_s, to.dwell_end_s);
    windows.push_back(w);
  }
  result.moves_used = windows.size();

  // The samples to use, chosen by stamp once (windows are disjoint and in time order).
  std::vector<std::size_t> used;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const ImuSample& sample = samples[k];
    if (!std::isfinite(sample.stamp_s) || !sample.outputs.allFinite()) continue;
    const double t = sample.stamp_s - origin;
    auto it = std::upper_bound(windows.begin(), windows.end(), t,
                               [](double value, const MoveWindow& w) { return value < w.begin; });
    if (it == windows.begin()) continue;
    --it;
    if (t <= it->end) used.push_back(k);
  }
  result.samples_used = used.size();

  Eigen::Vector3d sigma = sample_sigma;
  result.sigma_from_residuals = !(sigma.allFinite() && sigma.minCoeff() > 0.0);
  if (result.sigma_from_residuals) sigma = Eigen::Vector3d::Ones();

  if (used.size() < options.min_move_samples) {
    std::ostringstream msg;
    msg << "timing_lag: only " << used.size() << " of " << samples.size()
        << " samples fall inside the " << windows.size() << " moves within a phase (need at least "
        << options.min_move_samples
        << "); a timing lag shows only in samples taken while the gimbal moves, so record the raw "
           "IMU stream including the moves (were the samples outside dwells dropped?)";
    result.message = msg.str();
    return result;
  }

  // The fitted device: S, O and its effect terms (timing_lag has no output term).
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> S = base_fit.S;
  const Eigen::Vector3d O = base_fit.O;
  std::vector<Effect> terms;
  std::vector<double> values;
  for (const Effect& e : base_fit.effects) {
    if (e.kind == EffectKind::TimingLag) continue;
    terms.push_back(e);
    values.push_back(e.value);
  }
  values.push_back(0.0);  // keeps data() valid; never read beyond terms.size()
  const double g = base_fit.local_gravity;
  const double h = options.derivative_step_s;

  // Outputs of the device at true time t (relative axis); the specific force too when wanted.
  auto model_at = [&](double t, Eigen::Vector3d* force) {
    const DwellGeometry geom = geometry_of(gimbal_pose_at(schedule, t), t);
    if (force != nullptr) *force = specific_force(terms, values.data(), geom, g);
    return predict_outputs<double>(S.data(), O.data(), terms, values.data(), geom, g);
  };

  const Eigen::Vector3d weight = sigma.cwiseProduct(sigma).cwiseInverse();
  const Eigen::Matrix<double, 12, 12>& C = base_fit.covariance;
  const bool use_leak = C.allFinite();

  struct Sums {
    double chi2 = 0.0;  // sum w r^2
    double jr = 0.0;    // sum w J r   (J = d model / d lag)
    double jj = 0.0;    // sum w J^2
    Eigen::Matrix<double, 12, 1> u = Eigen::Matrix<double, 12, 1>::Zero();  // F^T W J
  };
  auto evaluate = [&](double lag, bool derivatives) {
    Sums sums;
    for (std::size_t k : used) {
      const ImuSample& sample = samples[k];
      const double t = sample.stamp_s - origin - lag;
      Eigen::Vector3d f;
      const Eigen::Vector3d m = model_at(t, derivatives ? &f : nullptr);
      const Eigen::Vector3d r = sample.outputs - m;
      sums.chi2 += r.cwiseProduct(r).dot(weight);
      if (!derivatives) continue;
      // d model(t_stamp - lag) / d lag = -(dm/dt), central difference.
      const Eigen::Vector3d J = (model_at(t - h, nullptr) - model_at(t + h, nullptr)) / (2.0 * h);
      const Eigen::Vector3d wJ = weight.cwiseProduct(J);
      sums.jr += wJ.dot(r);
      sums.jj += wJ.dot(J);
      // F = d outputs / d(S row-major, O), linear part: dR_s/dS_sj = f_j, dR_s/dO_s = 1.
      for (int s = 0; s < 3; ++s) {
        for (int j = 0; j < 3; ++j) sums.u(3 * s + j) += f(j) * wJ(s);
        sums.u(9 + s) += wJ(s);
      }
    }
    return sums;
  };
  // u^T C u / jj. With unit weights (sigma from residuals) u and jj carry 1/scale^2 less than
  // with the true weights, so the ratio is divided by scale^2 once that is known.
  auto leak_of = [&](const Sums& s) {
    if (!use_leak || !(s.jj > 0.0)) return 0.0;
    return std::max(0.0, static_cast<double>(s.u.transpose() * C * s.u)) / s.jj;
  };

  const Sums at_zero = evaluate(0.0, true);
  if (!(at_zero.jj > 0.0) || !std::isfinite(at_zero.jj) || !std::isfinite(at_zero.chi2)) {
    result.message =
        "timing_lag: the outputs do not change along the moves (no information on the lag)";
    return result;
  }

  // Gauss-Newton with step halving on chi2(lag), confined to +-max_abs_lag_s.
  double lag = 0.0;
  Sums current = at_zero;
  for (int it = 0; it < options.max_iterations; ++it) {
    result.iterations = it + 1;
    const double step = current.jr / current.jj;
    double trial = std::min(options.max_abs_lag_s, std::max(-options.max_abs_lag_s, lag + step));
    Sums next = evaluate(trial, true);
    int halvings = 0;
    while (!(next.chi2 <= current.chi2) && halvings < 30) {
      trial = lag + 0.5 * (trial - lag);
      next = evaluate(trial, true);
      ++halvings;
    }
    // Tolerances in units of the estimate's (unscaled) standard deviation 1 / sqrt(jj). Near the
    // minimum a step of d changes chi2 by jj d^2: 1e-8 for d = 1e-4, well above the round-off
    // of a sum of ~1e4 terms; below ~1e-5 the comparison of chi2 values is noise.
    if (!(next.chi2 <= current.chi2) || !(next.jj > 0.0)) {  // no descent left: at the minimum
      result.converged = std::abs(step) <= 1e-3 / std::sqrt(current.jj);
      break;
    }
    const double moved = trial - lag;
    lag = trial;
    current = next;
    if (std::abs(moved) <= 1e-4 / std::sqrt(current.jj)) {
      result.converged = true;
      break;
    }
  }
  result.at_bound = std::abs(lag) >= options.max_abs_lag_s;
  result.lag_s = lag;
  result.chi2 = current.chi2;
  const double n_res = 3.0 * static_cast<double>(used.size());
  result.reduced_chi2 = current.chi2 / std::max(1.0, n_res - 1.0);

  // Noise scale: known sigma (pooled dwell stds), or estimated from the residuals.
  const double scale2 = result.sigma_from_residuals
                            ? std::max(result.reduced_chi2, std::numeric_limits<double>::min())
                            : 1.0;
  result.sample_sigma =
      result.sigma_from_residuals ? Eigen::Vector3d::Constant(std::sqrt(scale2)) : sigma;

  // Uncertainty at the estimate: var = (1 + leak) / jj, scaled by the reduced chi-square above 1.
  result.base_fit_leak = leak_of(current) / scale2;
  const double inflation =
      result.sigma_from_residuals ? scale2 : std::max(1.0, result.reduced_chi2);
  result.std_s = std::sqrt((1.0 + result.base_fit_leak) / current.jj * inflation);

  // Tests of lag = 0, calibrated at lag = 0: the score jr0 has variance jj0 (1 + leak0) there.
  const double leak0 = leak_of(at_zero) / scale2;
  result.score_chi2 = at_zero.jr * at_zero.jr / (at_zero.jj * (1.0 + leak0)) / scale2;
  result.lr_chi2 = std::max(0.0, at_zero.chi2 - current.chi2) / (1.0 + leak0) / scale2;
  result.p_value = chi2_1_sf(result.lr_chi2);
  const double std0 = std::sqrt((1.0 + leak0) / at_zero.jj * scale2);
  result.detection_threshold_s = detectable_shift(options.alpha, options.detection_power) * std0;

  // At the bound the estimate is no minimum of chi2: not ok (the lag is larger than the options
  // allow, or the trajectory does not fit the data at all).
  result.ok = std::isfinite(result.lag_s) && std::isfinite(result.std_s) && result.std_s > 0.0 &&
              !result.at_bound;
  result.detected = result.ok && result.p_value <= options.alpha;
  std::ostringstream msg;
  msg.precision(3);
  if (!std::isfinite(result.lag_s) || !std::isfinite(result.std_s) || !(result.std_s > 0.0)) {
    msg << "timing_lag: the estimate is not finite";
  } else {
    msg << "timing_lag: " << result.lag_s * 1e3 << " +- " << result.std_s * 1e3 << " ms from "
        << result.samples_used << " samples in " << result.moves_used << " moves; LR chi2 "
        << result.lr_chi2 << ", p = " << result.p_value
        << (result.detected ? " (detected)" : " (not detected)");
    if (result.at_bound)
      msg << "; at the bound +-" << options.max_abs_lag_s
          << " s (not a minimum: raise max_abs_lag_s?)";
    if (!result.converged) msg << "; not converged";
    if (result.sigma_from_residuals) msg << "; noise scale from the move residuals";
  }
  result.message = msg.str();
  return result;
}

MoveSampleRecorder::MoveSampleRecorder(double margin_s, std::size_t max_samples)
    : margin_s_(margin_s), max_samples_(max_samples) {}

void MoveSampleRecorder::clear() {
  commands_.clear();
  samples_.clear();
  recent_.clear();
  in_move_ = false;
  keep_until_s_ = -std::numeric_limits<double>::infinity();
  have_phase_ = false;
  dropped_ = 0;
}

void MoveSampleRecorder::keep(const ImuSample& sample) {
  if (samples_.size() < max_samples_) {
    samples_.push_back(sample);
  } else {
    ++dropped_;
  }
}

void MoveSampleRecorder::add_command(const GimbalEvent& event) {
  commands_.push_back(event);
  if (event.state == GimbalState::Moving) {
    // Only moves within a phase have a trajectory (a remount has none): as the estimator.
    in_move_ = have_phase_ && event.phase == last_phase_;
    if (in_move_) {
      for (const ImuSample& s : recent_) {
        if (s.stamp_s >= event.stamp_s - margin_s_) keep(s);
      }
    }
    recent_.clear();
  } else if (event.state == GimbalState::Settled) {
    if (in_move_) keep_until_s_ = event.stamp_s + margin_s_;
    in_move_ = false;
    have_phase_ = true;
    last_phase_ = event.phase;
  } else {
    in_move_ = false;
  }
}

void MoveSampleRecorder::add_sample(const ImuSample& sample) {
  if (in_move_ || sample.stamp_s <= keep_until_s_) {
    keep(sample);
    return;
  }
  // At rest: remember the last margin_s in case a move starts next.
  recent_.push_back(sample);
  while (!recent_.empty() && recent_.front().stamp_s < sample.stamp_s - margin_s_) {
    recent_.pop_front();
  }
}

TimingLagEstimateOptions timing_lag_options_beside_screen() {
  TimingLagEstimateOptions options;
  options.alpha = kTimingLagAlphaBesideScreen;
  return options;
}

}  // namespace core
}  // namespace accel_intrinsics
