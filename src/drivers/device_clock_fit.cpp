// Device-to-host clock fit on the lower envelope of the delays (device_clock_fit.h).
#include "accel_intrinsics/drivers/device_clock_fit.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace accel_intrinsics {

void DeviceClockFitOptions::validate() const {
  auto positive = [](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0.0))
      throw std::invalid_argument(std::string(name) + " must be > 0");
  };
  positive(bin_s, "bin_s");
  positive(window_s, "window_s");
  positive(rate_span_s, "rate_span_s");
  positive(max_early_s, "max_early_s");
  positive(max_late_s, "max_late_s");
  if (!(std::isfinite(warmup_s) && warmup_s >= 0.0))
    throw std::invalid_argument("warmup_s must be >= 0");
  if (window_s < 2.0 * bin_s) throw std::invalid_argument("window_s must be >= 2 bin_s");
  if (outliers_to_restart < 1) throw std::invalid_argument("outliers_to_restart must be >= 1");
}

DeviceClockFit::DeviceClockFit(const DeviceClockFitOptions& options) : options_(options) {
  options_.validate();
}

void DeviceClockFit::reset() {
  points_.clear();
  have_bin_ = false;
  any_ = false;
  outliers_in_row_ = 0;
  offset_s_ = 0.0;
  rate_ = 1.0;
}

DeviceClockFit::Added DeviceClockFit::add(double device_s, double host_s) {
  const double delay = host_s - device_s;
  if (any_) {
    const bool backwards = !(device_s > last_device_s_);
    // Received before it was sent by more than max_early_s, or later than max_late_s: the
    // device's clock jumped (a reset, a wrapped counter). A late line within max_late_s is a
    // host that was busy, which the envelope ignores.
    const double residual = host_s - host_time(device_s);
    const bool off = residual < -options_.max_early_s || residual > options_.max_late_s;
    if (backwards || off) {
      if (++outliers_in_row_ < options_.outliers_to_restart) return Added::Outlier;
      reset();
      ++restarts_;
      add(device_s, host_s);
      return Added::Restarted;
    }
  }
  outliers_in_row_ = 0;
  if (!any_) {
    any_ = true;
    first_device_s_ = device_s;
    bin_start_s_ = device_s;
  }
  last_device_s_ = device_s;
  bool changed = false;
  if (have_bin_ && device_s >= bin_start_s_ + options_.bin_s) {
    points_.push_back(bin_);
    have_bin_ = false;
    while (!points_.empty() && points_.front().device_s < device_s - options_.window_s) {
      points_.pop_front();
    }
    bin_start_s_ = device_s;  // bins follow the samples: a gap in the data leaves no empty bins
    changed = true;
  }
  if (!have_bin_ || delay < bin_.delay_s) {
    bin_ = {device_s, delay};
    have_bin_ = true;
    changed = true;
  }
  if (changed) refit();
  return Added::Used;
}

void DeviceClockFit::refit() {
  // The rate from the closed bins alone once they span rate_span_s: the open bin's minimum over
  // its first few samples may still sit high and would tilt the line at its newest end, where
  // it is used. Before that, the rate is 1 and the offset the smallest delay of every bin.
  const bool fit_rate = points_.size() >= 3 &&
                        points_.back().device_s - points_.front().device_s >= options_.rate_span_s;
  const std::size_t n = fit_rate ? points_.size() : points_.size() + (have_bin_ ? 1 : 0);
  if (n == 0) return;
  auto at = [&](std::size_t i) { return i < points_.size() ? points_[i] : bin_; };
  if (!fit_rate) {
    double lowest = at(0).delay_s;
    for (std::size_t i = 1; i < n; ++i) lowest = std::min(lowest, at(i).delay_s);
    rate_ = 1.0;
    offset_s_ = lowest;
    return;
  }
  // Least squares of delay = a + b * (device - mean device): host = device + a + b (device - m).
  double mean_t = 0.0, mean_d = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    mean_t += at(i).device_s;
    mean_d += at(i).delay_s;
  }
  mean_t /= static_cast<double>(n);
  mean_d /= static_cast<double>(n);
  double stt = 0.0, std_ = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double dt = at(i).device_s - mean_t;
    stt += dt * dt;
    std_ += dt * (at(i).delay_s - mean_d);
  }
  const double b = stt > 0.0 ? std_ / stt : 0.0;
  rate_ = 1.0 + b;
  offset_s_ = mean_d - b * mean_t;
}

bool DeviceClockFit::ready() const {
  return any_ && last_device_s_ - first_device_s_ >= options_.warmup_s;
}

double DeviceClockFit::host_time(double device_s) const {
  return offset_s_ + rate_ * device_s;
}

}  // namespace accel_intrinsics
