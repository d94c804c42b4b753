// An indexing head or tilt table turned by hand (docs/design.md section 15, driver `manual`).
//
// Each move asks the operator: the protocol waits in WAIT_OPERATOR with the target's stage
// positions (the axis map of serial_gimbal.h, deg) on gimbal_controller/progress until
// gimbal_controller/continue. Then the driver averages the IMU for check_s and compares the
// mean direction with the commanded pose's specific force (the stage kinematics of
// core/model/gimbal_kinematics.h): within pose_tolerance_deg it settles; otherwise it names the
// pose it sees (the phase and angle nearest to the measured direction) and asks again.
// The direction of R = S f + O is compared, not f: a device's misalignment, scale and offsets of
// a few percent move it by a few degrees at most, below the default 5 deg tolerance.
// ROS-free: the node passes the IMU's samples in (on_imu).
#pragma once

#include <Eigen/Core>
#include <string>

#include "accel_intrinsics/drivers/gimbal_driver.h"
#include "accel_intrinsics/drivers/serial_gimbal.h"

namespace accel_intrinsics {

struct ManualGimbalOptions {
  AxisMap axis_map;                 // what the operator sets, per phase
  double pose_tolerance_deg = 5.0;  // the IMU's direction within this of the pose, deg
  double check_s = 1.0;             // the IMU's mean over this after continue, s
  std::size_t min_samples = 5;      // at least this many IMU samples in the mean
  std::string imu_topic = "imu/data_raw";

  // Throws std::invalid_argument naming the field.
  void validate() const;
};

// The pose nearest to a measured direction of the specific force: the phase whose plane of
// eq. (4) it is closest to, and the angle in that plane.
struct PoseMatch {
  core::Phase phase = core::Phase::X;
  double alpha_rad = 0.0;      // in [0, 2 pi)
  double off_plane_rad = 0.0;  // the direction's angle from that phase's plane
};
// `prefer`: the phase chosen when two planes are equally near (their common directions).
PoseMatch nearest_pose(const Eigen::Vector3d& direction, core::Phase prefer);
// The angle between two directions, rad.
double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

class ManualGimbal : public GimbalDriver {
 public:
  explicit ManualGimbal(const ManualGimbalOptions& options);

  std::string name() const override { return "manual"; }
  GimbalDriverTopics topics() const override;
  void on_imu(double t_s, const Eigen::Vector3d& outputs) override;

  void move_to(const GimbalTarget& target, double t_s) override;
  bool settled(double /*t_s*/) const override { return settled_; }
  double settled_at(double t_s) const override { return settled_ ? settled_s_ : t_s; }
  void stop(double t_s) override;
  void update(double t_s) override;
  std::string status_text() const override;
  GimbalTransforms orientation(double t_s) const override;

  bool needs_operator(double /*t_s*/) const override { return waiting_; }
  void operator_continue(double t_s) override;
  std::string operator_request() const override;
  std::string operator_complaint() const override { return complaint_; }
  std::map<std::string, double> operator_targets_deg() const override;

 private:
  ManualGimbalOptions options_;
  GimbalTarget target_;
  bool first_of_phase_ = true;  // the request names the held axes too
  bool moved_ = false;
  bool waiting_ = false;   // for the operator
  bool checking_ = false;  // averaging the IMU
  bool settled_ = true;
  double settled_s_ = 0.0;
  double check_from_s_ = 0.0;
  Eigen::Vector3d sum_ = Eigen::Vector3d::Zero();
  std::size_t samples_ = 0;
  std::string complaint_;
};

}  // namespace accel_intrinsics
