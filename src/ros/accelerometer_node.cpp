// Accelerometer node: AccelerometerSource -> imu/data_raw.
#include "accel_intrinsics/ros/accelerometer_node.h"

#include <sensor_msgs/Temperature.h>
#include <tf2/exceptions.h>

#include <cmath>
#include <stdexcept>

#include "accel_intrinsics/ros/accelerometer_serial_lines.h"
#include "accel_intrinsics/ros/conversions.h"
#include "accel_intrinsics/ros/names.h"
#include "accel_intrinsics/ros/params.h"

namespace accel_intrinsics {

AccelerometerOptions AccelerometerOptions::load(const ros::NodeHandle& pnh) {
  AccelerometerOptions o;
  read_param(pnh, "source", &o.source);
  require(o.source == "simulated" || o.source == "serial_lines", pnh, "source",
          "unknown accelerometer source '" + o.source +
              "' (known: simulated, serial_lines; for an IMU with its own ROS driver run the "
              "driver and remap its topic, see launch/rig.launch)");
  if (o.source == "serial_lines") o.serial_lines = load_serial_lines_options(pnh);
  read_param(pnh, "frame_id", &o.frame_id);
  require(!o.frame_id.empty(), pnh, "frame_id", "must not be empty");
  read_param(pnh, "world_frame", &o.world_frame);
  require(!o.world_frame.empty(), pnh, "world_frame", "must not be empty");
  read_param(pnh, "poll_hz", &o.poll_hz);
  require(std::isfinite(o.poll_hz) && o.poll_hz >= 1.0 && o.poll_hz <= 10000.0, pnh, "poll_hz",
          "must be in [1, 10000] Hz");
  read_param(pnh, "tf_cache_s", &o.tf_cache_s);
  require(std::isfinite(o.tf_cache_s) && o.tf_cache_s >= 1.0, pnh, "tf_cache_s", "must be >= 1 s");

  SimulatedAccelerometerOptions& s = o.simulated;
  read_matrix3(pnh, "device/S", &s.truth.S);
  read_vector3(pnh, "device/O", &s.truth.O);
  read_effects(pnh, "device/effects", &s.truth.effects);
  // A device that ages between runs (the lab archive's history, docs/design.md section 13): S and O
  // after device/aging/age_days of a linear drift.
  double age_days = 0.0;
  Eigen::Vector3d responsivity_per_day = Eigen::Vector3d::Zero();
  Eigen::Vector3d offset_per_day = Eigen::Vector3d::Zero();
  read_param(pnh, "device/aging/age_days", &age_days);
  require(std::isfinite(age_days) && age_days >= 0.0, pnh, "device/aging/age_days",
          "must be finite and >= 0 days");
  read_vector3(pnh, "device/aging/responsivity_per_day", &responsivity_per_day);
  read_vector3(pnh, "device/aging/offset_per_day", &offset_per_day);
  for (int i = 0; i < 3; ++i) s.truth.S.row(i) *= 1.0 + responsivity_per_day[i] * age_days;
  s.truth.O += offset_per_day * age_days;
  read_param(pnh, "rate_hz", &s.rate_hz);
  read_param(pnh, "noise_density", &s.noise_density);
  read_param(pnh, "bias/gm_sigma", &s.bias_gm_sigma);
  read_param(pnh, "bias/gm_tau_s", &s.bias_gm_tau_s);
  read_param(pnh, "bias/random_walk", &s.bias_random_walk);
  read_param(pnh, "quantization", &s.quantization);
  read_param(pnh, "local_gravity", &s.local_gravity);
  int seed = 1;
  if (read_param(pnh, "seed", &seed)) {
    require(seed >= 0, pnh, "seed", "must be >= 0");
    s.seed = static_cast<std::uint64_t>(seed);
  }
  core::TemperatureProfile& temp = s.temperature;
  read_param(pnh, "temperature/publish", &temp.recorded);
  read_param(pnh, "temperature/start_c", &temp.start_c);
  s.temperature_reference_c = temp.start_c;
  read_param(pnh, "temperature/reference_c", &s.temperature_reference_c);
  read_param(pnh, "temperature/rate_c_per_s", &temp.rate_c_per_s);
  read_param(pnh, "temperature/sine_amplitude_c", &temp.sine_amplitude_c);
  read_param(pnh, "temperature/sine_period_s", &temp.sine_period_s);
  read_param(pnh, "temperature/noise_c", &temp.noise_c);
  read_param(pnh, "temperature/rate_hz", &temp.rate_hz);
  try {
    s.validate();
  } catch (const std::invalid_argument& e) {
    throw ParamError("parameter " + pnh.getNamespace() + "/" + e.what());
  }
  require(o.poll_hz * 10.0 >= 1.0, pnh, "poll_hz", "too low");
  read_param(pnh, "fault/stall_after_s", &o.stall_after_s);
  read_param(pnh, "fault/stall_for_s", &o.stall_for_s);
  require(std::isfinite(o.stall_after_s) && std::isfinite(o.stall_for_s) && o.stall_for_s > 0.0,
          pnh, "fault/stall_for_s", "must be finite and > 0 s");
  read_param(pnh, "fault/decimate_after_s", &o.decimate_after_s);
  read_param(pnh, "fault/decimate", &o.decimate);
  require(std::isfinite(o.decimate_after_s), pnh, "fault/decimate_after_s", "must be finite");
  require(o.decimate >= 1, pnh, "fault/decimate", "must be >= 1");
  return o;
}

AccelerometerNode::AccelerometerNode(ros::NodeHandle nh, ros::NodeHandle pnh,
                                     const AccelerometerOptions& options)
    : nh_(nh), pnh_(pnh), options_(options), buffer_(ros::Duration(options.tf_cache_s)) {
  imu_pub_ = nh_.advertise<sensor_msgs::Imu>(names::kImuTopic, 10000);
  if (options_.source == "serial_lines") {
    // A bare MEMS part on a microcontroller (docs/design.md section 15): no tf, no gimbal. The
    // reader thread publishes what it stamped as it reads (no polling timer, no wake-up of this
    // thread per batch); the timer only logs and publishes the diagnostics.
    timer_ =
        nh_.createTimer(ros::Duration(1.0 / kSerialStatusHz), &AccelerometerNode::on_timer, this);
    auto serial = std::make_unique<SerialLinesAccelerometer>(
        options_.serial_lines, [] { return ros::Time::now().toSec(); },
        [this] {
          if (serial_ready_) poll(ros::Time::now());  // else: taken with the next batch
        });
    serial_ = serial.get();
    source_ = std::move(serial);
    serial_ready_ = true;
    updater_.reset(new diagnostic_updater::Updater(nh_, pnh_, pnh_.getNamespace()));
    updater_->setHardwareID("serial_lines " + options_.serial_lines.port);
    updater_->add("serial_lines", [this](diagnostic_updater::DiagnosticStatusWrapper& status) {
      diagnose_serial_lines(serial_->status(), options_.serial_lines, ros::Time::now().toSec(),
                            &status);
    });
    ROS_INFO("accelerometer: serial_lines source on %s (columns %s), publishing %s",
             options_.serial_lines.port.c_str(),
             options_.serial_lines.format.columns_text().c_str(),
             nh_.resolveName(names::kImuTopic).c_str());
    return;
  }
  timer_ =
      nh_.createTimer(ros::Duration(1.0 / options_.poll_hz), &AccelerometerNode::on_timer, this);
  auto simulated = std::make_unique<SimulatedAccelerometer>(
      options_.simulated, [this](double t_s, Eigen::Matrix3d* R) { return lookup(t_s, R); });
  simulated_ = simulated.get();
  source_ = std::move(simulated);
  if (source_->publishes_temperature())
    temperature_pub_ = nh_.advertise<sensor_msgs::Temperature>(
        core::channel_spec(core::Channel::Temperature).topic, 1000);
  tf_sub_ = nh_.subscribe(names::kTfTopic, 1000, &AccelerometerNode::on_tf, this,
                          ros::TransportHints().tcpNoDelay());
  command_sub_ =
      nh_.subscribe(names::kGimbalCommandTopic, 100, &AccelerometerNode::on_command, this);
  ROS_INFO(
      "accelerometer: %s source, %.1f Hz, noise %.3g m/s^2 per sample, orientation from %s "
      "(%s -> %s)",
      source_->name().c_str(), options_.simulated.rate_hz, options_.simulated.noise_std(),
      nh_.resolveName(names::kTfTopic).c_str(), options_.world_frame.c_str(),
      options_.frame_id.c_str());
}

AccelerometerNode::~AccelerometerNode() {
  // First: the serial reader thread publishes through this object's members.
  source_.reset();
}

void AccelerometerNode::on_tf(const tf2_msgs::TFMessage::ConstPtr& msg) {
  ros::Time newest;
  for (const geometry_msgs::TransformStamped& t : msg->transforms) {
    if (!latest_tf_.isZero() && t.header.stamp + ros::Duration(1.0) < latest_tf_) {
      // The clock went backwards (a restarted simulation): start over.
      ROS_WARN("accelerometer: tf time jumped back from %.3f to %.3f s; clearing the buffer",
               latest_tf_.toSec(), t.header.stamp.toSec());
      buffer_.clear();
      source_->restart();
      latest_tf_ = ros::Time();
      oldest_tf_ = ros::Time();
      have_origin_ = false;
    }
    buffer_.setTransform(t, "gimbal_controller", false);
    if (t.header.stamp > newest) newest = t.header.stamp;
  }
  if (!newest.isZero()) {
    if (oldest_tf_.isZero()) oldest_tf_ = newest;
    // A message carries the whole chain with one stamp.
    if (newest > latest_tf_) latest_tf_ = newest;
  }
}

void AccelerometerNode::on_command(const GimbalCommand::ConstPtr& msg) {
  if (!have_origin_ && simulated_ && !msg->header.stamp.isZero()) {
    simulated_->set_time_origin(msg->header.stamp.toSec());
    time_origin_s_ = msg->header.stamp.toSec();
    have_origin_ = true;
    if (options_.stall_after_s >= 0.0) {
      ROS_WARN("accelerometer: fault injection: no samples from %.3f s for %.3f s",
               time_origin_s_ + options_.stall_after_s, options_.stall_for_s);
    }
    if (options_.decimate_after_s >= 0.0 && options_.decimate > 1) {
      ROS_WARN("accelerometer: fault injection: one sample in %d from %.3f s", options_.decimate,
               time_origin_s_ + options_.decimate_after_s);
    }
  }
}

OrientationStatus AccelerometerNode::lookup(double t_s, Eigen::Matrix3d* R) {
  if (latest_tf_.isZero() || t_s > latest_tf_.toSec()) return OrientationStatus::NotYet;
  if (t_s < oldest_tf_.toSec()) return OrientationStatus::Never;
  try {
    const geometry_msgs::TransformStamped t =
        buffer_.lookupTransform(options_.world_frame, options_.frame_id, ros::Time(t_s));
    const Eigen::Quaterniond q(t.transform.rotation.w, t.transform.rotation.x,
                               t.transform.rotation.y, t.transform.rotation.z);
    *R = q.normalized().toRotationMatrix();
    return OrientationStatus::Available;
  } catch (const tf2::TransformException& e) {
    ROS_WARN_THROTTLE(5.0, "accelerometer: no orientation at %.4f s: %s", t_s, e.what());
    return OrientationStatus::Never;
  }
}

void AccelerometerNode::poll(const ros::Time& now) {
  batch_.clear();
  source_->poll(now.toSec(), &batch_);
  const double variance = source_->variance_per_axis();
  const bool faults = have_origin_ && (options_.stall_after_s >= 0.0 ||
                                       (options_.decimate_after_s >= 0.0 && options_.decimate > 1));
  for (const core::ImuSample& s : batch_) {
    if (faults) {
      const double t = s.stamp_s - time_origin_s_;
      if (options_.stall_after_s >= 0.0 && t >= options_.stall_after_s &&
          t < options_.stall_after_s + options_.stall_for_s) {
        ++fault_dropped_;
        continue;
      }
      if (options_.decimate_after_s >= 0.0 && options_.decimate > 1 &&
          t >= options_.decimate_after_s &&
          (decimate_counter_++ % static_cast<std::uint64_t>(options_.decimate)) != 0) {
        ++fault_dropped_;
        continue;
      }
    }
    imu_pub_.publish(to_msg(s, options_.frame_id, variance));
    ++published_;
  }
  if (!temperature_pub_) return;
  temperature_batch_.clear();
  source_->poll_temperatures(now.toSec(), &temperature_batch_);
  for (const core::TemperatureSample& reading : temperature_batch_) {
    sensor_msgs::Temperature msg;
    msg.header.stamp = ros::Time(reading.stamp_s);
    msg.header.frame_id = options_.frame_id;
    msg.temperature = reading.temperature_c;
    msg.variance = source_->temperature_variance();
    temperature_pub_.publish(msg);
  }
}

void AccelerometerNode::on_timer(const ros::TimerEvent&) {
  const ros::Time now = ros::Time::now();
  if (now.isZero()) return;
  if (!serial_) {
    poll(now);
    return;
  }
  // serial_lines: the reader thread publishes as it reads; here the port's news and diagnostics.
  const SerialLinesStatus status = serial_->status();
  log_serial_lines(serial_status_, status, options_.serial_lines);
  serial_status_ = status;
  updater_->update();
}

}  // namespace accel_intrinsics
