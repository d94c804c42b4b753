// A gimbal whose axes are ROS joints (docs/design.md section 15, driver `ros_joint`): the
// convention of ros_control's JointPositionController (Dynamixel and most motorised pan-tilt
// units): one std_msgs/Float64 position command per axis (rad) and sensor_msgs/JointState
// feedback (positions in rad).
//
// The axis map is the one of the serial gimbals (serial_gimbal.h AxisMap; axis letters are the
// keys of `axes`): stage position = zero_deg + sign * alpha (deg), the other axes held.
// Arrival: every mapped joint within tolerance_deg of its target, continuously for settle_s (node
// clock). Faults (GimbalFault, naming the joint): no JointState for a mapped joint for
// joint_state_timeout_s, or no arrival within move_timeout_s of the move.
// ROS-free: the node passes JointState positions in (on_joint_state) and publishes the commands
// it is handed (GimbalLinks); the tf pose is the reported joints through the stage kinematics.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "accel_intrinsics/drivers/gimbal_driver.h"
#include "accel_intrinsics/drivers/serial_gimbal.h"

namespace accel_intrinsics {

struct RosJointAxis {
  std::string joint;          // the joint's name in JointState
  std::string command_topic;  // std_msgs/Float64, rad
};

struct RosJointOptions {
  std::string joint_states_topic = "joint_states";
  std::map<std::string, RosJointAxis> axes;  // axis letter -> joint
  double tolerance_deg = 0.05;               // arrival: every mapped joint within this, deg
  double settle_s = 0.5;                     // within tolerance this long, s (node clock)
  double move_timeout_s = 30.0;              // no arrival by then: fault, s
  double joint_state_timeout_s = 2.0;        // a mapped joint silent this long: fault, s
  AxisMap axis_map;

  // Throws std::invalid_argument naming the field.
  void validate() const;
};

class RosJointGimbal : public GimbalDriver {
 public:
  explicit RosJointGimbal(const RosJointOptions& options);

  std::string name() const override { return "ros_joint"; }
  GimbalDriverTopics topics() const override;
  void connect(GimbalLinks* links) override { links_ = links; }
  void on_joint_state(double t_s, const std::vector<std::string>& names,
                      const std::vector<double>& positions_rad) override;

  void move_to(const GimbalTarget& target, double t_s) override;
  bool settled(double t_s) const override;
  double settled_at(double t_s) const override;
  void stop(double t_s) override;
  void update(double t_s) override;
  void recover(double t_s) override;
  bool manual_remount(core::Phase phase) const override;
  std::string status_text() const override;
  GimbalTransforms orientation(double t_s) const override;

 private:
  struct Joint {
    RosJointAxis axis;
    bool seen = false;
    double position_deg = 0.0;
    double seen_s = 0.0;
  };
  void command(const std::map<std::string, double>& positions_deg);
  std::string describe(const std::string& axis) const;

  RosJointOptions options_;
  GimbalLinks* links_ = nullptr;
  std::map<std::string, Joint> joints_;  // mapped axes only
  GimbalTarget target_;
  std::map<std::string, double> target_deg_;
  bool moving_ = false;
  double move_start_s_ = 0.0;
  double within_since_s_ = -1.0;
  double settled_s_ = 0.0;
  double watch_since_s_ = -1.0;  // the silence clock starts at the first update (or recover)
};

}  // namespace accel_intrinsics
