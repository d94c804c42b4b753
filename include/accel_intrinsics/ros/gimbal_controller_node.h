// The gimbal controller node: runs the protocol of build_schedule() (core::GimbalProtocol, the
// state machine) over a GimbalDriver, publishes gimbal/command at each state change (MOVING,
// SETTLED, DONE), broadcasts the true DUT orientation on tf (world -> gimbal -> dut), offers
// gimbal_controller/start, gimbal_controller/abort and gimbal_controller/resume, and reports
// progress (gimbal_controller/progress and diagnostic_updater on /diagnostics).
//
// Resume: the first run can begin at any position of the schedule (~resume_phase, ~resume_step,
// ~resume_approach at start-up: the next start or autostart begins there), and a running,
// finished or aborted protocol can be moved to one: gimbal_controller/resume (srv/ResumeAt.srv:
// phase, step, approach, after = the position after that one, reason) answers with the stamp of
// the MOVING (or DONE) it published. gimbal_controller/abort (std_srvs/Trigger, as start) aborts
// by hand; gimbal_controller/abort_run (srv/AbortRun.srv) aborts with a reason.
//
// Hardware (docs/design.md sections 10 and 15): ~driver picks a row of the gimbal driver table
// (drivers/gimbal_driver_table.h: simulated, grbl, smc100, ros_joint, manual), configured under
// ~<driver>/... (for the serial ones port, timeouts, settling, homing; for every hardware one the
// per-phase axis map ~<driver>/phases/{x,y,z}: axis, sign, zero_deg, hold, manual_remount). A
// fault of the device aborts the run with the device's words. A driver that talks over ROS
// topics names them (GimbalDriver::topics()): the node subscribes JointState (ros_joint) or the
// IMU (manual) for it and publishes its Float64 joint commands. The manual driver waits for the
// operator at each position in WAIT_OPERATOR (progress carries the request and the target's
// stage positions, stage_<axis>_deg) until gimbal_controller/continue. Before a phase that needs a
// manual remount the controller publishes MOVING for the phase's first position (closing the last
// dwell), turns the stage to that position, and waits in state REMOUNT (progress topic) until
// gimbal_controller/continue (std_srvs/Trigger); then the move is issued again and settles.
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <tf2_msgs/TFMessage.h>

#include <any>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "accel_intrinsics/AbortRun.h"
#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/ResumeAt.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/core/run/gimbal_protocol.h"
#include "accel_intrinsics/drivers/gimbal_driver.h"
#include "accel_intrinsics/drivers/serial_gimbal.h"

namespace accel_intrinsics {

struct GimbalControllerOptions {
  // steps, move_s, settle_s, dwell_s, phase_change_s, two_way, closing_position
  core::ProtocolOptions protocol;
  bool autostart = false;            // start the protocol without a start call
  double start_delay_s = 1.0;        // from start (or autostart) to the first MOVING, s
  double tick_hz = 100.0;            // state machine and tf rate on the node clock, Hz
  double progress_hz = 1.0;          // progress topic and log rate, Hz
  double settle_timeout_s = 60.0;    // abort when a move has not settled in this time, s
  std::string resume_phase;          // "" (from the start) or x|y|z: first position of a run
  std::uint32_t resume_step = 0;     // 0..N-1, or N: the closing position (closing_position)
  int resume_approach = +1;          // +1: the up sweep, -1: the return sweep (two_way)
  std::string driver = "simulated";  // a row of gimbal_driver_table()
  std::any driver_options;           // what the row's reader made of ~<driver>/...
  std::string world_frame = "world";
  std::string gimbal_frame = "gimbal";
  std::string dut_frame = "dut";

  // Reads the private parameters (src/ros/gimbal_controller_options.cpp); throws ParamError
  // naming the parameter.
  static GimbalControllerOptions load(const ros::NodeHandle& pnh);
};

// The tf message the controller broadcasts: world -> gimbal and gimbal -> dut at one stamp.
tf2_msgs::TFMessage make_tf_message(const GimbalTransforms& transforms, const ros::Time& stamp,
                                    const std::string& world_frame, const std::string& gimbal_frame,
                                    const std::string& dut_frame);

// The backend named by options.driver (its row of gimbal_driver_table()); throws ParamError for
// an unknown name or a device that does not start.
std::unique_ptr<GimbalDriver> make_gimbal_driver(const GimbalControllerOptions& options);

// The shell around core::GimbalProtocol (the state machine, core/gimbal_protocol.h): parameters,
// the timer, the services, gimbal/command, tf, progress and diagnostics.
class GimbalControllerNode : public GimbalLinks {
 public:
  using State = core::ProtocolState;

  GimbalControllerNode(ros::NodeHandle nh, ros::NodeHandle pnh,
                       const GimbalControllerOptions& options,
                       std::unique_ptr<GimbalDriver> driver);

  // One step of the protocol at time `now` (the timer calls it; tests may too).
  void tick(const ros::Time& now);
  // Begins a run (what the start service does); false with a reason when one is running.
  bool start(const ros::Time& now, std::string* message);
  // Stops a run (what the abort service does); publishes DONE to close the open dwell.
  bool abort(const ros::Time& now, const std::string& reason, std::string* message);
  // Ends a manual remount (what the continue service does). False with a reason when not in
  // REMOUNT.
  bool continue_after_remount(const ros::Time& now, std::string* message);
  // Moves to schedule position `index` now and continues the protocol from there, from any
  // state; index == size publishes DONE. Fills message (ends with "stamp=<t>").
  bool resume(const ros::Time& now, std::size_t index, const std::string& reason,
              std::string* message);
  // Schedule index of (phase, step, approach); size() if none. `after`: the one after it.
  std::size_t find_position(core::Phase phase, std::uint32_t step, int approach, bool after) const {
    return protocol_->find_position(phase, step, approach, after);
  }

  State state() const { return protocol_->state(); }
  // GimbalLinks: a joint command of the driver.
  void publish_command(const std::string& topic, double position_rad) override;
  static const char* state_name(State state) { return core::protocol_state_name(state); }

 private:
  void on_timer(const ros::TimerEvent& event);
  bool on_start(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool on_abort(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool on_abort_run(AbortRun::Request& req, AbortRun::Response& res);
  bool on_continue(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool on_resume(ResumeAt::Request& req, ResumeAt::Response& res);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);
  // Publishes, logs and reports what the protocol asked for, at `now`.
  void carry_out(const core::ProtocolActions& actions, const ros::Time& now);
  bool reply(const core::ProtocolReply& r, const ros::Time& now, std::string* message);
  void publish_tf(const ros::Time& now);
  void publish_progress(const ros::Time& now, const core::ProtocolStatus& status, bool log);
  // Subscriptions and publishers of a driver that talks over ROS topics.
  void wire_driver_topics();

  ros::NodeHandle nh_, pnh_;
  GimbalControllerOptions options_;
  std::unique_ptr<GimbalDriver> driver_;
  std::unique_ptr<core::GimbalProtocol> protocol_;
  ros::Publisher command_pub_, tf_pub_, progress_pub_;
  std::map<std::string, ros::Publisher> joint_command_pubs_;
  // JointState messages wait here and go to the driver at each tick (the driver reads them only
  // in update()): no wake-up of the spinner per message from a 1 kHz joint_state_controller.
  ros::CallbackQueue joint_state_queue_;
  ros::Subscriber joint_state_sub_, imu_sub_;
  ros::ServiceServer start_srv_, abort_srv_, abort_run_srv_, resume_srv_, continue_srv_;
  ros::Timer timer_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::Time last_tf_;
};

}  // namespace accel_intrinsics
