// Live load test of the accelerometer node with source serial_lines (issue 33): plays a
// microcontroller on a pseudo-terminal behind --port (a symlink the node is told to open),
// printing `t,x,y,z` lines at --rate (default 1 kHz, one line at a time as a device would) for
// --seconds, subscribes imu/data_raw (a consumer downstream) and reports the node's CPU share
// (from /proc/PID/stat over the sending time) and how many samples came back.
//
//   rosrun accel_intrinsics accelerometer _source:=serial_lines _serial_lines/port:=/tmp/ttyB
//     _serial_lines/columns:=t,x,y,z &  (one line)
//   rosrun accel_intrinsics serial_lines_load --pid $! --port /tmp/ttyB --seconds 20
#include <pty.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <termios.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "proc_stats.h"

namespace {

std::atomic<std::uint64_t> received{0};
void on_imu(const sensor_msgs::Imu::ConstPtr&) {
  ++received;
}

int usage() {
  std::fprintf(stderr,
               "usage: serial_lines_load --pid PID --port LINK [--rate HZ] [--seconds S]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "serial_lines_load", ros::init_options::AnonymousName);
  int pid = 0;
  std::string link;
  double rate_hz = 1000.0, seconds = 20.0;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--pid")
      pid = std::atoi(argv[i + 1]);
    else if (key == "--port")
      link = argv[i + 1];
    else if (key == "--rate")
      rate_hz = std::atof(argv[i + 1]);
    else if (key == "--seconds")
      seconds = std::atof(argv[i + 1]);
    else
      return usage();
  }
  if (pid <= 0 || link.empty() || rate_hz <= 0 || seconds <= 0) return usage();
  int master = -1, slave = -1;
  char name[256] = {0};
  if (openpty(&master, &slave, name, nullptr, nullptr) != 0) {
    std::perror("serial_lines_load: openpty");
    return 1;
  }
  termios tio{};
  tcgetattr(slave, &tio);
  cfmakeraw(&tio);
  tcsetattr(slave, TCSANOW, &tio);
  ::unlink(link.c_str());
  if (::symlink(name, link.c_str()) != 0) {
    std::perror("serial_lines_load: symlink");
    return 1;
  }
  ros::NodeHandle nh;
  ros::Subscriber sub = nh.subscribe("imu/data_raw", 10000, on_imu);
  ros::AsyncSpinner spinner(1);
  spinner.start();

  using Clock = std::chrono::steady_clock;
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / rate_hz));
  std::uint64_t k = 0;
  auto write_line = [&](Clock::time_point when) {
    std::this_thread::sleep_until(when);
    char line[128];
    const int n = std::snprintf(line, sizeof line, "%.6f,%.5f,%.5f,%.5f\n", k / rate_hz,
                                0.01 * (k % 17), -0.02 * (k % 5), 9.80665 + 1e-5 * (k % 11));
    ++k;
    return ::write(master, line, static_cast<std::size_t>(n)) == n;
  };
  // Until the node has connected and its first samples came back (the clock fit's warm-up).
  Clock::time_point next = Clock::now();
  const Clock::time_point give_up = next + std::chrono::seconds(20);
  while (received.load() < 10) {
    if (Clock::now() > give_up) {
      std::fprintf(stderr, "serial_lines_load: no sample back from the node within 20 s\n");
      return 1;
    }
    write_line(next += period);
  }
  const std::uint64_t k0 = k, received0 = received.load();
  const double cpu0 = bench::cpu_seconds(pid);
  const Clock::time_point t0 = Clock::now();
  const Clock::time_point end =
      t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  next = t0;
  std::uint64_t failed = 0;
  while (next < end) failed += !write_line(next += period);
  const double cpu1 = bench::cpu_seconds(pid);
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the last poll
  const std::uint64_t sent = k - k0, back = received.load() - received0;
  std::printf("sent %llu lines in %.2f s (%.0f lines/s), %llu write failures\n",
              static_cast<unsigned long long>(sent), wall, sent / wall,
              static_cast<unsigned long long>(failed));
  std::printf("received %llu samples\n", static_cast<unsigned long long>(back));
  std::printf("CPU %.2f %% of one core\n", 100.0 * (cpu1 - cpu0) / wall);
  ::unlink(link.c_str());
  ::close(master);
  ::close(slave);
  return cpu0 < 0 || cpu1 < 0 ? 1 : 0;
}
