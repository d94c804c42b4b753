#include "accel_intrinsics/ros/tumble_calibration_node.h"

#include <std_msgs/String.h>

#include <sstream>

#include "accel_intrinsics/io/tumble_progress.h"
#include "accel_intrinsics/ros/conversions.h"
#include "accel_intrinsics/ros/dwell_message.h"
#include "accel_intrinsics/ros/names.h"
#include "accel_intrinsics/ros/params.h"
#include "accel_intrinsics/ros/result_files.h"

namespace accel_intrinsics {

TumbleNodeOptions TumbleNodeOptions::load(const ros::NodeHandle& pnh) {
  TumbleNodeOptions o;
  o.common = CalibrationOptions::load(pnh);
  o.session.local_gravity = o.common.calibrate.fit.local_gravity;
  read_param(pnh, "rest_min_s", &o.session.rests.min_rest_s);
  read_param(pnh, "target_relative_std", &o.session.target_relative_std);
  read_param(pnh, "progress_period_s", &o.progress_period_s);
  try {
    core::validate(o.session);
  } catch (const std::invalid_argument& e) {
    throw ParamError(std::string("mode tumble: ") + e.what() + " (parameters " +
                     param_name(pnh, "rest_min_s") + ", " + param_name(pnh, "target_relative_std") +
                     ")");
  }
  if (!(o.progress_period_s > 0.0))
    throw ParamError("parameter " + param_name(pnh, "progress_period_s") + " must be > 0");
  return o;
}

TumbleCalibrationNode::TumbleCalibrationNode(ros::NodeHandle nh, ros::NodeHandle pnh,
                                             const TumbleNodeOptions& options)
    : nh_(nh),
      pnh_(pnh),
      options_(options),
      files_("", options.common.file_prefix),
      runs_(options.common.output_dir),
      session_(options.session) {
  progress_pub_ = nh_.advertise<std_msgs::String>(kTumbleProgressTopic, 1, true);
  result_pub_ = nh_.advertise<IntrinsicResult>(names::kResultTopic, 1, true);
  dwell_pub_ = advertise_dwells(nh_);
  get_srv_ = nh_.advertiseService(names::kGetIntrinsicsService,
                                  &TumbleCalibrationNode::on_get_intrinsics, this);
  reset_srv_ = nh_.advertiseService(names::kResetService, &TumbleCalibrationNode::on_reset, this);
  imu_sub_ = nh_.subscribe(names::kImuTopic, 2000, &TumbleCalibrationNode::handle_imu, this,
                           ros::TransportHints().tcpNoDelay());
  progress_timer_ = nh_.createWallTimer(ros::WallDuration(options_.progress_period_s),
                                        [this](const ros::WallTimerEvent&) {
                                          std::lock_guard<std::mutex> lock(mutex_);
                                          publish_progress();
                                        });
  publish_progress();
  ROS_INFO(
      "calibration: mode tumble: hold the device still in many orientations (rests of %.1f s "
      "or more), every axis up and down; progress on %s",
      options_.session.rests.min_rest_s, nh_.resolveName(kTumbleProgressTopic).c_str());
}

void TumbleCalibrationNode::handle_imu(const sensor_msgs::Imu& msg) {
  std::lock_guard<std::mutex> lock(mutex_);
  const core::ImuSample sample = to_core(msg);
  if (!session_.add_sample(sample.stamp_s, sample.outputs)) return;
  const core::TumbleProgress& p = session_.progress();
  ROS_INFO("calibration: %s", p.message.c_str());
  const std::vector<core::DwellRecord>& rests = session_.table().rows;
  for (; rests_published_ < rests.size(); ++rests_published_)
    dwell_pub_.publish(
        to_dwell_msg(rests[rests_published_], rests_published_, options_.common.frame_id));
  publish_progress();
  if (p.target_reached && !target_fitted_) {
    std::string message;
    target_fitted_ = fit_and_publish(&message);
    ROS_INFO("calibration: target_relative_std reached: %s", message.c_str());
  }
}

void TumbleCalibrationNode::publish_progress() {
  // still_s changes between rests: refresh it for the person waiting for "rest found".
  std_msgs::String out;
  core::TumbleProgress p = session_.progress();
  p.still_s = session_.detector().current_still_s();
  p.samples = session_.detector().samples();
  out.data = io::tumble_progress_json(p);
  progress_pub_.publish(out);
}

bool TumbleCalibrationNode::fit_and_publish(std::string* message) {
  core::CalibrationReport report;
  try {
    report = session_.report(options_.common.calibrate);
  } catch (const std::exception& e) {
    *message = e.what();
    return false;
  }
  result_ = to_msg(report.certificate);
  result_.quality_pass = report.quality.pass;
  result_.quality_reasons = report.quality.reasons;
  result_.header.stamp = ros::Time::now();
  result_.header.frame_id = options_.common.frame_id;
  result_pub_.publish(result_);
  have_result_ = true;
  io::ResultContext context;
  context.stamp_s = result_.header.stamp.toSec();
  context.certificate = options_.common.certificate;
  context.gravity_source = options_.common.gravity_source;
  std::string serial = options_.common.device_serial;
  pnh_.getParam("device_serial", serial);
  context.device_serial = serial;
  context.imu_topic = nh_.resolveName(names::kImuTopic);
  context.gimbal_driver = "none (hand tumble)";
  context.time_utc = io::utc_iso_time(ros::WallTime::now().toSec());
  if (new_run_pending_ && runs_.enabled()) {
    // The session's own directory; later fits of the same session replace its files.
    try {
      files_ = io::CheckpointFiles(runs_.start_run(serial, ros::WallTime::now().toSec()),
                                   options_.common.file_prefix);
      new_run_pending_ = false;
    } catch (const io::IoError& e) {
      ROS_ERROR("calibration: %s", e.what());
    }
  }
  core::RestDetection rests;
  rests.rests = session_.table().rows;
  rests.rejected = session_.detector().rejected();
  context.rest_detection = rests;
  context.rest_min_s = options_.session.rests.min_rest_s;
  if (files_.enabled()) {
    // The rests as a position table (phase '-': unknown orientations), beside the result.
    try {
      core::write_position_table_file(files_.table_path(), session_.table());
    } catch (const std::exception& e) {
      ROS_ERROR("calibration: %s", e.what());
    }
  }
  write_result_files(files_, options_.common.exports, report, context);
  if (files_.enabled())
    archive_result_file(options_.common.archive, options_.common.archive_device,
                        options_.common.archive_rig, files_.result_path(), files_.table_path());
  std::ostringstream s;
  s << "tumble fit of " << session_.table().rows.size() << " rests, reduced chi2 "
    << report.certificate.reduced_chi2 << ", g = " << report.certificate.local_gravity << " m/s^2";
  if (report.coverage && !report.coverage->complete())
    s << "; " << report.coverage->missing.front();
  if (!report.quality.pass) s << "; FAILS the quality gate: " << report.quality.summary();
  *message = s.str();
  return report.quality.pass;
}

bool TumbleCalibrationNode::on_get_intrinsics(GetIntrinsics::Request&,
                                              GetIntrinsics::Response& res) {
  std::lock_guard<std::mutex> lock(mutex_);
  const bool passed = fit_and_publish(&res.message);
  res.success = passed;
  if (have_result_) res.result = result_;
  if (!passed && !have_result_) {
    res.message = "no result yet: " + res.message + " (" + session_.progress().message + ")";
  }
  return true;
}

bool TumbleCalibrationNode::on_reset(std_srvs::Trigger::Request&,
                                     std_srvs::Trigger::Response& res) {
  std::lock_guard<std::mutex> lock(mutex_);
  const std::size_t rests = session_.table().rows.size();
  session_.reset();
  new_run_pending_ = true;  // the next result goes into a new run directory
  rests_published_ = 0;
  have_result_ = false;
  target_fitted_ = false;
  publish_progress();
  res.success = true;
  res.message = "reset: discarded " + std::to_string(rests) + " rests";
  return true;
}

}  // namespace accel_intrinsics
