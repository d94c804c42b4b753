// The serial_lines accelerometer source: reader thread, stamps, reconnects (serial_lines_source.h).
#include "accel_intrinsics/drivers/serial_lines_source.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include "accel_intrinsics/drivers/serial_port.h"

namespace accel_intrinsics {

void SerialLinesOptions::validate() const {
  if (port.empty()) throw std::invalid_argument("port must not be empty");
  if (baud <= 0) throw std::invalid_argument("baud must be > 0");
  if (!(std::isfinite(reconnect_interval_s) && reconnect_interval_s > 0.0)) {
    throw std::invalid_argument("reconnect_interval_s must be > 0 s");
  }
  if (max_pending < 1) throw std::invalid_argument("max_pending must be >= 1");
  if (!(std::isfinite(read_period_s) && read_period_s >= 0.0 && read_period_s <= 0.1)) {
    throw std::invalid_argument("read_period_s must be in [0, 0.1] s");
  }
  clock.validate();
}

const char* link_state_name(SerialLinkState state) {
  switch (state) {
    case SerialLinkState::Connected: return "connected";
    case SerialLinkState::Lost: return "lost";
    default: return "opening";
  }
}

std::uint64_t SerialLinesStatus::garbled_total() const {
  std::uint64_t total = 0;
  for (const std::uint64_t n : garbled) total += n;
  return total;
}

SerialLinesAccelerometer::SerialLinesAccelerometer(const SerialLinesOptions& options,
                                                   HostClock host_clock, SamplesReady on_samples)
    : options_(options),
      clock_(std::move(host_clock)),
      on_samples_(std::move(on_samples)),
      fit_(options.clock) {
  options_.validate();
  status_.since_s = clock_();
  thread_ = std::thread([this] { run(); });
}

SerialLinesAccelerometer::~SerialLinesAccelerometer() {
  stop_ = true;
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void SerialLinesAccelerometer::set_state(SerialLinkState state, const std::string& error,
                                         double host_s) {
  if (state != status_.state) status_.since_s = host_s;
  status_.state = state;
  if (!error.empty()) status_.last_error = error;
}

void SerialLinesAccelerometer::run() {
  SerialPort port;
  std::string line;
  // Wait for input in short slices so that the destructor's stop is seen within 0.1 s.
  constexpr double kSliceS = 0.1;
  // With device time, the lines that came within read_period_s are read and stamped together:
  // one wake-up for several lines. Without it, each line is read as it comes (its stamp).
  const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(options_.format.has_time() ? options_.read_period_s : 0.0));
  auto next_read = std::chrono::steady_clock::now();
  while (!stop_) {
    if (!port.is_open()) {
      try {
        port.open(options_.port, options_.baud);
        std::lock_guard<std::mutex> lock(mutex_);
        ++status_.connects;
        set_state(SerialLinkState::Connected, "", clock_());
        first_line_ = true;
      } catch (const SerialError& e) {
        std::unique_lock<std::mutex> lock(mutex_);
        ++status_.open_failures;
        set_state(status_.connects > 0 ? SerialLinkState::Lost : SerialLinkState::Opening, e.what(),
                  clock_());
        wake_.wait_for(lock, std::chrono::duration<double>(options_.reconnect_interval_s),
                       [this] { return stop_.load(); });
        continue;
      }
    }
    try {
      if (period.count() > 0) {
        std::unique_lock<std::mutex> lock(mutex_);
        if (wake_.wait_until(lock, next_read, [this] { return stop_.load(); })) break;
      }
      if (!port.read_available(kSliceS)) continue;
      const double host_s = clock_();
      next_read = std::chrono::steady_clock::now() + period;
      bool stamped = false;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        const std::uint64_t before = status_.samples;
        while (port.next_line(&line)) handle_line(line, host_s);
        stamped = status_.samples != before;
      }
      if (stamped && on_samples_) on_samples_();
    } catch (const SerialError& e) {
      port.close();
      std::unique_lock<std::mutex> lock(mutex_);
      const std::uint64_t before = status_.samples;
      ++status_.losses;
      status_.loss_error = e.what();
      set_state(SerialLinkState::Lost, e.what(), clock_());
      // The device may come back reset: its clock starts again. What was held for the warm-up
      // is stamped with the fit as it stands (rate 1, the smallest delay seen).
      if (!held_.empty() && fit_.points() > 0) {
        for (Held& h : held_) {
          h.sample.stamp_s = fit_.host_time(h.device_s);
          push(h.sample);
        }
      }
      held_.clear();
      fit_.reset();
      const bool stamped = status_.samples != before;
      lock.unlock();
      if (stamped && on_samples_) on_samples_();
    }
  }
}

void SerialLinesAccelerometer::push(const core::ImuSample& sample) {
  if (ready_.size() >= options_.max_pending) {
    ready_.pop_front();
    ++status_.overflow;
  }
  ready_.push_back(sample);
  ++status_.samples;
}

void SerialLinesAccelerometer::handle_line(const std::string& line, double host_s) {
  ++status_.lines;
  status_.last_line_host_s = host_s;
  ParsedLine parsed;
  LineFault fault = parse_sample_line(line, options_.format, &parsed);
  if (first_line_) {
    // Counted as partial whatever it parses as: "0.011,0.002,9.81" read from its third byte is
    // "11,0.002,9.81", a valid-looking sample with a wrong x.
    first_line_ = false;
    fault = LineFault::Partial;
  }
  core::ImuSample sample;
  sample.outputs << parsed.xyz[0], parsed.xyz[1], parsed.xyz[2];
  if (fault == LineFault::None && options_.format.has_time()) {
    if (fit_.add(parsed.t_s, host_s) == DeviceClockFit::Added::Outlier) fault = LineFault::Clock;
  }
  if (fault != LineFault::None) {
    ++status_.garbled[static_cast<int>(fault)];
    status_.last_garbled = printable(line.substr(0, 80));
    return;
  }
  if (!options_.format.has_time()) {
    sample.stamp_s = host_s;
    push(sample);
    return;
  }
  if (!fit_.ready()) {
    if (held_.size() < options_.max_pending) {
      held_.push_back({parsed.t_s, sample});
    } else {
      ++status_.overflow;
    }
    return;
  }
  stamp_held();
  sample.stamp_s = fit_.host_time(parsed.t_s);
  push(sample);
}

void SerialLinesAccelerometer::stamp_held() {
  for (Held& h : held_) {
    h.sample.stamp_s = fit_.host_time(h.device_s);
    push(h.sample);
  }
  held_.clear();
}

void SerialLinesAccelerometer::poll(double /*now_s*/, std::vector<core::ImuSample>* out) {
  std::lock_guard<std::mutex> lock(mutex_);
  out->insert(out->end(), ready_.begin(), ready_.end());
  ready_.clear();
}

SerialLinesStatus SerialLinesAccelerometer::status() const {
  std::lock_guard<std::mutex> lock(mutex_);
  SerialLinesStatus s = status_;
  s.clock_ready = fit_.ready();
  s.clock_offset_s = fit_.offset_s();
  s.clock_rate = fit_.rate();
  s.clock_points = fit_.points();
  s.clock_restarts = fit_.restarts();
  return s;
}

}  // namespace accel_intrinsics
