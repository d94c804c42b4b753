// apply_calibration: corrects a live IMU stream with a fitted calibration (docs/design.md section
// 7). Subscribes imu/data_raw, publishes imu/data_calibrated with linear_acceleration = P (R - O);
// every other field is passed through. linear_acceleration_covariance: P diag(sigma^2) P^T when
// the calibration file states the noise (a result with noise_density and sample_rate_hz), else
// the input's covariance carried through P (P C P^T) when the input states one, else the input's
// field as it is (unknown: -1 or zeros).
//
// Parameters (private): calibration_file (required: a result JSON/YAML or an imu_calib YAML),
// queue_size (default 1000, both ways), immediate (default true: the message is corrected and
// published in roscpp's network thread, no hand-off to a spinner thread), coalesce_s (default
// 0.001: after an idle spell the network thread naps this long so that the next messages are read
// in one go; 0 off; see immediate_callback_queue.h). With immediate false and coalesce_s > 0 the
// messages go to a queue of the node's own, served by a thread of its own that, once woken by a
// message, naps coalesce_s and then handles everything that came meanwhile: one wake-up per period
// instead of one per message (the nodelet's default: it never naps in another nodelet's thread).
// With immediate false and coalesce_s 0: the node handle's queue (the spinner's, or the nodelet
// manager's). batch_output (default true for the node, always false in the nodelet; only with
// immediate true): the corrected messages handled in one wake-up of the network thread go out in
// one socket write (TCPROS frames back to back, as a subscriber reads them anyway) when the next
// message wakes it, or within 5 ms when the stream stops; one write per batch instead of one per
// message. It breaks in-process subscribers of the output (which would see the first message of
// each batch only): never with a nodelet. A file that cannot be read refuses the start, naming it.
#pragma once

#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>

#include <Eigen/Core>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "accel_intrinsics/io/apply_calibration_file.h"
#include "accel_intrinsics/ros/immediate_callback_queue.h"

namespace accel_intrinsics {

// The per-message work, without ROS communication (tests and the benchmark call it).
class CalibrationApplier {
 public:
  explicit CalibrationApplier(const io::ApplyCalibration& calibration);
  // `out` = `in` with the corrected acceleration and its covariance.
  void apply(const sensor_msgs::Imu& in, sensor_msgs::Imu* out) const;
  const io::ApplyCalibration& calibration() const { return calibration_; }
  bool noise_known() const { return noise_known_; }

 private:
  io::ApplyCalibration calibration_;
  bool noise_known_ = false;
  Eigen::Matrix3d covariance_ = Eigen::Matrix3d::Zero();  // P diag(sigma^2) P^T when known
};

struct ApplyCalibrationOptions {
  std::string calibration_file;
  int queue_size = 1000;
  bool immediate = true;
  double coalesce_s = 0.001;
  bool batch_output = true;
  // Reads the private parameters and the file; throws ParamError naming the parameter (and the
  // file with what is wrong with it).
  static ApplyCalibrationOptions load(const ros::NodeHandle& pnh,
                                      io::ApplyCalibration* calibration);
};

class ApplyCalibrationNode {
 public:
  ApplyCalibrationNode(ros::NodeHandle nh, const ApplyCalibrationOptions& options,
                       const io::ApplyCalibration& calibration);
  ~ApplyCalibrationNode();
  ApplyCalibrationNode(const ApplyCalibrationNode&) = delete;
  ApplyCalibrationNode& operator=(const ApplyCalibrationNode&) = delete;

 private:
  void on_imu(const sensor_msgs::Imu::ConstPtr& msg);
  void serve_coalesced(double coalesce_s);
  // batch_output: the pending frames go out in one write; flush_stale from a timer.
  void flush_output();
  void flush_stale();

  CalibrationApplier applier_;
  ImmediateCallbackQueue immediate_queue_;
  // immediate false, coalesce_s > 0: the node's own queue and the thread that serves it.
  std::unique_ptr<ros::CallbackQueue> own_queue_;
  std::atomic<bool> serving_{false};
  std::thread server_;
  bool batch_output_ = false;
  std::mutex out_mutex_;
  std::vector<std::uint8_t> out_frames_;
  std::uint32_t out_count_ = 0;
  ros::WallTime out_since_;
  ros::WallTimer flush_timer_;
  ros::Subscriber sub_;
  ros::Publisher pub_;
};

}  // namespace accel_intrinsics
