#include "accel_intrinsics/core/run/tumble_session.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace accel_intrinsics {
namespace core {
namespace {

// Before the first fit: every axis up and down, then the eight corners.
Eigen::Vector3d starting_pose(std::size_t k) {
  static const double c = 1.0 / std::sqrt(3.0);
  static const Eigen::Vector3d poses[] = {{0, 0, 1},   {0, 0, -1},  {1, 0, 0},  {-1, 0, 0},
                                          {0, 1, 0},   {0, -1, 0},  {c, c, c},  {-c, -c, c},
                                          {c, -c, -c}, {-c, c, -c}, {c, -c, c}, {-c, c, c}};
  return poses[k % (sizeof(poses) / sizeof(poses[0]))];
}

}  // namespace

void validate(const TumbleSessionOptions& o) {
  validate(o.rests);
  if (!(std::isfinite(o.local_gravity) && o.local_gravity > 0.0))
    throw std::invalid_argument("tumble: local_gravity must be > 0");
  if (o.min_rests < 9) throw std::invalid_argument("tumble: min_rests must be >= 9");
  if (!(std::isfinite(o.target_relative_std) && o.target_relative_std >= 0.0))
    throw std::invalid_argument("tumble: target_relative_std must be >= 0 (0: fit when asked)");
}

TumbleSession::TumbleSession(const TumbleSessionOptions& options) : options_(options) {
  validate(options_);
  start();
  update_progress();
}

void TumbleSession::start() {
  assembler_.reset();
  long_rest_.clear();
  assembler_.set_release_observers([this](const GimbalEvent& e) { long_rest_.add_command(e); },
                                   [this](const ImuSample& s) { long_rest_.add_sample(s); });
  source_ = std::make_unique<DetectedDwellSource>(&assembler_, options_.rests);
}

void TumbleSession::reset() {
  start();
  table_ = PositionTable();
  dropped_ = 0;
  last_t_s_ = -std::numeric_limits<double>::infinity();
  update_progress();
}

bool TumbleSession::add_sample(double t_s, const Eigen::Vector3d& outputs) {
  if (!(t_s >= last_t_s_) || !outputs.allFinite()) {
    ++dropped_;
    return false;
  }
  last_t_s_ = t_s;
  ImuSample sample;
  sample.stamp_s = t_s;
  sample.outputs = outputs;
  const CompletedRows rests = source_->add_sample(sample);
  progress_.samples = detector().samples();
  progress_.still_s = detector().current_still_s();
  return take_new_rests(rests);
}

bool TumbleSession::finish() {
  return take_new_rests(source_->finish());
}

bool TumbleSession::take_new_rests(const CompletedRows& rests) {
  if (rests.empty()) return false;
  if (table_.rows.empty()) table_.time_origin_s = rests.front().t_start_s;
  table_.rows.insert(table_.rows.end(), rests.begin(), rests.end());
  update_progress();
  return true;
}

std::optional<NoiseModel> TumbleSession::noise_model() const {
  try {
    return long_rest_.noise_model(table_, 0.0);
  } catch (const std::invalid_argument&) {
    return std::nullopt;  // too short a record for a model: white
  }
}

void TumbleSession::update_progress() {
  TumbleProgress p;
  p.rests = table_.rows.size();
  p.rejected = detector().rejected().size();
  p.samples = detector().samples();
  p.still_s = detector().current_still_s();
  std::ostringstream message;
  if (p.rests >= options_.min_rests) {
    try {
      TumbleFitOptions fit_options;
      fit_options.local_gravity = options_.local_gravity;
      fit_options.min_rests = options_.min_rests;
      const FitResult fit = fit_tumble(table_, fit_options);
      p.fitted = true;
      p.coverage = tumble_coverage(fit, table_);
      p.relative = relative_uncertainties(fit);
      p.largest_relative_std = 0.0;
      for (const RelativeUncertainty& u : p.relative) {
        if (u.value > p.largest_relative_std) {
          p.largest_relative_std = u.value;
          p.largest_name = u.name;
        }
      }
      const PoseSuggestion next = suggest_next_pose(fit, table_);
      p.next_up = next.up;
      p.next_pose_words = next.words;
      p.target_reached = options_.target_relative_std > 0.0 && p.coverage->complete() &&
                         p.largest_relative_std <= options_.target_relative_std;
    } catch (const FitError& e) {
      p.fit_error = e.what();
    }
  }
  if (!p.fitted) {
    p.next_up = starting_pose(p.rests);
    p.next_pose_words = describe_pose(p.next_up);
  }
  message << p.rests << " rests";
  if (p.rests < options_.min_rests) {
    message << " (" << options_.min_rests - p.rests << " more before the first fit)";
  } else if (p.fitted) {
    message << ", largest relative uncertainty " << std::setprecision(2) << p.largest_relative_std
            << " (" << p.largest_name << ")";
    if (!p.coverage->complete()) message << "; " << p.coverage->missing.front();
  } else {
    message << ", no fit yet: " << p.fit_error;
  }
  if (p.target_reached) {
    message << "; target reached, fitting";
  } else {
    message << "; next: hold it with the " << p.next_pose_words << ", still for "
            << std::setprecision(3) << options_.rests.min_rest_s + 2.0 * options_.rests.trim_s
            << " s";
  }
  p.message = message.str();
  progress_ = p;
}

CalibrationReport TumbleSession::report(const CalibrateOptions& options) const {
  CalibrateOptions o = with_noise_model(options, noise_model());
  o.fit.local_gravity = options_.local_gravity;
  o.analyze = false;
  return calibrate(table_, nullptr, o);
}

}  // namespace core
}  // namespace accel_intrinsics
