#include "accel_intrinsics/ros/apply_calibration_node.h"

#include <ros/topic_manager.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/ros/names.h"
#include "accel_intrinsics/ros/params.h"

namespace accel_intrinsics {

CalibrationApplier::CalibrationApplier(const io::ApplyCalibration& calibration)
    : calibration_(calibration) {
  noise_known_ = calibration.sample_std.allFinite();
  if (noise_known_) {
    covariance_ =
        calibration.P * calibration.sample_std.cwiseAbs2().asDiagonal() * calibration.P.transpose();
  }
}

void CalibrationApplier::apply(const sensor_msgs::Imu& in, sensor_msgs::Imu* out) const {
  *out = in;
  const Eigen::Vector3d raw(in.linear_acceleration.x, in.linear_acceleration.y,
                            in.linear_acceleration.z);
  const Eigen::Vector3d a = calibration_.P * (raw - calibration_.O);
  out->linear_acceleration.x = a(0);
  out->linear_acceleration.y = a(1);
  out->linear_acceleration.z = a(2);
  if (noise_known_) {
    for (int i = 0; i < 9; ++i) out->linear_acceleration_covariance[i] = covariance_(i / 3, i % 3);
    return;
  }
  // REP 145: -1 in the first element means unknown, all zeros too; anything else is a
  // covariance of the raw outputs, carried through P.
  const auto& c = in.linear_acceleration_covariance;
  bool all_zero = true;
  for (double v : c) all_zero = all_zero && v == 0.0;
  if (c[0] == -1.0 || all_zero) return;
  Eigen::Matrix3d C;
  for (int i = 0; i < 9; ++i) C(i / 3, i % 3) = c[i];
  const Eigen::Matrix3d out_c = calibration_.P * C * calibration_.P.transpose();
  for (int i = 0; i < 9; ++i) out->linear_acceleration_covariance[i] = out_c(i / 3, i % 3);
}

ApplyCalibrationOptions ApplyCalibrationOptions::load(const ros::NodeHandle& pnh,
                                                      io::ApplyCalibration* calibration) {
  ApplyCalibrationOptions o;
  read_param(pnh, "calibration_file", &o.calibration_file);
  require(!o.calibration_file.empty(), pnh, "calibration_file",
          "is required: a result (offline_fit JSON, the calibration node's intrinsics.yaml) or "
          "an imu_calib YAML");
  read_param(pnh, "queue_size", &o.queue_size);
  require(o.queue_size >= 1, pnh, "queue_size", "must be >= 1");
  read_param(pnh, "immediate", &o.immediate);
  read_param(pnh, "coalesce_s", &o.coalesce_s);
  read_param(pnh, "batch_output", &o.batch_output);
  require(std::isfinite(o.coalesce_s) && o.coalesce_s >= 0.0 && o.coalesce_s <= 0.05, pnh,
          "coalesce_s", "must be in [0, 0.05] s");
  try {
    *calibration = io::read_apply_calibration(o.calibration_file);
  } catch (const io::IoError& e) {
    throw ParamError("parameter " + param_name(pnh, "calibration_file") + ": " + e.what());
  }
  return o;
}

ApplyCalibrationNode::ApplyCalibrationNode(ros::NodeHandle nh,
                                           const ApplyCalibrationOptions& options,
                                           const io::ApplyCalibration& calibration)
    : applier_(calibration) {
  pub_ = nh.advertise<sensor_msgs::Imu>(names::kCalibratedImuTopic, options.queue_size);
  ros::CallbackQueueInterface* queue = nullptr;  // the node handle's
  if (options.immediate) {
    queue = &immediate_queue_;
    batch_output_ = options.batch_output;
    if (batch_output_) {
      immediate_queue_.set_on_wake([this]() { flush_output(); });
      // When the stream stops, nothing wakes the network thread: a timer (the node handle's
      // queue) sends what waited longer than 2 ms.
      flush_timer_ = nh.createWallTimer(ros::WallDuration(0.005),
                                        [this](const ros::WallTimerEvent&) { flush_stale(); });
    }
  } else if (options.coalesce_s > 0.0) {
    own_queue_.reset(new ros::CallbackQueue);
    queue = own_queue_.get();
  }
  ros::SubscribeOptions sub_options = ros::SubscribeOptions::create<sensor_msgs::Imu>(
      names::kImuTopic, options.queue_size,
      boost::bind(&ApplyCalibrationNode::on_imu, this, boost::placeholders::_1),
      ros::VoidConstPtr(), queue);
  sub_options.transport_hints = ros::TransportHints().tcpNoDelay();
  immediate_queue_.set_coalesce_period(options.coalesce_s);
  sub_ = nh.subscribe(sub_options);
  if (own_queue_) {
    serving_ = true;
    server_ = std::thread(&ApplyCalibrationNode::serve_coalesced, this, options.coalesce_s);
  }
  ROS_INFO("apply_calibration: %s from %s (%s), %s -> %s", calibration.kind.c_str(),
           options.calibration_file.c_str(),
           applier_.noise_known() ? "with its noise: covariance filled" : "no noise figures",
           sub_.getTopic().c_str(), pub_.getTopic().c_str());
}

ApplyCalibrationNode::~ApplyCalibrationNode() {
  sub_.shutdown();
  flush_timer_.stop();
  if (server_.joinable()) {
    serving_ = false;
    server_.join();
  }
}

void ApplyCalibrationNode::serve_coalesced(double coalesce_s) {
  // callAvailable waits (woken by the first message after an idle spell) and handles what is
  // there; the nap then lets the next messages pile up in the queue, handled together on the next
  // round. Publishers adding to the queue meanwhile wake nobody: one wake-up per coalesce_s at
  // most, for at most coalesce_s of added latency.
  const auto nap = std::chrono::duration<double>(coalesce_s);
  while (serving_) {
    own_queue_->callAvailable(ros::WallDuration(0.1));
    if (serving_) std::this_thread::sleep_for(nap);
  }
}

void ApplyCalibrationNode::on_imu(const sensor_msgs::Imu::ConstPtr& msg) {
  sensor_msgs::ImuPtr out(new sensor_msgs::Imu);
  applier_.apply(*msg, out.get());
  if (!batch_output_) {
    pub_.publish(out);
    return;
  }
  // A TCPROS frame (4-byte little-endian length, then the message) appended to the batch.
  const std::uint32_t length = ros::serialization::serializationLength(*out);
  std::lock_guard<std::mutex> lock(out_mutex_);
  if (out_count_ == 0) out_since_ = ros::WallTime::now();
  const std::size_t at = out_frames_.size();
  out_frames_.resize(at + 4 + length);
  ros::serialization::OStream stream(out_frames_.data() + at, 4 + length);
  stream.next(length);
  ros::serialization::serialize(stream, *out);
  ++out_count_;
}

void ApplyCalibrationNode::flush_output() {
  std::lock_guard<std::mutex> lock(out_mutex_);  // held while publishing: batches stay in order
  if (out_count_ == 0) return;
  ros::SerializedMessage batch;
  batch.num_bytes = static_cast<std::uint32_t>(out_frames_.size());
  batch.buf.reset(new std::uint8_t[batch.num_bytes]);
  std::copy(out_frames_.begin(), out_frames_.end(), batch.buf.get());
  batch.message_start = batch.buf.get() + 4;
  out_frames_.clear();
  out_count_ = 0;
  // The publisher's own path with a prepared buffer: the subscriber links write it as it is.
  ros::SerializedMessage m;
  ros::TopicManager::instance()->publish(
      pub_.getTopic(), [&batch]() { return batch; }, m);
}

void ApplyCalibrationNode::flush_stale() {
  {
    std::lock_guard<std::mutex> lock(out_mutex_);
    if (out_count_ == 0 || (ros::WallTime::now() - out_since_).toSec() < 0.002) return;
  }
  flush_output();
}

}  // namespace accel_intrinsics
