// Live load test of the apply_calibration node or nodelet at 10 kHz: publishes sensor_msgs/Imu on
// imu/data_raw at --rate (default 10 kHz) for --seconds, subscribes imu/data_calibrated (a filter
// downstream) and reports the apply node's CPU share and how many messages came back.
//
//   Node (roscpp TCP both ways; CPU from /proc/PID/stat):
//     rosrun accel_intrinsics apply_calibration _calibration_file:=result.json &
//     rosrun accel_intrinsics apply_calibration_load --pid $(pgrep -n apply_calibrati) --seconds 20
//   Nodelet, in this process as in a nodelet manager beside the driver and the filter (messages
//   passed by pointer: the publisher publishes shared pointers, intra-process):
//     rosrun accel_intrinsics apply_calibration_load --nodelet result.json [--immediate 0|1]
//   The nodelet's share is this process's CPU minus the threads of the publisher (main thread)
//   and of the downstream subscriber (its spinner thread): the nodelet loader's worker threads and
//   roscpp's own threads, i.e. what the nodelet adds to a manager.
//
// Options: --rate HZ, --seconds S, --pace S (the publisher's sleep between rounds: 0.0005 sends
// bursts of 5 at 10 kHz, 0.0001 one message at a time as a driver would). The CPU share is over
// the sending time plus the drain (until every message came back, at most 2 s).
#include <nodelet/loader.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "proc_stats.h"

namespace {

std::atomic<std::uint64_t> received{0};
std::atomic<long> receiver_tid{0};
void on_calibrated(const sensor_msgs::Imu::ConstPtr&) {
  if (receiver_tid.load() == 0) receiver_tid = bench::current_thread_id();
  ++received;
}

int usage() {
  std::fprintf(stderr,
               "usage: apply_calibration_load (--pid PID | --nodelet CALIBRATION_FILE [--immediate "
               "0|1]) [--rate HZ] [--seconds S] [--pace S]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "apply_calibration_load", ros::init_options::AnonymousName);
  int pid = 0, immediate = -1;
  std::string nodelet_file;
  double rate_hz = 10000.0, seconds = 20.0, pace_s = 0.0005;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--pid")
      pid = std::atoi(argv[i + 1]);
    else if (key == "--nodelet")
      nodelet_file = argv[i + 1];
    else if (key == "--immediate")
      immediate = std::atoi(argv[i + 1]);
    else if (key == "--rate")
      rate_hz = std::atof(argv[i + 1]);
    else if (key == "--seconds")
      seconds = std::atof(argv[i + 1]);
    else if (key == "--pace")
      pace_s = std::atof(argv[i + 1]);
    else
      return usage();
  }
  const bool in_process = !nodelet_file.empty();
  if ((pid <= 0) == !in_process || rate_hz <= 0 || seconds <= 0 || pace_s < 0) return usage();
  ros::NodeHandle nh;
  std::unique_ptr<nodelet::Loader> loader;
  if (in_process) {
    const std::string name = ros::this_node::getName() + "_apply";
    ros::param::set(name + "/calibration_file", nodelet_file);
    if (immediate >= 0) ros::param::set(name + "/immediate", immediate != 0);
    loader.reset(new nodelet::Loader(false));
    ros::M_string remappings;
    remappings[ros::names::resolve(name + "/imu/data_raw")] = ros::names::resolve("imu/data_raw");
    remappings[ros::names::resolve(name + "/imu/data_calibrated")] =
        ros::names::resolve("imu/data_calibrated");
    if (!loader->load(name, "accel_intrinsics/ApplyCalibrationNodelet", remappings, {})) {
      std::fprintf(
          stderr, "apply_calibration_load: cannot load accel_intrinsics/ApplyCalibrationNodelet\n");
      return 1;
    }
  }
  ros::Publisher imu = nh.advertise<sensor_msgs::Imu>("imu/data_raw", 20000);
  ros::Subscriber sub =
      nh.subscribe("imu/data_calibrated", 20000, on_calibrated, ros::TransportHints().tcpNoDelay());
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const ros::WallTime wait_until = ros::WallTime::now() + ros::WallDuration(10.0);
  while ((imu.getNumSubscribers() == 0 || sub.getNumPublishers() == 0) &&
         ros::WallTime::now() < wait_until) {
    ros::WallDuration(0.05).sleep();
  }
  if (imu.getNumSubscribers() == 0 || sub.getNumPublishers() == 0) {
    std::fprintf(stderr, "apply_calibration_load: no apply node on %s -> imu/data_calibrated\n",
                 imu.getTopic().c_str());
    return 1;
  }
  // Warm-up: a few messages so that the receiver's thread is known before the measurement.
  sensor_msgs::Imu msg;
  msg.header.frame_id = "dut";
  msg.orientation_covariance[0] = -1;
  msg.angular_velocity_covariance[0] = -1;
  for (int i = 0; i < 10 && receiver_tid.load() == 0; ++i) {
    imu.publish(sensor_msgs::ImuPtr(new sensor_msgs::Imu(msg)));
    ros::WallDuration(0.05).sleep();
  }
  ros::WallDuration(0.5).sleep();
  const long main_tid = bench::current_thread_id();
  const int measured_pid = in_process ? static_cast<int>(getpid()) : pid;
  // In process: the nodelet's share = process - publisher thread - receiver thread.
  auto cpu_now = [&]() {
    double cpu = bench::cpu_seconds(measured_pid);
    if (in_process) {
      cpu -= bench::thread_cpu_seconds(main_tid);
      if (receiver_tid.load() != 0) cpu -= bench::thread_cpu_seconds(receiver_tid.load());
    }
    return cpu;
  };
  const std::uint64_t received0 = received.load();
  const double cpu0 = cpu_now();
  const double process_cpu0 = bench::cpu_seconds(measured_pid);
  const ros::WallTime wall0 = ros::WallTime::now();
  std::uint64_t sent = 0;
  while (ros::ok()) {
    const double elapsed = (ros::WallTime::now() - wall0).toSec();
    if (elapsed >= seconds) break;
    const std::uint64_t due = static_cast<std::uint64_t>(elapsed * rate_hz);
    for (; sent < due; ++sent) {
      msg.header.stamp = ros::Time::now();
      msg.linear_acceleration.z = 9.8 + 1e-3 * static_cast<double>(sent % 7);
      // A shared pointer: passed as it is to an in-process subscriber, serialized for TCP.
      imu.publish(sensor_msgs::ImuPtr(new sensor_msgs::Imu(msg)));
    }
    ros::WallDuration(pace_s).sleep();
  }
  const double send_wall = (ros::WallTime::now() - wall0).toSec();
  const ros::WallTime drain_until = ros::WallTime::now() + ros::WallDuration(2.0);
  while (received.load() - received0 < sent && ros::WallTime::now() < drain_until) {
    ros::WallDuration(0.001).sleep();
  }
  const double wall = (ros::WallTime::now() - wall0).toSec();
  const double cpu = cpu_now() - cpu0;
  const double process_cpu = bench::cpu_seconds(measured_pid) - process_cpu0;
  std::printf("sent %llu IMU messages in %.2f s (%.0f msgs/s), %llu came back calibrated\n",
              static_cast<unsigned long long>(sent), send_wall,
              static_cast<double>(sent) / send_wall,
              static_cast<unsigned long long>(received.load() - received0));
  if (in_process) {
    std::printf(
        "apply_calibration nodelet (in process, pointers): CPU %.1f %% of one core "
        "(whole process with publisher and subscriber: %.1f %%)\n",
        100.0 * cpu / wall, 100.0 * process_cpu / wall);
  } else {
    std::printf("apply_calibration (pid %d): CPU %.1f %% of one core\n", pid, 100.0 * cpu / wall);
  }
  spinner.stop();
  if (loader) loader->clear();
  return 0;
}
