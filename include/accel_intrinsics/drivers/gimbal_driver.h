// The gimbal behind an interface (hardware behind an interface, injected): the
// controller node drives any GimbalDriver; SimulatedGimbalDriver is the default backend.
//
// Frames (REP 103, z up in world): world -> gimbal -> dut, the stage kinematics of
// core/model/gimbal_kinematics.h (R_world_dut = Rx(X) Rz(Y), docs/design.md section 15):
//   world -> gimbal: the outer stage axis X (along world x; raised by the axis tilt of the
//                    simulated gimbal), turned by X.
//   gimbal -> dut:   the inner stage axis Y, turned by Y.
// With the default axis map the specific force in the DUT frame, R_world_dut^T (0, 0, g), is
// docs/design.md eq. (4) at the TRUE angle: x: g(0, sin a, cos a), y: g(sin a, 0, cos a),
// z: g(sin a, cos a, 0), with the tilt applied as in model.h (test/ros_unit/gimbal_tf_test.cpp,
// test/core/model/stage_kinematics_test.cpp).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "accel_intrinsics/core/model/effects.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/core/run/gimbal_protocol.h"

namespace accel_intrinsics {

// The two rotations broadcast on tf (translations are zero).
struct GimbalTransforms {
  Eigen::Quaterniond world_gimbal = Eigen::Quaterniond::Identity();
  Eigen::Quaterniond gimbal_dut = Eigen::Quaterniond::Identity();
  // R_world_dut: maps DUT-frame vectors to world-frame vectors.
  Eigen::Matrix3d world_dut() const {
    return (world_gimbal * gimbal_dut).normalized().toRotationMatrix();
  }
};

// The tf chain for a DUT turned about its own `phase` axis to the TRUE angle alpha, with the
// rotation axis raised by tilt_rad from horizontal (core::phase_pose, the stage kinematics).
GimbalTransforms gimbal_transforms(core::Phase phase, double true_angle_rad, double tilt_rad);
// The tf chain of a pose R_world_dut, split at the inner stage axis of `phase` at alpha.
GimbalTransforms split_at_inner_axis(const Eigen::Matrix3d& world_dut, core::Phase phase,
                                     double alpha_rad);

// The target, the fault and the protocol's part of the interface are declared in the core, which
// cannot include this header (core/gimbal_protocol.h says why); here they keep their names.
using core::GimbalFault;
using core::GimbalTarget;
using core::target_of;

// ROS topics a driver talks over (ros_joint, manual); the node wires them (names relative to the
// controller's namespace). Serial and simulated drivers use none.
struct GimbalDriverTopics {
  std::string joint_states;                 // sensor_msgs/JointState in ("" none)
  std::vector<std::string> command_topics;  // std_msgs/Float64 out, rad
  std::string imu;                          // sensor_msgs/Imu in ("" none)
};
// What the node carries out for such a driver.
class GimbalLinks {
 public:
  virtual ~GimbalLinks() = default;
  // Publishes a joint position command (rad) on one of topics().command_topics.
  virtual void publish_command(const std::string& topic, double position_rad) = 0;
};

// A gimbal the controller drives: what the protocol needs (core::GimbalMotion: name, move_to,
// settled, settled_at, stop, update, manual_remount, recover, status_text, the operator calls)
// and the DUT's true orientation for tf; a driver that talks over ROS topics names them and
// takes what arrives as plain calls (the node converts the messages), so it stays ROS-free.
class GimbalDriver : public core::GimbalMotion {
 public:
  // True orientation of the DUT at t_s (encoders on hardware; the model in simulation).
  virtual GimbalTransforms orientation(double t_s) const = 0;
  virtual GimbalDriverTopics topics() const { return {}; }
  // The node's links, before the first move; `links` outlives the driver's use of it.
  virtual void connect(GimbalLinks* /*links*/) {}
  // A sensor_msgs/JointState received at t_s (node clock): names and positions (rad).
  virtual void on_joint_state(double /*t_s*/, const std::vector<std::string>& /*names*/,
                              const std::vector<double>& /*positions_rad*/) {}
  // A sensor_msgs/Imu received at t_s: linear_acceleration (R_u, R_v, R_w).
  virtual void on_imu(double /*t_s*/, const Eigen::Vector3d& /*outputs*/) {}
};

// The simulated gimbal. Its effects are the gimbal side of docs/design.md section 3 and are read
// from the gimbal controller's own configuration; the calibration side never sees them. A move
// within a phase follows core::move_fraction() (simulator.h) from the MOVING time to the settled
// time, move_s + settle_s later: the commanded angle of the simulator and of the timing-lag
// estimator, so a recorded stand run is evaluated with the motion that made it. A phase change
// (remount) is a rotation over phase_change_s, then settle_s at rest. The times are those of
// core::build_schedule() for the same move_s, phase_change_s and settle_s.
struct SimulatedGimbalOptions {
  double move_s = 1.0;          // duration of a move to the next position, s
  double phase_change_s = 5.0;  // duration of a move that changes phase (remount), s
  double settle_s = 0.5;        // from the end of the drive's motion until settled, s
  double ringing_rad = 0.0;     // amplitude of an oscillation about the rotation axis that starts
                                // move_s (phase_change_s) after MOVING, rad; it decays with
                                // time constant settle_s / 5 (a disturbance outside the model)
  double ringing_hz = 4.0;      // its frequency, Hz
  // angle_offset, angle_scale, axis_tilt, backlash; at most one of each kind per phase.
  std::vector<core::Effect> effects;
  // Fault injection: a move to (never_settle_phase, never_settle_at_step) never settles (the
  // gimbal keeps hunting around the target). never_settle_at_step < 0: off.
  std::string never_settle_phase = "x";
  int never_settle_at_step = -1;

  // Throws std::invalid_argument naming the field.
  void validate() const;
};

class SimulatedGimbalDriver : public GimbalDriver {
 public:
  explicit SimulatedGimbalDriver(const SimulatedGimbalOptions& options);

  std::string name() const override { return "simulated"; }
  void move_to(const GimbalTarget& target, double t_s) override;
  bool settled(double t_s) const override;
  double settled_at(double t_s) const override;
  void stop(double t_s) override;
  GimbalTransforms orientation(double t_s) const override;

  // True DUT angle and tilt for a target under the configured gimbal effects (model.h).
  double true_angle(const GimbalTarget& target) const;
  double tilt(core::Phase phase) const;

 private:
  Eigen::Quaterniond pose_of(const GimbalTarget& target) const;  // R_world_dut
  // Commanded angle alpha at t_s: along the move within a phase, else the target's.
  double commanded_angle(double t_s) const;

  SimulatedGimbalOptions options_;
  std::vector<double> values_;
  GimbalTarget target_;
  Eigen::Quaterniond from_ = Eigen::Quaterniond::Identity();  // R_world_dut at the move start
  Eigen::Quaterniond to_ = Eigen::Quaterniond::Identity();    // R_world_dut at the target
  double from_angle_ = 0.0;                                   // commanded angle at the move start
  double stopped_angle_ = 0.0;  // commanded angle where an abort stopped the gimbal
  double move_start_s_ = 0.0;   // MOVING
  double motion_end_s_ = 0.0;   // the drive is done; ringing starts
  double settled_s_ = 0.0;      // settled
  bool in_phase_move_ = false;  // the move follows core::move_fraction (not a remount)
  bool on_path_ = true;         // at an angle of the current phase (not stopped mid-remount)
  bool moved_ = false;
  bool stopped_ = false;  // stopped by an abort: at rest, no ringing
};

}  // namespace accel_intrinsics
