// Live load test of a running apply_calibration node: publishes sensor_msgs/Imu on imu/data_raw
// at --rate (default 10 kHz) for --seconds, subscribes imu/data_calibrated (a filter downstream),
// and reports the node's CPU share (from /proc/PID/stat) and how many messages came back.
//   rosrun accel_intrinsics apply_calibration _calibration_file:=result.json &
//   rosrun accel_intrinsics apply_calibration_load --pid $(pgrep -n apply_calibrati) --seconds 20
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

namespace {

double cpu_seconds(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  std::getline(in, line);
  std::istringstream s(line.substr(line.rfind(')') + 2));
  std::string field;
  unsigned long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && s >> field; ++i) {
    if (i == 14) utime = std::stoul(field);
    if (i == 15) stime = std::stoul(field);
  }
  return static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

std::atomic<std::uint64_t> received{0};
void on_calibrated(const sensor_msgs::Imu::ConstPtr&) { ++received; }

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "apply_calibration_load", ros::init_options::AnonymousName);
  int pid = 0;
  double rate_hz = 10000.0, seconds = 20.0, pace_s = 0.0005;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--pid") pid = std::atoi(argv[i + 1]);
    else if (key == "--rate") rate_hz = std::atof(argv[i + 1]);
    else if (key == "--seconds") seconds = std::atof(argv[i + 1]);
    else if (key == "--pace") pace_s = std::atof(argv[i + 1]);
  }
  if (pid <= 0 || rate_hz <= 0 || seconds <= 0 || pace_s < 0) {
    std::fprintf(stderr, "usage: apply_calibration_load --pid PID [--rate HZ] [--seconds S] [--pace S]\n");
    return 2;
  }
  ros::NodeHandle nh;
  ros::Publisher imu = nh.advertise<sensor_msgs::Imu>("imu/data_raw", 20000);
  ros::Subscriber sub = nh.subscribe("imu/data_calibrated", 20000, on_calibrated,
                                     ros::TransportHints().tcpNoDelay());
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
  ros::WallDuration(0.5).sleep();
  const double cpu0 = cpu_seconds(pid);
  const ros::WallTime wall0 = ros::WallTime::now();
  std::uint64_t sent = 0;
  sensor_msgs::Imu msg;
  msg.header.frame_id = "dut";
  msg.orientation_covariance[0] = -1;
  msg.angular_velocity_covariance[0] = -1;
  while (ros::ok()) {
    const double elapsed = (ros::WallTime::now() - wall0).toSec();
    if (elapsed >= seconds) break;
    const std::uint64_t due = static_cast<std::uint64_t>(elapsed * rate_hz);
    for (; sent < due; ++sent) {
      msg.header.stamp = ros::Time::now();
      msg.linear_acceleration.z = 9.8 + 1e-3 * static_cast<double>(sent % 7);
      imu.publish(msg);
    }
    ros::WallDuration(pace_s).sleep();
  }
  const double wall = (ros::WallTime::now() - wall0).toSec();
  ros::WallDuration(2.0).sleep();  // the node drains its queue
  const double cpu = cpu_seconds(pid) - cpu0;
  std::printf("sent %llu IMU messages in %.2f s (%.0f msgs/s), %llu came back calibrated\n",
              static_cast<unsigned long long>(sent), wall, static_cast<double>(sent) / wall,
              static_cast<unsigned long long>(received.load()));
  std::printf("apply_calibration (pid %d): CPU %.1f %% of one core\n", pid,
              100.0 * cpu / (wall + 2.0));
  return 0;
}
