// The calibration node: a thin ROS shell around core::CalibrationRun (the run's state machine:
// dwells, watchdogs, retries, resume) and core::calibrate (fit -> analysis -> timing lag).
//
// It turns gimbal/command, imu/data_raw and gimbal_controller/progress into the run's inputs and
// carries out the actions the run returns: checkpoint rows and state (io::CheckpointFiles in
// output_dir), fit (on a worker thread when the analysis runs, so IMU handling never waits),
// ask the gimbal controller to resume (ResumeAt) or abort (AbortRun), log. It publishes the
// latched calibration/result (the certificate: the base fit, or the refit with named effects
// when ~certificate_model is "refit"), calibration/analysis and calibration/status, writes
// intrinsics.yaml and analysis.json (io writers, the same keys as offline_fit's JSON), and
// serves calibration/get_intrinsics, calibration/reset and calibration/analyze.
#pragma once

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <std_srvs/Trigger.h>

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "accel_intrinsics/GetIntrinsics.h"
#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/IntrinsicResult.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/core/run/calibration_run.h"
#include "accel_intrinsics/io/checkpoint.h"
#include "accel_intrinsics/io/exporters.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/io/run_directory.h"
#include "accel_intrinsics/ros/immediate_callback_queue.h"
#include "accel_intrinsics/ros/message_batcher.h"

namespace accel_intrinsics {

struct CalibrationOptions {
  // The run: assembler (settle_discard_s, reorder_window_s), steps, imu_timeout_s,
  // min_samples_per_dwell, on_fault (retry_on_fault), max_retries; record_moves = analyze.
  core::RunOptions run;
  // The pipeline: model, local_gravity, min_positions_per_phase, analyze, analysis/*,
  // certificate_model (certificate_refit).
  core::CalibrateOptions calibrate;
  double flush_period_s = 0.05;  // how often the run is ticked (buffered messages released), s
  double status_period_s = 1.0;  // calibration/status rate, s
  // Base of the run directories: each run writes into output_dir/<device>/<UTC time>/ (its
  // checkpoint, result.json, intrinsics.yaml, analysis JSON; io/run_directory.h); empty = no files
  std::string output_dir;
  // The device's serial (~device_serial, default "unnamed"): the run directory's <device> and
  // the result's device_serial. Read again from the parameter server when a new run starts
  // (supervise --device sets it before the run).
  std::string device_serial = "unnamed";
  std::string file_prefix;                // prefix of the file names in output_dir
  std::vector<io::ExportFormat> exports;  // written into output_dir with each result
  // Lab archive URL (scripts/archive add after each result file; docs/design.md section 13); empty:
  // none. Serial and rig of the record when the budget file's certificate block has none.
  std::string archive;
  std::string archive_device;
  std::string archive_rig;
  std::string frame_id = "dut";   // frame of the result header
  bool immediate_imu = true;      // handle IMU messages in the network thread
  double imu_coalesce_s = 0.001;  // nap of the network thread woken from idle, s
  // Without immediate_imu: roscpp hands each IMU message (a pointer) to a batch of the node's
  // own, and a thread of its own handles every imu_batch_s what came meanwhile under one lock
  // (the nodelet's default: one wake-up per period; the node's work never runs in the
  // publisher's thread, which only appends the pointer); 0: the node handle's queue.
  double imu_batch_s = 0.005;
  bool resume = false;  // reload the checkpoint of output_dir at start
  std::string gimbal_controller = "gimbal_controller";  // the controller's node name (relative)
  // After DONE, wall time without a message or clock tick after which the run is fitted although
  // the reorder window has not passed in stamp time (a replay that ended at DONE).
  double idle_fit_after_s = 1.0;
  // budget_file (io/budget_file.h): its spec goes to calibrate.budget, its certificate block and
  // the source of g to the result document.
  std::vector<std::pair<std::string, std::string>> certificate;
  std::string gravity_source;

  // Reads the private parameters; throws ParamError naming the parameter.
  static CalibrationOptions load(const ros::NodeHandle& pnh);
};

class CalibrationNode {
 public:
  CalibrationNode(ros::NodeHandle nh, ros::NodeHandle pnh, const CalibrationOptions& options);
  // Stops the subscriptions and joins the fit worker (a running fit is finished and discarded).
  ~CalibrationNode();

  // Message handlers (the subscribers call them; tests and benchmarks may too).
  void handle_command(const GimbalCommand& msg);
  void handle_imu(const sensor_msgs::Imu& msg);
  // A reading of a per-dwell channel (core::kChannels, e.g. the DUT's temperature on
  // imu/temperature; optional): each dwell records the aggregate of its readings.
  void handle_channel_sample(const core::ChannelSample& reading);
  // Ticks the run; returns the controller requests due (carried out by on_timer, unlocked).
  std::vector<core::RunAction> update(const ros::Time& now);

 private:
  void on_command(const GimbalCommand::ConstPtr& msg) { handle_command(*msg); }
  void on_imu(const sensor_msgs::Imu::ConstPtr& msg) { handle_imu(*msg); }
  void on_imu_batched(const sensor_msgs::Imu::ConstPtr& msg);  // hands it to imu_batcher_
  void handle_imu_locked(const sensor_msgs::Imu& msg);         // handle_imu under mutex_
  void on_progress(const diagnostic_msgs::DiagnosticStatus::ConstPtr& msg);
  void on_timer(const ros::TimerEvent&);
  // Wall-time watch of a stream that stopped after DONE (see idle_fit_after_s).
  void on_wall_timer(const ros::WallTimerEvent&);
  void note_activity();  // a message came (under the lock)
  bool on_get_intrinsics(GetIntrinsics::Request& req, GetIntrinsics::Response& res);
  bool on_reset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool on_analyze(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);

  // Under the lock: carries out the run's actions; controller requests go to `requests` (they
  // are sent without the lock: the reply is read by the network thread, which may be waiting
  // for the lock in handle_imu).
  void carry_out(const core::RunActions& actions, std::vector<core::RunAction>* requests);
  void call_controller(const core::RunAction& request);
  // Fit of a FitNow: a report to publish, or the fit's error. Under the lock.
  void finish_fit(std::uint64_t ticket, const core::CalibrationReport* report,
                  const core::AssemblerCounters& counters, const std::string& error,
                  const ros::Time& stamp);
  // The certificate and the analysis out: message, topics, files. Under the lock.
  // `counters`: the run's sample counters when it was handed to the fit.
  void publish_certificate(const core::CalibrationReport& report,
                           const core::AssemblerCounters& counters, const ros::Time& stamp);
  // Returns the one-line summary (logged, and the analyze service's answer).
  std::string publish_analysis(const core::CalibrationReport& report, const ros::Time& stamp);
  void publish_status(const ros::Time& now);
  void diagnose_imu(diagnostic_updater::DiagnosticStatusWrapper& status);
  void diagnose_run(diagnostic_updater::DiagnosticStatusWrapper& status);

  // Fit worker: with the analysis on, FitNow hands it the table; it runs core::calibrate
  // without the lock, then finishes under the lock (the run discards a superseded ticket).
  struct FitJob {
    std::uint64_t ticket = 0;
    core::PositionTable table;
    core::RawStreams moves;
    core::AssemblerCounters counters;
    ros::Time stamp;
    std::optional<core::NoiseModel> noise_model;  // of the run's long rest; none: white
  };
  void fit_loop();

  ros::NodeHandle nh_, pnh_;
  CalibrationOptions options_;
  // Serializes every handler: IMU messages may arrive on roscpp's network thread
  // (immediate_imu) while commands, the timer and the services run on the spinner thread.
  mutable std::recursive_mutex mutex_;
  ImmediateCallbackQueue immediate_queue_;
  // roscpp's queue of the IMU subscription, and the bound of the IMU thread's batch.
  static constexpr std::size_t kImuQueueSize = 20000;
  // The IMU messages on their way to the IMU thread (immediate_imu false, imu_batch_s > 0).
  std::unique_ptr<MessageBatcher<sensor_msgs::Imu>> imu_batcher_;
  core::CalibrationRun run_;
  io::CheckpointFiles files_;  // in the current run's directory
  io::RunDirectories runs_;    // output_dir/<device>/<UTC time>/
  // A new run (start, reset) writes into a new directory, made at its first write.
  bool new_run_pending_ = false;
  std::string device_serial_;  // of the current run's directory
  // The current run is a mount check (~mount_check true when it would open its directory, set by
  // supervise --check-mount): it writes nothing and leaves `latest` alone, until the next run.
  bool mount_check_run_ = false;
  ros::Publisher run_directory_pub_;  // names::kRunDirectoryTopic
  // Makes the new run's directory when one is pending (files_ then writes there).
  void ensure_run_directory();
  io::ResultContext result_context(const ros::Time& stamp) const;
  ros::Subscriber command_sub_, imu_sub_, progress_sub_;
  std::vector<ros::Subscriber> channel_subs_;  // one per core::kChannels row
  ros::Publisher result_pub_, status_pub_, analysis_pub_;
  ros::Publisher dwell_pub_;  // calibration/dwell: each accepted row (ros/dwell_message.h)
  ros::ServiceServer get_srv_, reset_srv_, analyze_srv_;
  ros::Timer timer_;
  ros::WallTimer wall_timer_;
  ros::WallTime last_activity_;  // wall time of the last message or clock change
  ros::Time last_clock_;         // ros::Time::now() at the last wall tick
  std::unique_ptr<diagnostic_updater::Updater> updater_;

  IntrinsicResult result_;            // the latest certificate
  std::uint64_t resets_ = 0;          // a reset discards analyses started before it
  std::uint64_t fits_published_ = 0;  // ... and so does a newer fit
  bool shutting_down_ = false;        // the destructor runs: fits are discarded
  ros::Time last_status_;
  core::RunState last_state_ = core::RunState::Idle;
  // IMU rate for the diagnostics.
  std::uint64_t imu_received_ = 0, rate_count_ = 0;
  double rate_first_stamp_s_ = 0.0, rate_last_stamp_s_ = 0.0;

  std::mutex job_mutex_;  // job_, stop_worker_ (taken after mutex_, never before)
  std::condition_variable job_cv_;
  std::optional<FitJob> job_;
  bool stop_worker_ = false;
  std::thread fit_thread_;  // started last in the constructor
};

}  // namespace accel_intrinsics
