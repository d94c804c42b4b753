// The accelerometer node: publishes the samples of an AccelerometerSource on imu/data_raw as
// sensor_msgs/Imu (REP 145 and docs/design.md section 2: linear_acceleration carries R_u, R_v,
// R_w). The simulated source reads the DUT orientation from tf (the relative topic "tf", so rigs in
// different namespaces stay apart) at each sample time.
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/buffer.h>

#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/drivers/accelerometer_source.h"
#include "accel_intrinsics/drivers/serial_lines_source.h"

namespace accel_intrinsics {

struct AccelerometerOptions {
  std::string source = "simulated";         // backend: simulated or serial_lines
  std::string frame_id = "dut";             // header.frame_id of the IMU messages
  std::string world_frame = "world";        // tf frames the simulated source looks up
  double poll_hz = 200.0;                   // how often the source is polled (node clock), Hz
  double tf_cache_s = 60.0;                 // tf history kept, s
  SimulatedAccelerometerOptions simulated;  // ~device/S, ~device/O, ~device/effects, ~rate_hz, ...
  SerialLinesOptions serial_lines;          // ~serial_lines/port, baud, columns, separator, ...
  // Fault injection (~fault/...), times in seconds after the first gimbal command (t0):
  double stall_after_s = -1.0;     // publish nothing from t0 + stall_after_s (< 0: off) ...
  double stall_for_s = 1e9;        // ... for this long (default: for good)
  double decimate_after_s = -1.0;  // from t0 + decimate_after_s (< 0: off) ...
  int decimate = 1;                // ... publish only every decimate-th sample

  // Reads the private parameters; throws ParamError naming the parameter.
  static AccelerometerOptions load(const ros::NodeHandle& pnh);
};

class AccelerometerNode {
 public:
  // Builds the simulated source on this node's tf buffer, or the serial_lines source.
  AccelerometerNode(ros::NodeHandle nh, ros::NodeHandle pnh, const AccelerometerOptions& options);
  ~AccelerometerNode();  // stops the source (the serial reader) before the members it uses

  // Polls the source for samples up to `now` and publishes them (the timer calls it, or for
  // serial_lines the source's reader thread, as it stamps samples).
  void poll(const ros::Time& now);
  // serial_lines: how often the node logs the port's changes and updates its diagnostics, Hz.
  static constexpr double kSerialStatusHz = 10.0;

 private:
  void on_tf(const tf2_msgs::TFMessage::ConstPtr& msg);
  void on_command(const GimbalCommand::ConstPtr& msg);
  void on_timer(const ros::TimerEvent&);
  OrientationStatus lookup(double t_s, Eigen::Matrix3d* R_world_dut);

  ros::NodeHandle nh_, pnh_;
  AccelerometerOptions options_;
  tf2_ros::Buffer buffer_;
  std::unique_ptr<AccelerometerSource> source_;
  SimulatedAccelerometer* simulated_ = nullptr;           // source_ when simulated
  SerialLinesAccelerometer* serial_ = nullptr;            // source_ when serial_lines
  std::atomic<bool> serial_ready_{false};                 // source_ set: the reader may publish
  SerialLinesStatus serial_status_;                       // as last seen (logs what changed)
  std::unique_ptr<diagnostic_updater::Updater> updater_;  // serial_lines only
  ros::Subscriber tf_sub_, command_sub_;
  ros::Publisher imu_pub_;
  ros::Publisher temperature_pub_;  // imu/temperature, when the source publishes a temperature
  std::vector<core::TemperatureSample> temperature_batch_;
  ros::Timer timer_;
  ros::Time latest_tf_;  // newest stamp of a complete world -> dut chain
  ros::Time oldest_tf_;  // oldest stamp still in the buffer (after a restart: the first)
  bool have_origin_ = false;
  std::vector<core::ImuSample> batch_;
  std::uint64_t published_ = 0;
  double time_origin_s_ = 0.0;
  std::uint64_t fault_dropped_ = 0, decimate_counter_ = 0;
};

}  // namespace accel_intrinsics
