// Rostest: the real accelerometer node, source serial_lines, against a pseudo-terminal written
// here as a microcontroller would (see serial_lines_accelerometer.test).
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>
#include <random>
#include <string>
#include <vector>

#include "../support/precise_sleep.h"
#include "wait_for.h"

namespace {

// The node's "serial_lines" diagnostic, as last published on /diagnostics.
class SerialDiagnostics {
 public:
  void on_message(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg) {
    for (const auto& status : msg->status) {
      if (status.name.find("serial_lines") == std::string::npos) continue;
      std::lock_guard<std::mutex> lock(mutex_);
      level_ = status.level;
      message_ = status.message;
      for (const auto& kv : status.values) values_[kv.key] = kv.value;
      ++count_;
    }
  }
  std::string value(const std::string& key) const {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = values_.find(key);
    return it == values_.end() ? "" : it->second;
  }
  int level() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return level_;
  }
  std::string message() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return message_;
  }
  int count() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return count_;
  }

 private:
  mutable std::mutex mutex_;
  std::map<std::string, std::string> values_;
  std::string message_;
  int level_ = -1, count_ = 0;
};

struct Received {
  std::mutex mutex;
  std::vector<sensor_msgs::Imu> messages;
  void on_imu(const sensor_msgs::Imu::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex);
    messages.push_back(*msg);
  }
  std::size_t size() {
    std::lock_guard<std::mutex> lock(mutex);
    return messages.size();
  }
};

// The microcontroller: a pseudo-terminal behind `link`.
class Pty {
 public:
  explicit Pty(const std::string& link) : link_(link) {}
  ~Pty() { unplug(); }
  void plug() {
    char name[256] = {0};
    ASSERT_EQ(openpty(&master_, &slave_, name, nullptr, nullptr), 0);
    termios tio{};
    tcgetattr(slave_, &tio);
    cfmakeraw(&tio);
    tcsetattr(slave_, TCSANOW, &tio);
    std::filesystem::create_directories(std::filesystem::path(link_).parent_path());
    ::unlink(link_.c_str());
    ASSERT_EQ(::symlink(name, link_.c_str()), 0);
  }
  void unplug() {
    if (master_ >= 0) ::close(master_);
    if (slave_ >= 0) ::close(slave_);
    master_ = slave_ = -1;
    ::unlink(link_.c_str());
  }
  void write(const std::string& text) {
    std::size_t done = 0;
    while (master_ >= 0 && done < text.size()) {
      const ssize_t n = ::write(master_, text.data() + done, text.size() - done);
      if (n <= 0) return;
      done += static_cast<std::size_t>(n);
    }
  }

 private:
  std::string link_;
  int master_ = -1, slave_ = -1;
};

struct Truth {
  double host_s;
  std::string y, z;  // as printed
};

// Samples k in [k0, k1) at 500 Hz on a device clock 100 ppm fast (device time 40 + k / 500 s),
// sample k taken at host time host0 + (k / 500) / (1 + 1e-4) and written after an exponential
// jitter (mean 0.3 ms); before every 100th, one garbled line, never before the first line written
// (the node drops the first line after opening as partial whatever it holds: a garbled one there
// would let the real line through and break the counts below, one start in a hundred). x = k.
std::map<long, Truth> play(Pty& pty, double host0, long k0, long k1, std::mt19937_64* rng,
                           int* garbled) {
  std::map<long, Truth> truth;
  std::exponential_distribution<double> jitter(1.0 / 0.0003);
  const char* junk[] = {"\x01\x02\xfe\xff\n", "1.0,2.0\n", "41.0,x,1,2\n"};
  const accel_intrinsics::precise_sleep::PreciseWakeUps precise;
  for (long k = k0; k < k1; ++k) {
    const double device_s = k / 500.0;
    const double host = host0 + device_s / (1.0 + 1e-4);
    // A deadline on ros::WallTime's clock (CLOCK_REALTIME).
    accel_intrinsics::precise_sleep::sleep_until(CLOCK_REALTIME, host + jitter(*rng));
    char y[32], z[32], line[128];
    std::snprintf(y, sizeof y, "%.5f", -0.5 + 1e-3 * (k % 101));
    std::snprintf(z, sizeof z, "%.0f", 16384.0 + (k % 7));  // counts: any unit
    std::snprintf(line, sizeof line, "%.6f,%ld,%s,%s\n", 40.0 + device_s, k, y, z);
    std::string text = line;
    if (k % 100 == 50 && k != k0) {
      text = junk[(k / 100) % 3] + text;
      ++*garbled;
    }
    pty.write(text);
    truth[k] = {host, y, z};
  }
  return truth;
}

long as_long(const std::string& s) {
  return s.empty() ? -1 : std::stol(s);
}

}  // namespace

TEST(SerialLinesAccelerometer, PublishesTheDevicesSamplesWithDeviceTimeAndSurvivesAnUnplug) {
  ros::NodeHandle nh, pnh("~");
  std::string port;
  double max_error_s = 0.001;
  ASSERT_TRUE(pnh.getParam("port", port));
  pnh.getParam("max_stamp_error_s", max_error_s);
  Received received;
  SerialDiagnostics diag;
  ros::Subscriber imu_sub = nh.subscribe("imu/data_raw", 10000, &Received::on_imu, &received);
  ros::Subscriber diag_sub =
      nh.subscribe("/diagnostics", 100, &SerialDiagnostics::on_message, &diag);
  ros::AsyncSpinner spinner(2);
  spinner.start();

  // No device yet: the node says it cannot open the port, and keeps trying.
  ASSERT_TRUE(
      test_wait::wait_for([&] { return diag.count() > 0; }, 15.0, "the node's diagnostics"));
  EXPECT_EQ(diag.level(), diagnostic_msgs::DiagnosticStatus::ERROR) << diag.message();
  EXPECT_NE(diag.message().find("cannot be opened"), std::string::npos) << diag.message();
  ASSERT_TRUE(test_wait::wait_for([&] { return imu_sub.getNumPublishers() > 0; }, 10.0,
                                  "the node's imu/data_raw"));

  Pty pty(port);
  pty.plug();
  ASSERT_TRUE(test_wait::wait_for([&] { return diag.value("state") == "connected"; }, 10.0,
                                  "the node opening the port"));
  std::mt19937_64 rng(17);
  int garbled = 0;
  const double host0 = ros::WallTime::now().toSec() + 0.05;
  // 10 s of lines: the clock rate is the slope through the minima of 0.25 s bins, ~39 of them
  // (3 s gave ~11: for the same scatter of the minima, a slope about 6.7 times noisier).
  std::map<long, Truth> truth = play(pty, host0, 0, 5000, &rng, &garbled);
  ASSERT_TRUE(test_wait::wait_for([&] { return received.size() >= truth.size() - 1; }, 10.0,
                                  "every sample but the first"));
  ASSERT_TRUE(test_wait::wait_for(
      [&] { return as_long(diag.value("lines")) == static_cast<long>(truth.size() + garbled); },
      5.0, "the diagnostics counting every line"));
  EXPECT_EQ(diag.level(), diagnostic_msgs::DiagnosticStatus::OK) << diag.message();
  EXPECT_EQ(as_long(diag.value("garbled")), garbled + 1);  // + the first line (partial)
  EXPECT_EQ(as_long(diag.value("garbled_binary")), garbled / 3 + (garbled % 3 > 0));
  EXPECT_EQ(as_long(diag.value("garbled_partial")), 1);
  EXPECT_EQ(diag.value("clock_ready"), "true");
  const double rate_ppm = std::stod(diag.value("clock_rate_ppm"));
  EXPECT_NEAR(rate_ppm, -100.0, 40.0);
  char rate_text[32];
  std::snprintf(rate_text, sizeof rate_text, "%.1f", rate_ppm);
  RecordProperty("clock_rate_ppm", rate_text);  // in the test's XML result: the margin in CI
  std::printf("device clock rate seen by the node: %s ppm (-100 +- 40) from %s lines\n", rate_text,
              diag.value("lines").c_str());

  // Unplugged: the diagnostics say lost with the system's words; then back.
  pty.unplug();
  ASSERT_TRUE(test_wait::wait_for([&] { return diag.value("state") == "lost"; }, 5.0,
                                  "the diagnostics reporting the lost port"));
  EXPECT_EQ(diag.level(), diagnostic_msgs::DiagnosticStatus::ERROR);
  EXPECT_NE(diag.message().find("lost"), std::string::npos) << diag.message();
  const std::size_t before = received.size();
  pty.plug();
  ASSERT_TRUE(test_wait::wait_for([&] { return diag.value("connects") == "2"; }, 5.0,
                                  "the node reopening the port"));
  const long k_back = std::lround(std::ceil((ros::WallTime::now().toSec() - host0 + 0.05) * 500));
  const std::map<long, Truth> after = play(pty, host0, k_back, k_back + 750, &rng, &garbled);
  ASSERT_TRUE(test_wait::wait_for([&] { return received.size() >= before + after.size() - 1; },
                                  10.0, "samples after the return"));
  truth.insert(after.begin(), after.end());
  ros::WallDuration(0.2).sleep();  // anything extra (a garbled line published) would show now

  std::lock_guard<std::mutex> lock(received.mutex);
  EXPECT_EQ(received.messages.size(), truth.size() - 2);  // less the two first lines
  double worst = 0.0;
  for (const sensor_msgs::Imu& m : received.messages) {
    const long k = std::lround(m.linear_acceleration.x);
    ASSERT_TRUE(truth.count(k)) << "published a sample never written: x = " << k;
    const Truth& t = truth.at(k);
    EXPECT_EQ(m.linear_acceleration.y, std::strtod(t.y.c_str(), nullptr)) << k;
    EXPECT_EQ(m.linear_acceleration.z, std::strtod(t.z.c_str(), nullptr)) << k;
    EXPECT_EQ(m.header.frame_id, "dut");
    worst = std::max(worst, std::abs(m.header.stamp.toSec() - t.host_s));
  }
  EXPECT_LT(worst, max_error_s) << "worst stamp error " << worst * 1e3 << " ms";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "serial_lines_accelerometer_test");
  return RUN_ALL_TESTS();
}
