// The common part of the serial gimbal drivers: axis map, settling, reported orientation.
#include "accel_intrinsics/drivers/serial_gimbal.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <thread>

#include "accel_intrinsics/core/model/constants.h"

namespace accel_intrinsics {

namespace {

constexpr double kDeg = core::kPi / 180.0;

std::string phase_key(int p) {
  return std::string("phases.") + "xyz"[p];
}

}  // namespace

std::vector<std::string> AxisMap::axes() const {
  std::set<std::string> all;
  for (const PhaseAxes& p : phases) {
    all.insert(p.axis);
    for (const auto& h : p.hold) all.insert(h.first);
  }
  return std::vector<std::string>(all.begin(), all.end());
}

std::map<std::string, double> AxisMap::positions_deg(core::Phase phase, double alpha_rad) const {
  const PhaseAxes& p = phases[core::index(phase)];
  std::map<std::string, double> out = p.hold;
  out[p.axis] = p.zero_deg + p.sign * alpha_rad / kDeg;
  return out;
}

double AxisMap::alpha_rad(core::Phase phase, double axis_position_deg) const {
  const PhaseAxes& p = phases[core::index(phase)];
  return (axis_position_deg - p.zero_deg) / p.sign * kDeg;
}

void AxisMap::validate(const std::vector<std::string>& known) const {
  const auto is_known = [&](const std::string& a) {
    return known.empty() || std::find(known.begin(), known.end(), a) != known.end();
  };
  std::string names;
  for (const std::string& k : known) names += (names.empty() ? "" : ", ") + k;
  for (int i = 0; i < 3; ++i) {
    const PhaseAxes& p = phases[i];
    const std::string key = phase_key(i);
    if (p.axis.empty()) throw std::invalid_argument(key + ".axis is missing");
    if (!is_known(p.axis)) {
      throw std::invalid_argument(key + ".axis '" + p.axis + "' is not an axis of the device (" +
                                  names + ")");
    }
    if (p.sign != 1.0 && p.sign != -1.0)
      throw std::invalid_argument(key + ".sign must be +1 or -1");
    if (!std::isfinite(p.zero_deg)) throw std::invalid_argument(key + ".zero_deg must be finite");
    for (const auto& h : p.hold) {
      if (h.first == p.axis) {
        throw std::invalid_argument(key + ".hold names " + h.first +
                                    ", the axis that turns in this phase");
      }
      if (!is_known(h.first)) {
        throw std::invalid_argument(key + ".hold: '" + h.first +
                                    "' is not an axis of the device (" + names + ")");
      }
      if (!std::isfinite(h.second))
        throw std::invalid_argument(key + ".hold." + h.first + " must be finite");
    }
  }
  // Consecutive phases that turn the same axis with the same holds leave the DUT turning about
  // the same of its axes: only a remount by hand changes that.
  for (int i = 1; i < 3; ++i) {
    const PhaseAxes& a = phases[i - 1];
    const PhaseAxes& b = phases[i];
    if (a.axis == b.axis && a.hold == b.hold && !b.manual_remount) {
      throw std::invalid_argument(
          phase_key(i) + " turns the same axis as " + phase_key(i - 1) +
          " with the same holds: set " + phase_key(i) +
          ".manual_remount: true (a one-axis stage, remounted by hand) or map it to another axis");
    }
  }
}

void SerialGimbalOptions::validate() const {
  if (port.empty()) throw std::invalid_argument("port is missing (the device, e.g. /dev/ttyUSB0)");
  if (!(reply_timeout_s > 0.0) || !std::isfinite(reply_timeout_s))
    throw std::invalid_argument("reply_timeout_s must be > 0 s");
  if (!(poll_interval_s >= 0.0) || !std::isfinite(poll_interval_s))
    throw std::invalid_argument("poll_interval_s must be >= 0 s");
  if (!(tolerance_deg > 0.0) || !std::isfinite(tolerance_deg))
    throw std::invalid_argument("tolerance_deg must be > 0 deg");
  if (!(settle_s >= 0.0) || !std::isfinite(settle_s))
    throw std::invalid_argument("settle_s must be >= 0 s");
  if (!(connect_timeout_s >= 0.0) || !std::isfinite(connect_timeout_s))
    throw std::invalid_argument("connect_timeout_s must be >= 0 s");
  if (!(home_timeout_s > 0.0) || !std::isfinite(home_timeout_s))
    throw std::invalid_argument("home_timeout_s must be > 0 s");
}

SerialGimbalDriver::SerialGimbalDriver(const SerialGimbalOptions& options) : options_(options) {
  options_.validate();
}

void SerialGimbalDriver::start_device() {
  // A USB adapter that is still enumerating, an emulator that is still starting: try again.
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    try {
      port_.open(options_.port, options_.baud, options_.xon_xoff);
      break;
    } catch (const SerialError& e) {
      if (std::chrono::steady_clock::now() - start >
          std::chrono::duration<double>(options_.connect_timeout_s)) {
        throw GimbalFault(name() + ": " + e.what());
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  initialize();
  last_status_ = poll_status();
}

void SerialGimbalDriver::write(const std::string& bytes) {
  try {
    port_.write(bytes);
  } catch (const SerialError& e) {
    throw GimbalFault(name() + ": " + e.what());
  }
}

std::string SerialGimbalDriver::expect_line(const std::string& what, double timeout_s) {
  if (timeout_s < 0.0) timeout_s = options_.reply_timeout_s;
  std::string line;
  try {
    if (port_.read_line(&line, timeout_s)) return line;
  } catch (const SerialError& e) {
    throw GimbalFault(name() + ": " + e.what() + " (waiting for the reply to " + what + ")");
  }
  std::ostringstream s;
  s << name() << ": no reply on " << options_.port << " within " << timeout_s << " s to " << what;
  throw GimbalFault(s.str());
}

void SerialGimbalDriver::move_to(const GimbalTarget& target, double t_s) {
  // The stage rests where it was last polled until this command goes out at t_s, in the pose of
  // the phase it is in. Without this sample the orientation between the last poll and t_s would
  // interpolate toward the first position polled in motion (or take the next phase's frame), and
  // the tf filled in up to the MOVING stamp would show the move early (the clock check then saw
  // the IMU "early" on a loaded machine). Mid-move there is no rest to record.
  if (polled_ && !moving_) record_position(t_s);
  target_ = target;
  target_positions_ = options_.axis_map.positions_deg(target.phase, target.angle_rad);
  moving_ = true;
  at_rest_since_s_ = -1.0;
  send_move(target_positions_);
  poll(t_s);
}

bool SerialGimbalDriver::at_target(const DeviceStatus& status) const {
  for (const auto& t : target_positions_) {
    const auto it = status.position.find(t.first);
    if (it == status.position.end()) {
      throw GimbalFault(name() + ": the status does not report axis " + t.first + ": '" +
                        status.text + "'");
    }
    if (std::abs(it->second - t.second) > options_.tolerance_deg) return false;
  }
  return true;
}

void SerialGimbalDriver::poll(double t_s) {
  last_poll_ = std::chrono::steady_clock::now();
  polled_ = true;
  last_status_ = poll_status();
  record_position(t_s);
  if (!moving_) return;
  if (last_status_.at_rest && at_target(last_status_)) {
    if (at_rest_since_s_ < 0.0) at_rest_since_s_ = t_s;
  } else {
    at_rest_since_s_ = -1.0;
  }
}

void SerialGimbalDriver::record_position(double t_s) {
  const PhaseAxes& p = options_.axis_map.phases[core::index(target_.phase)];
  const auto it = last_status_.position.find(p.axis);
  if (it == last_status_.position.end()) return;
  if (!history_.empty() && t_s < history_.back().t_s) history_.clear();  // clock jumped back
  history_.push_back(
      Sample{t_s, target_.phase, options_.axis_map.alpha_rad(target_.phase, it->second)});
  while (history_.size() > 2000) history_.pop_front();
}

void SerialGimbalDriver::update(double t_s) {
  const auto now = std::chrono::steady_clock::now();
  if (!polled_ || now - last_poll_ >= std::chrono::duration<double>(options_.poll_interval_s)) {
    poll(t_s);
  }
  if (moving_ && at_rest_since_s_ >= 0.0 && t_s - at_rest_since_s_ >= options_.settle_s) {
    moving_ = false;
    settled_s_ = at_rest_since_s_ + options_.settle_s;
  }
}

void SerialGimbalDriver::recover(double t_s) {
  port_.close();
  moving_ = false;
  at_rest_since_s_ = -1.0;
  settled_s_ = t_s;
  history_.clear();
  polled_ = false;
  start_device();  // reopen, reset, home or unlock as at start
}

bool SerialGimbalDriver::settled(double) const {
  return !moving_;
}

double SerialGimbalDriver::settled_at(double t_s) const {
  return moving_ ? t_s : std::min(t_s, settled_s_);
}

void SerialGimbalDriver::stop(double t_s) {
  try {
    send_stop();
  } catch (const std::exception&) {
    // Best effort: a device that faulted may not answer any more.
  }
  moving_ = false;
  settled_s_ = t_s;
}

bool SerialGimbalDriver::manual_remount(core::Phase phase) const {
  return options_.axis_map.phases[core::index(phase)].manual_remount;
}

GimbalTransforms SerialGimbalDriver::orientation(double t_s) const {
  if (history_.empty()) return gimbal_transforms(target_.phase, target_.angle_rad, 0.0);
  const Sample* at = &history_.front();
  double alpha = at->alpha_rad;
  if (t_s >= history_.back().t_s) {
    at = &history_.back();
    alpha = at->alpha_rad;
  } else if (t_s > history_.front().t_s) {
    const auto after = std::lower_bound(history_.begin(), history_.end(), t_s,
                                        [](const Sample& s, double t) { return s.t_s < t; });
    const auto before = after - 1;
    at = &*before;
    alpha = before->alpha_rad;
    // Between two polls of one phase the angle is interpolated; across a phase change (the
    // frame changes with the move command) it is not.
    const double span = after->t_s - before->t_s;
    if (after->phase == before->phase && span > 0.0) {
      alpha += (t_s - before->t_s) / span * (after->alpha_rad - before->alpha_rad);
    }
  }
  return gimbal_transforms(at->phase, alpha, 0.0);
}

}  // namespace accel_intrinsics
