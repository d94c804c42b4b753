// The calibration node: joins imu/data_raw samples to the dwells announced on gimbal/command
// (core::DwellAssembler, the same class offline_fit uses), checkpoints each completed dwell to
// the position table CSV, fits on DONE, publishes the latched calibration/result, writes the
// result YAML, and serves calibration/get_intrinsics and calibration/reset.
//
// Beyond that (issues 5 and 6):
//  - analysis: with ~analyze (or the calibration/analyze service) core::analyze() runs after
//    the fit; the JSON goes to the latched calibration/analysis (std_msgs/String) and to
//    analysis.json. The certificate (calibration/result) stays the base fit unless
//    ~certificate_model is "refit"; its `model` field always names the model it holds.
//    After a fit the analysis runs on a worker thread, off the node's lock (IMU handling never
//    waits for it); the result (certificate, YAML, state) goes out when it finishes. A reset
//    meanwhile discards it (generation counter).
//  - resume: the node's own position table (rows accepted so far, in protocol order) and a small
//    state file (time origin, N, done, fault) are checkpointed in output_dir; with ~resume a
//    restarted node reloads them and asks the gimbal controller to continue after the last
//    checkpointed dwell (gimbal_controller/resume), discarding whatever it measured meanwhile.
//  - watchdogs: no IMU samples for ~imu_timeout_s during a dwell, a dwell with fewer than
//    ~min_samples_per_dwell samples: per ~on_fault the position is measured again (the gimbal
//    controller is rewound to it; at most ~max_retries times per position) or the run is aborted
//    (gimbal_controller/abort); get_intrinsics then says why.
//  - diagnostics: diagnostic_updater status on /diagnostics (IMU rate, dropped samples by reason,
//    current dwell, faults).
#pragma once

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <ros/callback_queue_interface.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <std_srvs/Trigger.h>

#include <diagnostic_updater/diagnostic_updater.h>

#include <array>
#include <chrono>
#include <condition_variable>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "accel_intrinsics/GetIntrinsics.h"
#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/IntrinsicResult.h"
#include "accel_intrinsics/ResumeAt.h"
#include "accel_intrinsics/core/discrepancy.h"
#include "accel_intrinsics/core/dwell_assembler.h"
#include "accel_intrinsics/core/fit.h"
#include "accel_intrinsics/core/raw_stream_analysis.h"

namespace accel_intrinsics {

// A callback queue that runs each callback at once, in the thread that adds it (roscpp's
// network thread). For the IMU stream it saves the queue hand-off and the wake-up of the spinner
// thread per message, which dominate the node's CPU use at 10 kHz.
class ImmediateCallbackQueue : public ros::CallbackQueueInterface {
 public:
  void addCallback(const ros::CallbackInterfacePtr& callback, uint64_t owner_id = 0) override;
  void removeByID(uint64_t owner_id) override;
  // Coalesce network wake-ups: when a message arrives after the thread was idle, nap for this
  // long so that the following messages pile up in the socket and are read in one go. 0: off.
  void set_coalesce_period(double seconds) { coalesce_s_ = seconds; }

 private:
  double coalesce_s_ = 0.0;
  std::chrono::steady_clock::time_point last_return_{};
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
  double imu_coalesce_s = 0.001;   // nap of the network thread woken from idle (see above), s

  // Analysis (issue 5).
  bool analyze = false;                 // run core::analyze() after each fit
  core::AnalysisOptions analysis;       // ~analysis/alpha, max_effects, monte_carlo_draws, seed
  bool certificate_refit = false;       // ~certificate_model: base (false) | refit (true)

  // Resume and watchdogs (issue 6).
  bool resume = false;                  // reload the checkpoint of output_dir at start
  double imu_timeout_s = 0.0;           // no samples this long during a dwell: fault (0 = off)
  std::uint32_t min_samples_per_dwell = 0;  // fewer samples in a dwell: fault (0 = off)
  bool retry_on_fault = false;          // ~on_fault: abort (false) | retry (true)
  std::uint32_t max_retries = 2;        // retries of one position before aborting
  std::string gimbal_controller = "gimbal_controller";  // the controller's node name (relative)

  // Reads the private parameters; throws ParamError naming the parameter.
  static CalibrationOptions load(const ros::NodeHandle& pnh);
};

class CalibrationNode {
 public:
  CalibrationNode(ros::NodeHandle nh, ros::NodeHandle pnh, const CalibrationOptions& options);
  // Stops the subscriptions, waits for a handler still running on the network thread, and joins
  // the analysis worker (a running analysis is finished and discarded).
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
  std::string state_path() const;
  std::string analysis_path() const;
  // The rows accepted so far (checkpointed, restored ones included) with the run's time origin.
  const core::PositionTable& table() const { return table_; }
  // Non-empty after a watchdog aborted the run: why.
  const std::string& fault() const { return fault_; }

 private:
  void on_command(const GimbalCommand::ConstPtr& msg) { handle_command(*msg); }
  void on_imu(const sensor_msgs::Imu::ConstPtr& msg) { handle_imu(*msg); }
  void on_progress(const diagnostic_msgs::DiagnosticStatus::ConstPtr& msg);
  void on_timer(const ros::TimerEvent&);
  bool on_get_intrinsics(GetIntrinsics::Request& req, GetIntrinsics::Response& res);
  bool on_reset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool on_analyze(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  void on_dwell(const core::DwellRecord& row);
  void run_fit(const ros::Time& now);
  // Publishes result_ (the certificate), writes the result YAML and the state (after the fit, or
  // after the analysis that follows it).
  void publish_result(const ros::Time& now);
  // The options core::analyze() runs with.
  core::AnalysisOptions analysis_options() const;
  // Publishes an analysis of table_ (latched topic, analysis.json) and sets the certificate by
  // the policy; returns a one-line summary. Under the lock; the analysis itself ran without it.
  std::string apply_analysis(const core::AnalysisResult& analysis, const core::FitResult& base,
                             const core::TimingLagEstimate* lag, const ros::Time& now);
  // The assembler's callbacks: dwells to on_dwell, and (with analyze) the released stream to
  // move_samples_. After every assembler reset.
  void connect_assembler();
  // Analysis worker: run_fit() hands it a copy of the table; it analyzes without the lock, then
  // applies the result under the lock unless a reset bumped the generation meanwhile.
  struct AnalysisJob {
    std::uint64_t generation = 0;
    core::PositionTable table;
    core::FitResult base;
    ros::Time stamp;
    // Raw streams around the moves (MoveSampleRecorder), for the timing lag.
    std::vector<core::GimbalEvent> commands;
    std::vector<core::ImuSample> move_samples;
  };
  void start_analysis(const ros::Time& now);
  void analysis_loop();

  // Checkpoint.
  void load_checkpoint();
  void write_state();
  void open_csv(bool append);
  void clear_checkpoint();

  // Watchdogs and resynchronization with the gimbal controller.
  struct Blackout {
    double begin_s = -std::numeric_limits<double>::infinity();
    double end_s = std::numeric_limits<double>::infinity();  // stamp of the rewound MOVING
  };
  // What to ask the gimbal controller once the lock is released.
  struct ControllerRequest {
    enum class Kind { None, Resume, Abort } kind = Kind::None;
    core::Phase phase = core::Phase::X;
    std::uint32_t step = 0;
    int approach = +1;
    bool after = false;  // resume at the position after (phase, step, approach)
    std::string reason;
  };
  void raise_fault(const std::string& what, core::Phase phase, std::uint32_t step, int approach,
                   double dwell_start_s);
  void check_watchdogs(const ros::Time& now);
  bool in_blackout(double t_start_s, double t_end_s) const;
  bool request_pending() const;  // a rewind asked for or not yet confirmed
  // Continue the run after the last recorded dwell, discarding what was measured before the
  // controller's new MOVING: after this node restarted from its checkpoint, or after the gimbal
  // controller restarted mid-run. `cause` names which, for the logs and the controller.
  void begin_resume(const std::string& cause);
  void restart_assembler();
  ControllerRequest take_request();
  void apply_reply(const ControllerRequest& request, bool called, bool success,
                   const std::string& message, double stamp_s);
  void diagnose_imu(diagnostic_updater::DiagnosticStatusWrapper& status);
  void diagnose_run(diagnostic_updater::DiagnosticStatusWrapper& status);
  int approach_of_next_row(core::Phase phase, std::uint32_t step) const;
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
  // With analyze: the gimbal events and the samples near the moves of the current run, which the
  // timing-lag estimate reads (bounded; cleared at a reset and when a resume rewinds the run).
  core::MoveSampleRecorder move_samples_;
  ros::Subscriber command_sub_, imu_sub_, progress_sub_;
  ros::Publisher result_pub_, status_pub_, analysis_pub_;
  ros::ServiceServer get_srv_, reset_srv_, analyze_srv_;
  ros::Timer timer_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;

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

  // Accepted rows (restored + this session's, minus discarded ones) and the run's time origin.
  core::PositionTable table_;
  bool have_fit_ = false;
  core::FitResult base_fit_;
  core::FitResult certificate_fit_;  // base_fit_, or the refit with named effects
  std::string analysis_json_;
  std::string analysis_error_;
  // Bumped by reset() and by each new analysis: a running analysis of an older one is discarded.
  std::uint64_t analysis_generation_ = 0;
  bool analysis_running_ = false;          // fit done, the result waits for the worker
  std::mutex job_mutex_;                   // job_, job_pending_, stop_worker_ (after mutex_)
  std::condition_variable job_cv_;
  AnalysisJob job_;
  bool job_pending_ = false;
  bool stop_worker_ = false;
  std::thread analysis_thread_;            // started last in the constructor
  // Counters of assemblers restarted after a fault, added to the current one's for reports.
  core::AssemblerCounters counters_before_;
  core::AssemblerCounters counters() const;
  std::uint64_t rows_discarded_ = 0;
  bool restored_ = false;          // rows were reloaded from a checkpoint
  bool resume_pending_ = false;    // restored mid-protocol: rewind the controller on its first command
  ros::Time resume_deadline_;      // ... or at this time if no command comes
  std::string controller_state_;   // latest state on gimbal_controller/progress
  // The controller came back IDLE in the middle of a run (it died and was restarted).
  bool controller_restarted_ = false;
  bool restore_done_ = false;      // the checkpoint says DONE: fit it at the first update
  std::vector<Blackout> blackouts_;
  ControllerRequest request_;      // pending, sent by on_timer outside the lock
  bool pending_restart_ = false;   // restart the assembler at the end of update()
  ros::Time request_after_;        // do not retry a failed request before this
  std::string fault_;              // the run was aborted by a watchdog: why
  std::string controller_abort_;   // the gimbal controller's progress said ABORTED: why
  std::string last_fault_;         // the latest fault (retried or not)
  std::map<std::tuple<int, std::uint32_t, int>, std::uint32_t> retries_;  // per position
  std::uint64_t retries_total_ = 0;
  // What the latest commands (arrival order) say: in a dwell since this SETTLED stamp?
  bool live_in_dwell_ = false;
  GimbalCommand live_dwell_;
  double newest_sample_stamp_s_ = -std::numeric_limits<double>::infinity();
  // Dwells announced by the commands (stamp order), to catch a dwell with no sample at all.
  struct Announced {
    core::Phase phase;
    std::uint32_t step;
    double begin_s, end_s;
    bool recorded;
  };
  std::vector<Announced> announced_;
  // IMU rate for the diagnostics.
  std::uint64_t imu_received_ = 0, rate_count_ = 0;
  double rate_first_stamp_s_ = 0.0, rate_last_stamp_s_ = 0.0;
  double imu_rate_hz_ = 0.0;
};

}  // namespace accel_intrinsics
