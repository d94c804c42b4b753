// The calibration node in mode: tumble (docs/design.md section 11): no gimbal controller. A thin
// shell around core::TumbleSession: imu/data_raw in; rests found as they end; after each rest (and
// once a second) the progress on calibration/tumble_progress (std_msgs/String, latched, the JSON of
// io::tumble_progress_json: rests, coverage, current relative uncertainties, the next pose in
// words); the fit on calibration/get_intrinsics or when ~target_relative_std is reached, published
// on the latched calibration/result and written to output_dir (intrinsics.yaml, exports) as the
// gimbal node does. calibration/reset forgets the rests.
#pragma once

#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <std_srvs/Trigger.h>

#include <mutex>
#include <string>

#include "accel_intrinsics/GetIntrinsics.h"
#include "accel_intrinsics/IntrinsicResult.h"
#include "accel_intrinsics/core/run/tumble_session.h"
#include "accel_intrinsics/io/checkpoint.h"
#include "accel_intrinsics/io/run_directory.h"
#include "accel_intrinsics/ros/calibration_node.h"

namespace accel_intrinsics {

constexpr char kTumbleProgressTopic[] = "calibration/tumble_progress";

struct TumbleNodeOptions {
  CalibrationOptions common;  // local_gravity, output_unit, output_dir, exports, quality, budget
  core::TumbleSessionOptions session;  // ~rest_min_s, ~target_relative_std
  double progress_period_s = 1.0;

  // Reads the private parameters; throws ParamError naming the parameter.
  static TumbleNodeOptions load(const ros::NodeHandle& pnh);
};

class TumbleCalibrationNode {
 public:
  TumbleCalibrationNode(ros::NodeHandle nh, ros::NodeHandle pnh, const TumbleNodeOptions& options);

  void handle_imu(const sensor_msgs::Imu& msg);

 private:
  bool on_get_intrinsics(GetIntrinsics::Request& req, GetIntrinsics::Response& res);
  bool on_reset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  void publish_progress();
  // Fits the rests so far; false with the reason in *message when it cannot.
  bool fit_and_publish(std::string* message);

  ros::NodeHandle nh_, pnh_;
  TumbleNodeOptions options_;
  io::CheckpointFiles files_;  // in the session's run directory (made at its first result)
  io::RunDirectories runs_;    // output_dir/<device>/<UTC time>/
  bool new_run_pending_ = true;
  std::mutex mutex_;
  core::TumbleSession session_;
  bool have_result_ = false;
  bool target_fitted_ = false;
  IntrinsicResult result_;
  ros::Subscriber imu_sub_;
  ros::Publisher progress_pub_, result_pub_;
  ros::Publisher dwell_pub_;         // calibration/dwell: each rest found
  std::size_t rests_published_ = 0;  // rows of session_.table() published on it
  ros::ServiceServer get_srv_, reset_srv_;
  ros::WallTimer progress_timer_;
};

}  // namespace accel_intrinsics
