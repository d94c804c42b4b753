// Live load test of a running calibration node: publishes IMU messages at --rate (default
// 10 kHz) and gimbal commands (0.5 s MOVING, then a dwell of --dwell s, default 1.5) on real time,
// (--first-dwell S: the first dwell lasts S instead, a long rest as the noise model takes it),
// then reports the node's CPU share (from /proc/PID/stat) and its resident memory before and after,
// and the node's own counters (calibration/status) to show that it kept up.
//   rosrun accel_intrinsics calibration __name:=calibration &        (real time, no use_sim_time)
//   rosrun accel_intrinsics calibration_node_load --pid $(pgrep -n calibration) --seconds 20
// The nodelet (accel_intrinsics/CalibrationNodelet) in this process, as in the IMU driver's
// manager: the IMU messages are published as shared pointers and reach it without serialization
// or sockets; its share is this process's CPU minus the publisher's thread (the main thread: the
// driver's work), i.e. the nodelet's IMU thread, its timers and roscpp's own threads.
//   rosrun accel_intrinsics calibration_node_load --nodelet 1 --rate 50000 --seconds 20
// The last line counts what the node received against what was sent (nothing may be lost).
#include <diagnostic_msgs/DiagnosticStatus.h>
#include <nodelet/loader.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>

#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "accel_intrinsics/GimbalCommand.h"
#include "proc_stats.h"

namespace {

using bench::cpu_seconds;
using bench::rss_kb;

std::mutex status_mutex;
std::map<std::string, std::string> status;
void on_status(const diagnostic_msgs::DiagnosticStatus::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(status_mutex);
  for (const auto& kv : msg->values) status[kv.key] = kv.value;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "calibration_node_load", ros::init_options::AnonymousName);
  int pid = 0, nodelet = 0;
  double rate_hz = 10000.0, seconds = 20.0, dwell_s = 1.5, first_dwell_s = 0.0;
  double pace_s = 0.0005;  // the publisher's sleep between rounds: messages come in small bursts
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--pid")
      pid = std::atoi(argv[i + 1]);
    else if (key == "--rate")
      rate_hz = std::atof(argv[i + 1]);
    else if (key == "--seconds")
      seconds = std::atof(argv[i + 1]);
    else if (key == "--dwell")
      dwell_s = std::atof(argv[i + 1]);
    else if (key == "--first-dwell")
      first_dwell_s = std::atof(argv[i + 1]);
    else if (key == "--pace")
      pace_s = std::atof(argv[i + 1]);
    else if (key == "--nodelet")
      nodelet = std::atoi(argv[i + 1]);
  }
  if ((pid <= 0) == (nodelet == 0) || rate_hz <= 0 || seconds <= 0 || dwell_s <= 0 || pace_s < 0 ||
      first_dwell_s < 0) {
    std::fprintf(stderr,
                 "usage: calibration_node_load (--pid PID | --nodelet 1) [--rate HZ] [--seconds S] "
                 "[--dwell S] [--first-dwell S] [--pace S]\n");
    return 2;
  }
  ros::NodeHandle nh;
  std::unique_ptr<nodelet::Loader> loader;
  if (nodelet) {
    pid = static_cast<int>(getpid());
    const std::string name = ros::this_node::getName() + "_calibration";
    ros::param::set(name + "/status_period_s", 0.5);
    loader.reset(new nodelet::Loader(false));
    // Its public topics are in its namespace, this node's: imu/data_raw, gimbal/command, ...
    if (!loader->load(name, "accel_intrinsics/CalibrationNodelet", ros::M_string(), {})) {
      std::fprintf(stderr,
                   "calibration_node_load: cannot load accel_intrinsics/CalibrationNodelet\n");
      return 1;
    }
  }
  ros::Publisher imu = nh.advertise<sensor_msgs::Imu>("imu/data_raw", 20000);
  ros::Publisher cmd = nh.advertise<accel_intrinsics::GimbalCommand>("gimbal/command", 100);
  ros::Subscriber sub = nh.subscribe("calibration/status", 10, on_status);
  const ros::WallTime wait_until = ros::WallTime::now() + ros::WallDuration(10.0);
  while ((imu.getNumSubscribers() == 0 || cmd.getNumSubscribers() == 0) &&
         ros::WallTime::now() < wait_until) {
    ros::WallDuration(0.05).sleep();
  }
  if (imu.getNumSubscribers() == 0) {
    std::fprintf(stderr, "calibration_node_load: nobody subscribes to %s\n",
                 imu.getTopic().c_str());
    return 1;
  }
  ros::WallDuration(0.5).sleep();
  const long main_tid = bench::current_thread_id();
  // In process: the nodelet's share = process - the publisher (this, the main thread).
  auto cpu_now = [&]() {
    return nodelet ? cpu_seconds(pid) - bench::thread_cpu_seconds(main_tid) : cpu_seconds(pid);
  };
  const long rss0 = rss_kb(pid);
  const double cpu0 = cpu_now();
  const double process_cpu0 = cpu_seconds(pid);
  const ros::WallTime wall0 = ros::WallTime::now();
  const ros::Time t0 = ros::Time::now();
  std::uint64_t sent = 0;
  double next_command = 0.0;
  bool moving = true;
  std::uint32_t step = 0;
  sensor_msgs::Imu msg;
  msg.header.frame_id = "dut";
  msg.orientation_covariance[0] = -1;
  msg.angular_velocity_covariance[0] = -1;
  while (ros::ok()) {
    const double elapsed = (ros::WallTime::now() - wall0).toSec();
    if (elapsed >= seconds) break;
    if (elapsed >= next_command) {
      accel_intrinsics::GimbalCommand c;
      c.header.stamp = t0 + ros::Duration(next_command);
      c.phase = 0;
      c.steps = 100000;
      c.step = step;
      c.state = moving ? accel_intrinsics::GimbalCommand::MOVING
                       : accel_intrinsics::GimbalCommand::SETTLED;
      cmd.publish(c);
      if (!moving) ++step;
      next_command += moving ? 0.5 : (step == 1 && first_dwell_s > 0.0 ? first_dwell_s : dwell_s);
      moving = !moving;
    }
    const std::uint64_t due = static_cast<std::uint64_t>(elapsed * rate_hz);
    for (; sent < due; ++sent) {
      msg.header.stamp = t0 + ros::Duration(static_cast<double>(sent) / rate_hz);
      msg.linear_acceleration.z = 9.8 + 1e-3 * static_cast<double>(sent % 7);
      if (nodelet) {
        // A shared pointer, as a nodelet driver publishes: passed as it is in process.
        imu.publish(sensor_msgs::ImuPtr(new sensor_msgs::Imu(msg)));
      } else {
        imu.publish(msg);
      }
    }
    ros::spinOnce();
    ros::WallDuration(pace_s).sleep();
  }
  const double wall = (ros::WallTime::now() - wall0).toSec();
  ros::WallDuration(1.5).sleep();  // the node drains its queue and publishes its status
  const double cpu = cpu_now() - cpu0;
  const double process_cpu = cpu_seconds(pid) - process_cpu0;
  const long rss1 = rss_kb(pid);
  const ros::WallTime status_until = ros::WallTime::now() + ros::WallDuration(3.0);
  while (ros::WallTime::now() < status_until) {
    ros::spinOnce();
    ros::WallDuration(0.05).sleep();
  }
  std::printf("sent %llu IMU messages in %.2f s (%.0f msgs/s) and %u dwells\n",
              static_cast<unsigned long long>(sent), wall, static_cast<double>(sent) / wall, step);
  std::printf("calibration %s (pid %d): CPU %.1f %% of one core; RSS %ld kB -> %ld kB\n",
              nodelet ? "nodelet (in process, pointers)" : "node", pid, 100.0 * cpu / (wall + 1.5),
              rss0, rss1);
  // In process, the publisher's thread also does roscpp's hand-off of each message (what the
  // driver's thread would do): the whole process shows whether work only moved between threads.
  if (nodelet) {
    std::printf("whole process with the publisher: %.1f %% of one core\n",
                100.0 * process_cpu / (wall + 1.5));
  }
  std::lock_guard<std::mutex> lock(status_mutex);
  std::printf(
      "node counters: samples_used %s, dropped_outside_dwell %s, dropped_late %s, "
      "dwells_x %s\n",
      status["samples_used"].c_str(), status["dropped_outside_dwell"].c_str(),
      status["dropped_late"].c_str(), status["dwells_x"].c_str());
  // Every sample the node took in is in one of its counters (used, or dropped for a reason).
  unsigned long long received = 0;
  for (const char* key :
       {"samples_used", "dropped_outside_dwell", "dropped_settle_discard", "dropped_non_finite",
        "dropped_backwards", "duplicates", "dropped_late"}) {
    received += std::strtoull(status[key].c_str(), nullptr, 10);
  }
  std::printf("received %llu of %llu IMU messages sent\n", received,
              static_cast<unsigned long long>(sent));
  if (loader) loader->clear();
  return 0;
}
