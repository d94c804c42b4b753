// The calibration node: joins imu/data_raw samples to the dwells announced on gimbal/command
// (core::DwellAssembler, the same class offline_fit uses), checkpoints each completed dwell to
// the position table CSV, fits on DONE, publishes the latched calibration/result, writes the
// result YAML, and serves calibration/get_intrinsics and calibration/reset.
#pragma once

#include <ros/callback_queue_interface.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <std_srvs/Trigger.h>

#include <array>
#include <fstream>
#include <memory>
#include <mutex>
#include <string>

#include "accel_intrinsics/GetIntrinsics.h"
#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/IntrinsicResult.h"
#include "accel_intrinsics/core/dwell_assembler.h"
#include "accel_intrinsics/core/fit.h"

namespace accel_intrinsics {

// A callback queue that runs each callback at once, in the thread that adds it (roscpp's
// network thread). For the IMU stream it saves the queue hand-off and the wake-up of the spinner
// thread per message, which dominate the node's CPU use at 10 kHz.
class ImmediateCallbackQueue : public ros::CallbackQueueInterface {
 public:
  void addCallback(const ros::CallbackInterfacePtr& callback, uint64_t owner_id = 0) override;
  void removeByID(uint64_t owner_id) override;
};

struct CalibrationOptions {
  core::FitOptions fit;              // model (joint|eq4), local_gravity, min_positions_per_phase
  core::AssemblerOptions assembler;  // settle_discard_s, reorder_window_s
  double flush_period_s = 0.05;      // how often buffered messages are released, s
  double status_period_s = 1.0;      // calibration/status rate, s
  std::uint32_t steps = 0;       // expected N, for messages before the first command (0: unknown)
  std::string output_dir;        // position table and result YAML; empty = do not write
  std::string file_prefix;       // prefix of the file names in output_dir
  std::string frame_id = "dut";  // frame of the result header
  bool immediate_imu = true;     // handle IMU messages in the network thread (see above)

  // Reads the private parameters; throws ParamError naming the parameter.
  static CalibrationOptions load(const ros::NodeHandle& pnh);
};

class CalibrationNode {
 public:
  CalibrationNode(ros::NodeHandle nh, ros::NodeHandle pnh, const CalibrationOptions& options);
  // Stops the subscriptions and waits for a handler still running on the network thread.
  ~CalibrationNode();

  // Message handlers (the subscribers call them; tests and benchmarks may too).
  void handle_command(const GimbalCommand& msg);
  void handle_imu(const sensor_msgs::Imu& msg);
  // Releases buffered messages older than now - reorder window; fits after DONE + window.
  void update(const ros::Time& now);
  // Discards everything of the current run.
  void reset(const std::string& reason);

  // What get_intrinsics says while there is no result: the phases that lack dwells, and how many.
  std::string missing_message() const;
  bool has_result() const { return has_result_; }
  const core::DwellAssembler& assembler() const { return assembler_; }
  std::string csv_path() const;
  std::string yaml_path() const;

 private:
  void on_command(const GimbalCommand::ConstPtr& msg) { handle_command(*msg); }
  void on_imu(const sensor_msgs::Imu::ConstPtr& msg) { handle_imu(*msg); }
  void on_timer(const ros::TimerEvent&);
  bool on_get_intrinsics(GetIntrinsics::Request& req, GetIntrinsics::Response& res);
  bool on_reset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  void on_dwell(const core::DwellRecord& row);
  void run_fit(const ros::Time& now);
  void write_result_yaml(const core::FitResult& fit, const ros::Time& stamp);
  void publish_status(const ros::Time& now);
  void warn_on_new_drops();
  std::array<int, 3> dwells_per_phase() const;

  ros::NodeHandle nh_, pnh_;
  CalibrationOptions options_;
  // Serializes every handler: IMU messages may arrive on roscpp's network thread
  // (immediate_imu) while commands, the timer and the services run on the spinner thread.
  mutable std::recursive_mutex mutex_;
  ImmediateCallbackQueue immediate_queue_;
  core::DwellAssembler assembler_;
  ros::Subscriber command_sub_, imu_sub_;
  ros::Publisher result_pub_, status_pub_;
  ros::ServiceServer get_srv_, reset_srv_;
  ros::Timer timer_;

  std::ofstream csv_;
  bool done_pending_ = false;  // DONE received, waiting for the reorder window
  double done_stamp_s_ = 0.0;
  bool has_result_ = false;
  IntrinsicResult result_;
  std::string fit_error_;
  std::uint32_t steps_seen_ = 0;
  std::uint64_t commands_received_ = 0;
  std::uint64_t runs_ = 0;
  ros::Time last_status_;
  core::AssemblerCounters warned_;  // counters at the last warning
  std::uint64_t rejected_commands_ = 0;
};

}  // namespace accel_intrinsics
