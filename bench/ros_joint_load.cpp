// Live load test of the gimbal controller's ros_joint driver (issue 33): plays a ros_control
// gimbal beside a running gimbal_controller (driver ros_joint, config/ros_joint_gimbal.yaml's
// joints and command topics): follows each Float64 position command at once and publishes
// sensor_msgs/JointState (name, position, velocity, effort of the two joints, as
// joint_state_controller does) on joint_states, first at --baseline-rate (default 10 Hz) for
// --seconds, then at --rate (default 1 kHz, one message at a time) for --seconds. Before the
// measurements it calls gimbal_controller/start, so the protocol runs (moves, arrivals, tf) while
// the controller's CPU share is read from /proc/PID/stat over each period. Prints both shares,
// their difference (what handling the JointState messages at --rate costs) and the moves the
// controller commanded (the protocol ran). With --reference-pid (bench/joint_state_sink, a
// subscriber that does nothing, woken per message) the same shares of that process are printed:
// what a naive subscriber pays for the stream.
//
//   rosparam load config/ros_joint_gimbal.yaml /gimbal_controller
//   rosrun accel_intrinsics gimbal_controller _driver:=ros_joint &
//   rosrun accel_intrinsics ros_joint_load --pid $! --seconds 20
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64.h>
#include <std_srvs/Trigger.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <string>
#include <thread>

#include "proc_stats.h"

namespace {

std::mutex mutex;
double outer_rad = 0.0, inner_rad = 0.0;
std::atomic<std::uint64_t> commands{0};

void on_outer_command(const std_msgs::Float64::ConstPtr& m) {
  std::lock_guard<std::mutex> lock(mutex);
  outer_rad = m->data;
  ++commands;
}

void on_inner_command(const std_msgs::Float64::ConstPtr& m) {
  std::lock_guard<std::mutex> lock(mutex);
  inner_rad = m->data;
  ++commands;
}

int usage() {
  std::fprintf(stderr,
               "usage: ros_joint_load --pid PID [--reference-pid PID] [--rate HZ] "
               "[--baseline-rate HZ] [--seconds S]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "ros_joint_load", ros::init_options::AnonymousName);
  int pid = 0, reference_pid = 0;
  double rate_hz = 1000.0, baseline_hz = 10.0, seconds = 20.0;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--pid")
      pid = std::atoi(argv[i + 1]);
    else if (key == "--reference-pid")
      reference_pid = std::atoi(argv[i + 1]);
    else if (key == "--rate")
      rate_hz = std::atof(argv[i + 1]);
    else if (key == "--baseline-rate")
      baseline_hz = std::atof(argv[i + 1]);
    else if (key == "--seconds")
      seconds = std::atof(argv[i + 1]);
    else
      return usage();
  }
  if (pid <= 0 || rate_hz <= 0 || baseline_hz <= 0 || seconds <= 0) return usage();

  ros::NodeHandle nh;
  // The joints and command topics of config/ros_joint_gimbal.yaml (relative to the controller's
  // namespace, the root here).
  ros::Subscriber outer_sub =
      nh.subscribe("gimbal_outer_position_controller/command", 10, on_outer_command);
  ros::Subscriber inner_sub =
      nh.subscribe("gimbal_inner_position_controller/command", 10, on_inner_command);
  ros::Publisher pub = nh.advertise<sensor_msgs::JointState>("joint_states", 1000);
  ros::AsyncSpinner spinner(1);
  spinner.start();

  sensor_msgs::JointState msg;
  msg.name = {"gimbal_outer_joint", "gimbal_inner_joint"};
  msg.position.assign(2, 0.0);
  msg.velocity.assign(2, 0.0);
  msg.effort.assign(2, 0.0);
  std::uint64_t seq = 0;
  using Clock = std::chrono::steady_clock;
  // Publishes at rate for seconds (one message at a time); returns the messages sent.
  auto publish_for = [&](double rate, double duration_s) {
    const auto period =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / rate));
    const Clock::time_point end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                     std::chrono::duration<double>(duration_s));
    Clock::time_point next = Clock::now();
    std::uint64_t sent = 0;
    while (next < end && ros::ok()) {
      std::this_thread::sleep_until(next += period);
      {
        std::lock_guard<std::mutex> lock(mutex);
        msg.position[0] = outer_rad;
        msg.position[1] = inner_rad;
      }
      msg.header.seq = static_cast<std::uint32_t>(++seq);
      msg.header.stamp = ros::Time::now();
      pub.publish(msg);
      ++sent;
    }
    return sent;
  };

  // Until the controller subscribes (and its start service is there), at the baseline rate.
  const Clock::time_point give_up = Clock::now() + std::chrono::seconds(20);
  const std::uint32_t subscribers = reference_pid > 0 ? 2 : 1;
  while (pub.getNumSubscribers() < subscribers ||
         !ros::service::exists("gimbal_controller/start", false)) {
    if (Clock::now() > give_up) {
      std::fprintf(stderr, "ros_joint_load: no gimbal_controller subscribed within 20 s\n");
      return 1;
    }
    publish_for(baseline_hz, 0.2);
  }
  publish_for(baseline_hz, 0.5);
  std_srvs::Trigger start;
  if (!ros::service::call("gimbal_controller/start", start) || !start.response.success) {
    std::fprintf(stderr, "ros_joint_load: gimbal_controller/start failed: %s\n",
                 start.response.message.c_str());
    return 1;
  }
  publish_for(baseline_hz, 1.0);  // past the start delay, into the protocol

  auto measure = [&](double rate, double* cpu_pct, double* achieved_hz, double* reference_pct) {
    const std::uint64_t commands0 = commands.load();
    const double ref0 = reference_pid > 0 ? bench::cpu_seconds(reference_pid) : 0.0;
    const double cpu0 = bench::cpu_seconds(pid);
    const Clock::time_point t0 = Clock::now();
    const std::uint64_t sent = publish_for(rate, seconds);
    const double cpu1 = bench::cpu_seconds(pid);
    const double ref1 = reference_pid > 0 ? bench::cpu_seconds(reference_pid) : 0.0;
    const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
    *cpu_pct = 100.0 * (cpu1 - cpu0) / wall;
    *reference_pct = 100.0 * (ref1 - ref0) / wall;
    *achieved_hz = sent / wall;
    std::printf(
        "at %.0f Hz: sent %llu JointState messages in %.2f s (%.0f msgs/s), "
        "%llu commands back; CPU %.2f %% of one core\n",
        rate, static_cast<unsigned long long>(sent), wall, *achieved_hz,
        static_cast<unsigned long long>(commands.load() - commands0), *cpu_pct);
    if (reference_pid > 0)
      std::printf("at %.0f Hz: reference subscriber CPU %.2f %% of one core\n", rate,
                  *reference_pct);
    return cpu0 >= 0 && cpu1 >= 0 && ref0 >= 0 && ref1 >= 0;
  };
  double base_cpu = 0, base_hz = 0, cpu = 0, hz = 0, base_ref = 0, ref = 0;
  const bool ok =
      measure(baseline_hz, &base_cpu, &base_hz, &base_ref) && measure(rate_hz, &cpu, &hz, &ref);
  std::printf(
      "baseline CPU %.2f %%; at rate CPU %.2f %%; JointState handling %.2f %% of one core\n",
      base_cpu, cpu, cpu - base_cpu);
  std::printf("commands received %llu\n", static_cast<unsigned long long>(commands.load()));
  spinner.stop();
  return ok ? 0 : 1;
}
