// The serial_lines accelerometer source (docs/design.md section 15, "Bare MEMS parts"): its
// line format, its device-clock fit, and the source on a real pseudo-terminal written from a
// thread as a microcontroller would (rates to 1 kHz, a device clock 100 ppm fast, reception
// jitter with stalls, garbled and cut lines, the port unplugged and back). The truth is the
// test's own: each line's host time is set here before it is written.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <random>
#include <thread>

#include "../support/precise_sleep.h"
#include "accel_intrinsics/drivers/device_clock_fit.h"
#include "accel_intrinsics/drivers/serial_line_format.h"
#include "accel_intrinsics/drivers/serial_lines_source.h"

namespace ai = accel_intrinsics;

namespace {

double monotonic_s() {
  timespec now{};
  ::clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

// The test's host clock: CLOCK_MONOTONIC from its first use.
double start_s() {
  static const double start = monotonic_s();
  return start;
}

double wall_s() {
  const double start = start_s();
  return monotonic_s() - start;
}

// Sleeps to the absolute host time t_s on wall_s()'s clock.
void sleep_until_wall(double t_s) {
  ai::precise_sleep::sleep_until(CLOCK_MONOTONIC, start_s() + t_s);
}

ai::SerialLineFormat format(const std::string& columns, const std::string& separator = ",") {
  ai::SerialLineFormat f;
  f.roles = ai::SerialLineFormat::parse_columns(columns);
  f.separator = ai::SerialLineFormat::parse_separator(separator);
  return f;
}

ai::LineFault parse(const std::string& line, const ai::SerialLineFormat& f,
                    ai::ParsedLine* out = nullptr) {
  ai::ParsedLine ignored;
  return ai::parse_sample_line(line, f, out ? out : &ignored);
}

// A microcontroller on a pseudo-terminal reached through a symlink (a stable name, like
// /dev/serial/by-id/...), which can be unplugged (the pty closed, the link removed) and plugged
// back (a new pty behind the same link).
class Device {
 public:
  Device() {
    dir_ = std::filesystem::temp_directory_path() /
           ("serial_lines_test_" + std::to_string(::getpid()) + "_" + std::to_string(count_++));
    std::filesystem::create_directories(dir_);
    link_ = (dir_ / "ttyMEMS").string();
    plug();
  }
  ~Device() {
    unplug();
    std::error_code ignored;
    std::filesystem::remove_all(dir_, ignored);
  }
  const std::string& port() const { return link_; }

  void plug() {
    std::lock_guard<std::mutex> lock(mutex_);
    char name[256] = {0};
    if (openpty(&master_, &slave_, name, nullptr, nullptr) != 0)
      throw std::runtime_error("openpty");
    termios tio{};
    tcgetattr(slave_, &tio);
    cfmakeraw(&tio);
    tcsetattr(slave_, TCSANOW, &tio);
    ::unlink(link_.c_str());
    if (::symlink(name, link_.c_str()) != 0) throw std::runtime_error("symlink");
  }
  void unplug() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (master_ >= 0) ::close(master_);
    if (slave_ >= 0) ::close(slave_);
    master_ = slave_ = -1;
    ::unlink(link_.c_str());
  }
  // Writes all bytes (blocking); false when unplugged.
  bool write(const std::string& bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (master_ < 0) return false;
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(master_, bytes.data() + done, bytes.size() - done);
      if (n <= 0) return false;
      done += static_cast<std::size_t>(n);
    }
    return true;
  }

 private:
  static inline int count_ = 0;
  std::filesystem::path dir_;
  std::string link_;
  std::mutex mutex_;
  int master_ = -1, slave_ = -1;
};

// The microcontroller's program: sample k at device time t0 + k / rate_hz on a clock running
// drift_ppm fast, i.e. at host time host0 + (k / rate_hz) / (1 + drift). Each line leaves after
// a one-sided jitter (exponential, mean jitter_mean_s, and a stall of 3-8 ms on one line in 50).
struct DeviceProgram {
  double rate_hz = 1000.0;
  double drift_ppm = 100.0;
  double device_t0_s = 1234.5;  // the device's uptime at the first sample
  double jitter_mean_s = 0.0002;
  bool print_time = true;
  std::string separator = ",";
  std::uint64_t seed = 7;
};

struct Written {
  double truth_host_s;  // when the device took the sample (host clock)
  double sent_host_s;   // just before the line was written
  // How late the writer woke: sent_host_s less the later of the planned time (truth + jitter)
  // and the time it went to sleep (a line behind a stall is sent at once, not late by waking).
  double late_s;
  double x, y, z;
};

// Writes lines for samples [k_begin, k_end) with host0 the host time of sample 0. x = k (the
// sample's id), y and z known values. Returns what was written, by k.
std::map<long, Written> write_samples(Device& dev, const DeviceProgram& p, double host0,
                                      long k_begin, long k_end, std::mt19937_64* rng,
                                      const std::function<std::string(long)>& garbage = {}) {
  const ai::precise_sleep::PreciseWakeUps precise;
  std::map<long, Written> out;
  std::exponential_distribution<double> jitter(1.0 / p.jitter_mean_s);
  std::uniform_real_distribution<double> stall(0.003, 0.008);
  std::uniform_int_distribution<int> one_in(0, 49);
  const double drift = p.drift_ppm * 1e-6;
  for (long k = k_begin; k < k_end; ++k) {
    const double device_s = k / p.rate_hz;
    const double truth = host0 + device_s / (1.0 + drift);
    double delay = jitter(*rng);
    if (one_in(*rng) == 0) delay += stall(*rng);
    const double before_sleep = wall_s();
    sleep_until_wall(truth + delay);
    const std::string extra = garbage ? garbage(k) : "";
    const double sent = wall_s();
    Written w{truth,
              sent,
              sent - std::max(truth + delay, before_sleep),
              static_cast<double>(k),
              -0.25 + 1e-3 * (k % 97),
              9.80665 + 1e-6 * (k % 13)};
    char line[160];
    if (p.print_time) {
      std::snprintf(line, sizeof line, "%.6f%s%.0f%s%.6f%s%.6f\r\n", p.device_t0_s + device_s,
                    p.separator.c_str(), w.x, p.separator.c_str(), w.y, p.separator.c_str(), w.z);
    } else {
      std::snprintf(line, sizeof line, "%.0f%s%.6f%s%.6f\n", w.x, p.separator.c_str(), w.y,
                    p.separator.c_str(), w.z);
    }
    if (!dev.write(extra + line)) continue;
    // A line preceded by garbage with no newline of its own is one line: not a sample.
    if (extra.empty() || extra.back() == '\n') out[k] = w;
  }
  return out;
}

// The value a "%.6f" line carries.
double printed(double v) {
  char text[64];
  std::snprintf(text, sizeof text, "%.6f", v);
  return std::strtod(text, nullptr);
}

bool wait_for(const std::function<bool()>& done, double limit_s) {
  const double end = wall_s() + limit_s;
  while (wall_s() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return done();
}

ai::SerialLinesOptions source_options(const std::string& port, const std::string& columns,
                                      const std::string& separator = ",") {
  ai::SerialLinesOptions o;
  o.port = port;
  o.format = format(columns, separator);
  o.reconnect_interval_s = 0.05;
  return o;
}

std::vector<ai::core::ImuSample> drain(ai::SerialLinesAccelerometer& source, double quiet_s = 0.3) {
  std::vector<ai::core::ImuSample> all;
  double last = wall_s();
  while (wall_s() - last < quiet_s) {
    const std::size_t before = all.size();
    source.poll(wall_s(), &all);
    if (all.size() > before) last = wall_s();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return all;
}

}  // namespace

TEST(SerialLineFormat, ColumnsAndSeparators) {
  EXPECT_EQ(format("t, x ,y,z").columns_text(), "t,x,y,z");
  EXPECT_EQ(format("x,_,y,z").columns_text(), "x,_,y,z");
  EXPECT_TRUE(format("t,x,y,z").has_time());
  EXPECT_FALSE(format("x,y,z").has_time());
  EXPECT_THROW(format("x,y"), std::invalid_argument);
  EXPECT_THROW(format("x,y,z,x"), std::invalid_argument);
  EXPECT_THROW(format("t,t,x,y,z"), std::invalid_argument);
  EXPECT_THROW(format("x,y,w"), std::invalid_argument);
  EXPECT_EQ(ai::SerialLineFormat::parse_separator("whitespace"), ' ');
  EXPECT_EQ(ai::SerialLineFormat::parse_separator("\t"), '\t');
  EXPECT_EQ(ai::SerialLineFormat::parse_separator(";"), ';');
  EXPECT_THROW(ai::SerialLineFormat::parse_separator("."), std::invalid_argument);
  EXPECT_THROW(ai::SerialLineFormat::parse_separator(",,"), std::invalid_argument);
}

TEST(SerialLineFormat, ParsesSamplesAndNamesEachFault) {
  ai::ParsedLine p;
  ASSERT_EQ(parse("12.5,-0.25,1e-3,+9.81", format("t,x,y,z"), &p), ai::LineFault::None);
  EXPECT_EQ(p.t_s, 12.5);
  EXPECT_EQ(p.xyz[0], -0.25);
  EXPECT_EQ(p.xyz[1], 1e-3);
  EXPECT_EQ(p.xyz[2], 9.81);
  // Blanks around columns; counts (integers) as printed; a skipped column.
  ASSERT_EQ(parse(" 100, -2048 , 16384 ", format("x,y,z"), &p), ai::LineFault::None);
  EXPECT_EQ(p.xyz[1], -2048.0);
  ASSERT_EQ(parse("7;1;2;3", format("_,z,y,x", ";"), &p), ai::LineFault::None);
  EXPECT_EQ(p.xyz[0], 3.0);
  EXPECT_EQ(p.xyz[2], 1.0);
  // Whitespace: any run of blanks and tabs.
  ASSERT_EQ(parse("\t0.5   1.5\t 2.5  ", format("x,y,z", " "), &p), ai::LineFault::None);
  EXPECT_EQ(p.xyz[2], 2.5);
  const ai::SerialLineFormat f = format("t,x,y,z");
  EXPECT_EQ(parse("1,2,3", f), ai::LineFault::Columns);
  EXPECT_EQ(parse("1,2,3,4,5", f), ai::LineFault::Columns);
  EXPECT_EQ(parse("1,2,3,4,", f), ai::LineFault::Columns);
  EXPECT_EQ(parse("", f), ai::LineFault::Columns);
  EXPECT_EQ(parse("1,2,,4", f), ai::LineFault::Number);
  EXPECT_EQ(parse("1,2,abc,4", f), ai::LineFault::Number);
  EXPECT_EQ(parse("1,2,3.0.1,4", f), ai::LineFault::Number);
  EXPECT_EQ(parse("1,nan,3,4", f), ai::LineFault::Number);
  EXPECT_EQ(parse("1,inf,3,4", f), ai::LineFault::Number);
  EXPECT_EQ(parse("1,2,3,4 5", f), ai::LineFault::Number);
  EXPECT_EQ(parse(std::string("1,2,\x01", 5) + "3,4", f), ai::LineFault::Binary);
  EXPECT_EQ(parse("1,2,\xc3\xa9,4", f), ai::LineFault::Binary);
  EXPECT_EQ(parse(std::string(300, '1'), f), ai::LineFault::TooLong);
}

TEST(DeviceClockFit, LowerEnvelopeTracksDriftUnderJitterAndStalls) {
  // 30 s at 1 kHz of a device clock 100 ppm fast; delays of 120 us transport plus exponential
  // jitter (mean 0.5 ms) and, one line in 50, a stall of up to 20 ms.
  std::mt19937_64 rng(3);
  std::exponential_distribution<double> jitter(1.0 / 0.0005);
  std::uniform_real_distribution<double> stall(0.0, 0.02);
  std::uniform_int_distribution<int> one_in(0, 49);
  ai::DeviceClockFit fit;
  const double drift = 100e-6, host0 = 5000.0, device0 = 77.0, latency = 120e-6;
  double worst_after_warmup = 0.0;
  for (int k = 0; k < 30000; ++k) {
    const double host_truth = host0 + k * 1e-3;
    const double device = device0 + (host_truth - host0) * (1.0 + drift);
    double delay = latency + jitter(rng) + (one_in(rng) == 0 ? stall(rng) : 0.0);
    ASSERT_EQ(fit.add(device, host_truth + delay), ai::DeviceClockFit::Added::Used) << k;
    if (fit.ready()) {
      worst_after_warmup =
          std::max(worst_after_warmup, std::abs(fit.host_time(device) - (host_truth + latency)));
    }
  }
  EXPECT_TRUE(fit.ready());
  // The mapping sits on the transport latency, not on the mean jitter (0.5 ms).
  EXPECT_LT(worst_after_warmup, 60e-6);
  EXPECT_NEAR((fit.rate() - 1.0) * 1e6, -100.0 / (1.0 + drift), 2.0);
}

TEST(DeviceClockFit, ARebootedDeviceRestartsTheFitAndASingleBadTimeIsDropped) {
  ai::DeviceClockFit fit;
  double host = 100.0;
  for (int k = 0; k < 2000; ++k, host += 1e-3) fit.add(50.0 + k * 1e-3, host);
  ASSERT_TRUE(fit.ready());
  // One line whose t is far ahead (a digit lost), then normal lines: one outlier, no restart.
  EXPECT_EQ(fit.add(59.0, host), ai::DeviceClockFit::Added::Outlier);
  host += 1e-3;
  EXPECT_EQ(fit.add(52.0, host), ai::DeviceClockFit::Added::Used);
  host += 1e-3;
  EXPECT_EQ(fit.restarts(), 0u);
  // The device reboots: t starts again near 0. Four outliers, then the fit starts over.
  for (int k = 0; k < 4; ++k, host += 1e-3) {
    EXPECT_EQ(fit.add(0.01 + k * 1e-3, host), ai::DeviceClockFit::Added::Outlier) << k;
  }
  EXPECT_EQ(fit.add(0.014, host), ai::DeviceClockFit::Added::Restarted);
  EXPECT_EQ(fit.restarts(), 1u);
  EXPECT_FALSE(fit.ready());
  for (int k = 1; k < 1000; ++k) fit.add(0.014 + k * 1e-3, host + k * 1e-3);
  ASSERT_TRUE(fit.ready());
  EXPECT_NEAR(fit.host_time(0.5), host + 0.486, 1e-9);
}

// The ISSUE's scenario: 1 kHz, a device clock 100 ppm fast, reception jitter with stalls; every
// published stamp within 1 ms of the host time the sample was taken, the values unchanged.
TEST(SerialLinesSource, StampsFromDeviceTimeWithin1msAt1kHz) {
  Device dev;
  ai::SerialLinesAccelerometer source(source_options(dev.port(), "t,x,y,z"), wall_s);
  ASSERT_TRUE(wait_for([&] { return source.status().connects == 1; }, 5.0));
  DeviceProgram p;
  std::mt19937_64 rng(p.seed);
  const double host0 = wall_s() + 0.05;
  // 12 s of lines: the clock rate is the slope through the minima of 0.25 s bins, ~47 of them.
  // Over 5 s (~19 minima) it spread by ~12 ppm (-81 to -112 ppm in four runs): the minima
  // scatter by ~50-70 us, by a model of this writer and reader mostly the device's own jitter
  // seen through 5 ms batched reads, little the writer's wake-ups; the slope's spread goes as
  // the span to the power -1.5.
  std::map<long, Written> written = write_samples(dev, p, host0, 0, 12000, &rng);
  const std::vector<ai::core::ImuSample> got = drain(source);
  const ai::SerialLinesStatus st = source.status();
  // Every line but the first (partial by rule) is published, once, unchanged, within 1 ms.
  EXPECT_EQ(got.size(), written.size() - 1);
  EXPECT_EQ(st.garbled_total(), 1u);
  EXPECT_EQ(st.garbled[static_cast<int>(ai::LineFault::Partial)], 1u);
  double worst = 0.0;
  std::map<long, int> seen;
  for (const ai::core::ImuSample& s : got) {
    const long k = std::lround(s.outputs.x());
    ASSERT_TRUE(written.count(k)) << k;
    ++seen[k];
    const Written& w = written.at(k);
    // Unchanged: exactly the number the device printed.
    EXPECT_EQ(s.outputs.y(), printed(w.y)) << k;
    EXPECT_EQ(s.outputs.z(), printed(w.z)) << k;
    worst = std::max(worst, std::abs(s.stamp_s - w.truth_host_s));
  }
  EXPECT_EQ(seen.size(), got.size()) << "a sample published twice";
  EXPECT_LT(worst, 1e-3) << "worst stamp error " << worst * 1e3 << " ms";
  EXPECT_TRUE(st.clock_ready);
  EXPECT_NEAR((st.clock_rate - 1.0) * 1e6, -100.0, 30.0);
  char rate_text[32];
  std::snprintf(rate_text, sizeof rate_text, "%.1f", (st.clock_rate - 1.0) * 1e6);
  RecordProperty("clock_rate_ppm", rate_text);  // in the test's XML result: the margin in CI
  std::vector<double> late;
  for (const auto& [k, w] : written) late.push_back(w.late_s);
  std::sort(late.begin(), late.end());
  std::printf(
      "worst stamp error at 1 kHz: %.0f us over %zu samples; drift seen %.1f ppm (-100 +- 30); "
      "writer late by %.0f us (median), %.0f us (99th percentile)\n",
      worst * 1e6, got.size(), (st.clock_rate - 1.0) * 1e6, late[late.size() / 2] * 1e6,
      late[late.size() * 99 / 100] * 1e6);
}

// Without t: the host clock at reception, never before the line was sent; blanks separate.
TEST(SerialLinesSource, StampsAtReceptionWithoutDeviceTime) {
  Device dev;
  ai::SerialLinesOptions o = source_options(dev.port(), "x,y,z", "whitespace");
  o.read_period_s = 0.05;  // applies with a t column only: here each line is read as it comes
  ai::SerialLinesAccelerometer source(o, wall_s);
  ASSERT_TRUE(wait_for([&] { return source.status().connects == 1; }, 5.0));
  DeviceProgram p;
  p.print_time = false;
  p.rate_hz = 200.0;
  p.separator = "  ";
  std::mt19937_64 rng(11);
  const std::map<long, Written> written = write_samples(dev, p, wall_s() + 0.02, 0, 400, &rng);
  const std::vector<ai::core::ImuSample> got = drain(source);
  ASSERT_EQ(got.size(), written.size() - 1);
  std::vector<double> delays;
  for (const ai::core::ImuSample& s : got) {
    const Written& w = written.at(std::lround(s.outputs.x()));
    EXPECT_GE(s.stamp_s, w.sent_host_s);
    delays.push_back(s.stamp_s - w.sent_host_s);
  }
  std::nth_element(delays.begin(), delays.begin() + delays.size() / 2, delays.end());
  EXPECT_LT(delays[delays.size() / 2], 0.005);
}

// Garbled lines of every kind between good ones: counted by kind, never published.
TEST(SerialLinesSource, GarbledAndCutLinesAreCountedNeverPublished) {
  Device dev;
  ai::SerialLinesAccelerometer source(source_options(dev.port(), "t,x,y,z"), wall_s);
  ASSERT_TRUE(wait_for([&] { return source.status().connects == 1; }, 5.0));
  DeviceProgram p;
  p.rate_hz = 500.0;
  std::mt19937_64 rng(5);
  // Before every 40th sample, one kind of garbage, in turn.
  const std::vector<std::string> junk = {
      std::string("\x02\x7f\xc3\xff junk\x00\x01", 11) + "\n",  // binary
      "1.5,2.5\n",                                              // columns: too few
      "1.0,2.0,3.0,4.0,5.0\n",                                  // columns: too many
      "1300.0,abc,1,2\n",                                       // number
      "1300.0,nan,1,2\n",                                       // number
      std::string(300, '7') + "\n",                             // too long
      "1234.9,1",  // a line cut in half: it runs into the next one (columns, both lost)
  };
  std::map<ai::LineFault, int> expected;
  const ai::LineFault kinds[] = {
      ai::LineFault::Binary, ai::LineFault::Columns, ai::LineFault::Columns, ai::LineFault::Number,
      ai::LineFault::Number, ai::LineFault::TooLong, ai::LineFault::Columns};
  int n_junk = 0;
  auto garbage = [&](long k) -> std::string {
    if (k == 0 || k % 40 != 0) return "";
    const std::size_t i = static_cast<std::size_t>(n_junk++) % junk.size();
    ++expected[kinds[i]];
    return junk[i];
  };
  const std::map<long, Written> written =
      write_samples(dev, p, wall_s() + 0.02, 0, 1400, &rng, garbage);
  const std::vector<ai::core::ImuSample> got = drain(source);
  const ai::SerialLinesStatus st = source.status();
  ASSERT_GE(n_junk, 30);
  EXPECT_EQ(got.size(), written.size() - 1);  // the first line: partial
  for (const ai::core::ImuSample& s : got) {
    ASSERT_TRUE(written.count(std::lround(s.outputs.x()))) << "published: " << s.outputs.x();
    EXPECT_NEAR(s.outputs.y(), written.at(std::lround(s.outputs.x())).y, 5e-7);
  }
  for (const auto& [kind, count] : expected) {
    EXPECT_EQ(st.garbled[static_cast<int>(kind)], static_cast<std::uint64_t>(count))
        << ai::line_fault_name(kind);
  }
  EXPECT_EQ(st.garbled[static_cast<int>(ai::LineFault::Partial)], 1u);
  EXPECT_EQ(st.garbled_total(), static_cast<std::uint64_t>(n_junk) + 1);
  EXPECT_EQ(st.lines, got.size() + st.garbled_total());
  EXPECT_FALSE(st.last_garbled.empty());
}

// The port unplugged mid-stream and plugged back: the reader says so, retries, resumes, and the
// stamps after the return are again within 1 ms (the clock fit restarts on reconnection).
TEST(SerialLinesSource, RecoversWhenThePortIsLostAndBack) {
  Device dev;
  ai::SerialLinesAccelerometer source(source_options(dev.port(), "t,x,y,z"), wall_s);
  ASSERT_TRUE(wait_for([&] { return source.status().connects == 1; }, 5.0));
  DeviceProgram p;
  std::mt19937_64 rng(9);
  const double host0 = wall_s() + 0.02;
  std::map<long, Written> written = write_samples(dev, p, host0, 0, 1500, &rng);
  std::vector<ai::core::ImuSample> got = drain(source, 0.2);
  dev.unplug();
  ASSERT_TRUE(wait_for([&] { return source.status().state == ai::SerialLinkState::Lost; }, 5.0));
  ai::SerialLinesStatus st = source.status();
  EXPECT_EQ(st.losses, 1u);
  EXPECT_NE(st.loss_error.find("lost"), std::string::npos) << st.loss_error;
  // Still away: attempts fail with the system's words, the state stays lost.
  ASSERT_TRUE(wait_for([&] { return source.status().open_failures >= 2; }, 5.0));
  st = source.status();
  EXPECT_EQ(st.state, ai::SerialLinkState::Lost);
  EXPECT_NE(st.last_error.find("cannot open"), std::string::npos) << st.last_error;
  dev.plug();
  ASSERT_TRUE(wait_for([&] { return source.status().connects == 2; }, 5.0));
  EXPECT_EQ(source.status().state, ai::SerialLinkState::Connected);
  // The device kept running on the same clock: its samples from now on.
  const long k_back = std::lround(std::ceil((wall_s() - host0 + 0.05) * p.rate_hz));
  const std::map<long, Written> after = write_samples(dev, p, host0, k_back, k_back + 1500, &rng);
  const std::vector<ai::core::ImuSample> more = drain(source);
  got.insert(got.end(), more.begin(), more.end());
  written.insert(after.begin(), after.end());
  std::size_t n_after = 0;
  double worst = 0.0;
  for (const ai::core::ImuSample& s : got) {
    const long k = std::lround(s.outputs.x());
    ASSERT_TRUE(written.count(k)) << k;
    n_after += k >= k_back;
    worst = std::max(worst, std::abs(s.stamp_s - written.at(k).truth_host_s));
  }
  EXPECT_EQ(n_after, after.size() - 1);  // the first line after reopening: partial
  EXPECT_GE(got.size(), 1400u + n_after);
  EXPECT_LT(worst, 1e-3) << "worst stamp error " << worst * 1e3 << " ms";
  std::printf("worst stamp error across the unplug: %.0f us\n", worst * 1e6);
  EXPECT_EQ(source.status().garbled[static_cast<int>(ai::LineFault::Partial)], 2u);
}

// With device time the port is read in batches (one wake-up for the lines of read_period_s), and
// the samples-ready callback hands every sample over from the reader thread, once, in order.
TEST(SerialLinesSource, ReadsInBatchesWithDeviceTimeAndHandsEverySampleOver) {
  ai::SerialLinesOptions bad = source_options("/dev/null", "t,x,y,z");
  bad.read_period_s = 0.2;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
  Device dev;
  ai::SerialLinesOptions o = source_options(dev.port(), "t,x,y,z");
  o.read_period_s = 0.01;
  std::atomic<ai::SerialLinesAccelerometer*> self{nullptr};
  std::atomic<int> calls{0};
  std::mutex got_mutex;
  std::vector<ai::core::ImuSample> got;  // filled on the reader thread
  ai::SerialLinesAccelerometer source(o, wall_s, [&] {
    ++calls;
    std::lock_guard<std::mutex> lock(got_mutex);
    if (ai::SerialLinesAccelerometer* s = self.load()) s->poll(wall_s(), &got);
  });
  self = &source;
  ASSERT_TRUE(wait_for([&] { return source.status().connects == 1; }, 5.0));
  DeviceProgram p;
  std::mt19937_64 rng(13);
  const std::map<long, Written> written = write_samples(dev, p, wall_s() + 0.02, 0, 2000, &rng);
  // The reader counts a batch's samples, then calls the callback: wait for the callback to have
  // handed every sample over (a fixed sleep after the count fails when the reader is preempted
  // between the two), bounded: a batch never handed over fails here and below.
  EXPECT_TRUE(wait_for(
      [&] {
        std::lock_guard<std::mutex> lock(got_mutex);
        return got.size() + 1 >= written.size();
      },
      5.0))
      << "the callback did not hand every sample over";
  self = nullptr;
  std::vector<ai::core::ImuSample> rest;
  source.poll(wall_s(), &rest);
  EXPECT_TRUE(rest.empty()) << rest.size() << " samples were not handed over by the callback";
  std::lock_guard<std::mutex> lock(got_mutex);
  ASSERT_EQ(got.size(), written.size() - 1);  // the first line: partial
  double worst = 0.0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const long k = std::lround(got[i].outputs.x());
    if (i > 0) {
      EXPECT_EQ(k, std::lround(got[i - 1].outputs.x()) + 1);
    }
    worst = std::max(worst, std::abs(got[i].stamp_s - written.at(k).truth_host_s));
  }
  EXPECT_LT(worst, 1e-3) << "worst stamp error " << worst * 1e3 << " ms";
  // 2 s of lines at 1 kHz read every 10 ms: about 200 batches (fewer when the host is slow),
  // where reading each line as it comes takes about 2000 wake-ups.
  EXPECT_GE(calls.load(), 1);
  EXPECT_LT(calls.load(), 500) << "the lines were not read in batches";
  std::printf("%zu samples in %d batches; worst stamp error %.0f us\n", got.size(), calls.load(),
              worst * 1e6);
}
