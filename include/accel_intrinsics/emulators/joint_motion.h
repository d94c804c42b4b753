// One joint of an emulated ros_control position controller on a servo (joint_controller_emulator,
// the emulator of the ros_joint driver). ROS-free.
//
// The joint approaches its commanded position as a damped second-order system,
//   x'' = wn^2 (x_cmd - x) - 2 zeta wn x',   wn = 2 pi natural_frequency_hz,
// with its speed limited to max_speed_deg_s (the servo's profile velocity): a large move runs at
// that speed and ends in the second-order approach. With zeta < 1 a small step overshoots by
// exp(-pi zeta / sqrt(1 - zeta^2)) of its size (4.6 % at zeta = 0.7), then rings down.
// Time passes by advance(dt_s), integrated (semi-implicit Euler) in steps of at most max_step_s.
#pragma once

namespace accel_intrinsics {

struct JointMotionOptions {
  double natural_frequency_hz = 2.0;  // wn / (2 pi), Hz
  double damping_ratio = 0.7;         // zeta, in (0, 2]; < 1 overshoots
  double max_speed_deg_s = 90.0;      // speed limit, deg/s
  double max_step_s = 0.001;          // integration step, s

  // Throws std::invalid_argument naming the field.
  void validate() const;
  // The overshoot of a small step (speed limit not reached), as a share of the step: 0 when
  // damping_ratio >= 1.
  double small_step_overshoot() const;
};

class JointMotion {
 public:
  explicit JointMotion(const JointMotionOptions& options, double position_rad = 0.0);

  // A new position command (rad); the joint starts toward it at the next advance().
  void command(double position_rad) { command_rad_ = position_rad; }
  // Lets dt_s seconds pass (dt_s <= 0: nothing happens).
  void advance(double dt_s);

  double position_rad() const { return position_rad_; }
  double velocity_rad_s() const { return velocity_rad_s_; }
  double command_rad() const { return command_rad_; }

 private:
  void step(double dt_s);

  JointMotionOptions options_;
  double wn_rad_s_ = 0.0;
  double max_speed_rad_s_ = 0.0;
  double position_rad_ = 0.0;
  double velocity_rad_s_ = 0.0;
  double command_rad_ = 0.0;
};

}  // namespace accel_intrinsics
