// Calibration node: the ROS shell of core::CalibrationRun and core::calibrate.
#include "accel_intrinsics/ros/calibration_node.h"

#include <diagnostic_msgs/KeyValue.h>
#include <std_msgs/String.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <thread>

#include "accel_intrinsics/AbortRun.h"
#include "accel_intrinsics/ResumeAt.h"
#include "accel_intrinsics/core/fit/quality.h"
#include "accel_intrinsics/io/analysis_report.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/ros/channel_messages.h"
#include "accel_intrinsics/ros/conversions.h"
#include "accel_intrinsics/ros/dwell_message.h"
#include "accel_intrinsics/ros/names.h"
#include "accel_intrinsics/ros/params.h"
#include "accel_intrinsics/ros/result_files.h"
#include "accel_intrinsics/ros/scripts.h"

namespace accel_intrinsics {

CalibrationNode::CalibrationNode(ros::NodeHandle nh, ros::NodeHandle pnh,
                                 const CalibrationOptions& options)
    : nh_(nh),
      pnh_(pnh),
      options_(options),
      run_(options.run),
      files_("", options.file_prefix),
      runs_(options.output_dir),
      new_run_pending_(runs_.enabled()),
      device_serial_(options.device_serial) {
  if (options_.resume) {
    // The checkpoint of the device's newest run (its `latest` link).
    const std::string latest = runs_.latest_run(device_serial_);
    if (!latest.empty()) {
      files_ = io::CheckpointFiles(latest, options_.file_prefix);
      new_run_pending_ = false;
    }
    const std::string param = param_name(pnh_, "resume");
    const std::string where = latest.empty() ? runs_.device_dir(device_serial_) : latest;
    carry_out(restore_from_checkpoint(&files_, where, &run_, param), nullptr);
  }
  result_pub_ = nh_.advertise<IntrinsicResult>(names::kResultTopic, 1, true);
  status_pub_ =
      nh_.advertise<diagnostic_msgs::DiagnosticStatus>(names::kCalibrationStatusTopic, 1, true);
  analysis_pub_ = nh_.advertise<std_msgs::String>(names::kAnalysisTopic, 1, true);
  run_directory_pub_ = nh_.advertise<std_msgs::String>(names::kRunDirectoryTopic, 10);
  dwell_pub_ = advertise_dwells(nh_);
  get_srv_ =
      nh_.advertiseService(names::kGetIntrinsicsService, &CalibrationNode::on_get_intrinsics, this);
  reset_srv_ = nh_.advertiseService(names::kResetService, &CalibrationNode::on_reset, this);
  analyze_srv_ = nh_.advertiseService(names::kAnalyzeService, &CalibrationNode::on_analyze, this);
  // Named after the node (its private namespace), also in a nodelet manager.
  updater_.reset(new diagnostic_updater::Updater(nh_, pnh_, pnh_.getNamespace()));
  updater_->setHardwareID("accel_intrinsics " + nh_.getNamespace());
  updater_->add("imu", this, &CalibrationNode::diagnose_imu);
  updater_->add("run", this, &CalibrationNode::diagnose_run);
  command_sub_ = nh_.subscribe(names::kGimbalCommandTopic, 1000, &CalibrationNode::on_command, this,
                               ros::TransportHints().tcpNoDelay());
  const bool batched = !options_.immediate_imu && options_.imu_batch_s > 0.0;
  // Batched: roscpp calls on_imu_batched at once in the publisher's thread (it only appends the
  // pointer, never naps: no coalescing there), and the IMU thread handles the batches.
  ros::CallbackQueueInterface* imu_queue =  // nullptr: the node handle's
      options_.immediate_imu || batched ? &immediate_queue_ : nullptr;
  if (batched) {  // before the subscription: on_imu_batched hands to it
    imu_batcher_ = std::make_unique<MessageBatcher<sensor_msgs::Imu>>(
        kImuQueueSize, options_.imu_batch_s,
        [this](const std::vector<sensor_msgs::Imu::ConstPtr>& batch) {
          std::lock_guard<std::recursive_mutex> lock(mutex_);  // once per batch
          last_activity_ = ros::WallTime::now();
          for (const sensor_msgs::Imu::ConstPtr& msg : batch) handle_imu_locked(*msg);
        });
  }
  ros::SubscribeOptions imu_options = ros::SubscribeOptions::create<sensor_msgs::Imu>(
      names::kImuTopic, kImuQueueSize,
      boost::bind(batched ? &CalibrationNode::on_imu_batched : &CalibrationNode::on_imu, this,
                  boost::placeholders::_1),
      ros::VoidConstPtr(), imu_queue);
  immediate_queue_.set_coalesce_period(options_.immediate_imu ? options_.imu_coalesce_s : 0.0);
  imu_sub_ = nh_.subscribe(imu_options);
  for (const ChannelMessage& channel : channel_messages()) {
    channel_subs_.push_back(channel.subscribe(
        nh_, core::channel_spec(channel.channel).topic, 1000,
        [this](const core::ChannelSample& reading) { handle_channel_sample(reading); }));
  }
  progress_sub_ = nh_.subscribe(names::kProgressTopic, 10, &CalibrationNode::on_progress, this);
  timer_ =
      nh_.createTimer(ros::Duration(options_.flush_period_s), &CalibrationNode::on_timer, this);
  last_activity_ = ros::WallTime::now();
  wall_timer_ =
      nh_.createWallTimer(ros::WallDuration(std::min(0.25, options_.idle_fit_after_s / 2)),
                          &CalibrationNode::on_wall_timer, this);
  ROS_INFO("calibration: model %s, local_gravity %.6f m/s^2, reorder window %.3f s, output %s%s%s",
           core::model_name(options_.calibrate.fit.model), options_.calibrate.fit.local_gravity,
           options_.run.assembler.reorder_window_s,
           options_.output_dir.empty() ? "(none)" : options_.output_dir.c_str(),
           options_.calibrate.analyze ? ", analysis after the fit" : "",
           options_.resume ? ", resume from the checkpoint" : "");
  // Last: nothing after this may throw (a joinable std::thread must not be destroyed).
  fit_thread_ = std::thread(&CalibrationNode::fit_loop, this);
}

CalibrationNode::~CalibrationNode() {
  {
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    shutting_down_ = true;  // a fit still running is finished and discarded
  }
  imu_sub_.shutdown();
  imu_batcher_.reset();  // joins its thread; messages not yet handled are dropped
  for (ros::Subscriber& sub : channel_subs_) sub.shutdown();
  command_sub_.shutdown();
  timer_.stop();
  {
    std::lock_guard<std::mutex> lock(job_mutex_);
    stop_worker_ = true;
    job_.reset();
  }
  job_cv_.notify_all();
  // Not under mutex_: the worker takes it to finish its fit.
  if (fit_thread_.joinable()) fit_thread_.join();
}

// ---- Inputs ------------------------------------------------------------------------------------

void CalibrationNode::on_imu_batched(const sensor_msgs::Imu::ConstPtr& msg) {
  if (!imu_batcher_->push(msg)) {
    ROS_WARN_THROTTLE(5.0, "calibration: the IMU batch is full (%zu messages): dropping messages",
                      imu_batcher_->capacity());
  }
}

void CalibrationNode::handle_command(const GimbalCommand& msg) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  last_activity_ = ros::WallTime::now();
  if (!is_well_formed(msg)) {
    run_.note_rejected_command();
    ROS_WARN_THROTTLE(5.0,
                      "calibration: rejected a malformed gimbal command (phase %u state %u step "
                      "%u/%u angle %f stamp %.3f); %llu so far",
                      msg.phase, msg.state, msg.step, msg.steps, msg.angle,
                      msg.header.stamp.toSec(),
                      static_cast<unsigned long long>(run_.status(0.0).commands_rejected));
    return;
  }
  carry_out(run_.on_command(to_core(msg)), nullptr);
}

void CalibrationNode::handle_imu(const sensor_msgs::Imu& msg) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  last_activity_ = ros::WallTime::now();
  handle_imu_locked(msg);
}

void CalibrationNode::handle_imu_locked(const sensor_msgs::Imu& msg) {
  ++imu_received_;
  const core::ImuSample sample = to_core(msg);
  if (std::isfinite(sample.stamp_s)) {
    if (rate_count_ == 0) rate_first_stamp_s_ = sample.stamp_s;
    rate_last_stamp_s_ = sample.stamp_s;
    ++rate_count_;
  }
  const core::RunActions actions = run_.on_sample(sample);
  if (!actions.empty()) carry_out(actions, nullptr);
}

void CalibrationNode::handle_channel_sample(const core::ChannelSample& reading) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  last_activity_ = ros::WallTime::now();
  const core::RunActions actions = run_.on_channel_sample(reading);
  if (!actions.empty()) carry_out(actions, nullptr);
}

void CalibrationNode::on_progress(const diagnostic_msgs::DiagnosticStatus::ConstPtr& msg) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  std::string state;
  for (const auto& value : msg->values) {
    if (value.key == "state") state = value.value;
  }
  carry_out(run_.on_controller_state(state, msg->message), nullptr);
}

std::vector<core::RunAction> CalibrationNode::update(const ros::Time& now) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  std::vector<core::RunAction> requests;
  if (now.isZero()) return requests;
  carry_out(run_.tick(now.toSec()), &requests);
  if (now < last_status_ || (now - last_status_).toSec() >= options_.status_period_s) {
    publish_status(now);
  }
  if (updater_) updater_->update();
  return requests;
}

void CalibrationNode::on_timer(const ros::TimerEvent&) {
  for (const core::RunAction& request : update(ros::Time::now())) call_controller(request);
}

void CalibrationNode::on_wall_timer(const ros::WallTimerEvent&) {
  // The sim-time timer stops with the clock; this one sees a replay that ended at DONE.
  std::vector<core::RunAction> requests;
  {
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    const ros::Time clock = ros::Time::now();
    const ros::WallTime wall = ros::WallTime::now();
    if (clock != last_clock_) {
      last_clock_ = clock;
      last_activity_ = wall;
    }
    if (!run_.waiting_after_done() || (wall - last_activity_).toSec() < options_.idle_fit_after_s) {
      return;
    }
    carry_out(run_.on_streams_idle(), &requests);
    publish_status(clock);
  }
  for (const core::RunAction& request : requests) call_controller(request);
}

void CalibrationNode::call_controller(const core::RunAction& action) {
  // Without the lock (see carry_out); the reply goes back to the run under it.
  const std::string controller = options_.gimbal_controller;
  const core::ControllerRequest& r = action.request;
  if (action.kind == core::RunAction::Kind::ResumeAt) {
    ResumeAt srv;
    srv.request = to_resume_request(r);
    ros::ServiceClient client = nh_.serviceClient<ResumeAt>(controller + "/resume");
    const bool reached = client.waitForExistence(ros::Duration(0.5)) && client.call(srv);
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    carry_out(run_.on_resume_reply(r, reached, srv.response.success, srv.response.message,
                                   srv.response.stamp.toSec(), ros::Time::now().toSec()),
              nullptr);
  } else {
    AbortRun srv;
    srv.request.reason = r.reason;
    ros::ServiceClient client = nh_.serviceClient<AbortRun>(controller + "/abort_run");
    const bool reached = client.waitForExistence(ros::Duration(0.5)) && client.call(srv);
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    carry_out(run_.on_abort_reply(r, reached, srv.response.message, ros::Time::now().toSec()),
              nullptr);
  }
}

// ---- Actions -----------------------------------------------------------------------------------

void CalibrationNode::carry_out(const core::RunActions& actions,
                                std::vector<core::RunAction>* requests) {
  using Kind = core::RunAction::Kind;
  for (const core::RunAction& a : actions) {
    try {
      switch (a.kind) {
        case Kind::Log: log_run_action(a); break;
        case Kind::DwellAccepted:
          ensure_run_directory();
          files_.append_row(a.row);
          ROS_INFO("calibration: %s", a.text.c_str());
          // Its row number: the table holds it and the rows of the later DwellAccepted here.
          if (dwell_pub_) {
            const std::size_t rows = run_.table().rows.size();
            const std::size_t later = static_cast<std::size_t>(std::count_if(
                &a + 1, actions.data() + actions.size(),
                [](const core::RunAction& b) { return b.kind == Kind::DwellAccepted; }));
            dwell_pub_.publish(
                to_dwell_msg(a.row, rows > later ? rows - later - 1 : 0, options_.frame_id));
          }
          break;
        case Kind::CheckpointState:
          ensure_run_directory();
          files_.write_state(run_.checkpoint_state());
          break;
        case Kind::ClearCheckpoint: {
          // A new run (or a reset): its result and any fit still running go; its files stay in
          // their run directory, and the next run writes into a new one.
          if (runs_.enabled()) {
            files_ = io::CheckpointFiles("", options_.file_prefix);
            new_run_pending_ = true;
          }
          mount_check_run_ = false;
          result_ = IntrinsicResult();
          ++resets_;
          std::lock_guard<std::mutex> job_lock(job_mutex_);
          // The final fit of a run that a new run replaced still goes out.
          if (job_ && !run_.fit_may_publish(job_->ticket)) job_.reset();
          break;
        }
        case Kind::FitNow:
          if (options_.calibrate.analyze) {
            // The analysis takes seconds: off the lock, on the worker.
            {
              std::lock_guard<std::mutex> job_lock(job_mutex_);
              job_ = FitJob{a.fit_ticket, a.table,          {a.move_commands, a.move_samples},
                            a.counters,   ros::Time::now(), a.noise_model};
            }
            job_cv_.notify_one();
            ROS_INFO(
                "calibration: fitting %zu dwells; the discrepancy analysis runs, the result "
                "follows it",
                a.table.rows.size());
          } else {
            const ros::Time now = ros::Time::now();
            try {
              const core::CalibrationReport report = core::calibrate(
                  a.table, nullptr, core::with_noise_model(options_.calibrate, a.noise_model));
              finish_fit(a.fit_ticket, &report, a.counters, "", now);
            } catch (const std::exception& e) {
              finish_fit(a.fit_ticket, nullptr, a.counters, e.what(), now);
            }
          }
          break;
        case Kind::ResumeAt:
        case Kind::Abort:
          if (requests != nullptr) requests->push_back(a);
          break;
      }
    } catch (const io::IoError& e) {
      ROS_ERROR_THROTTLE(10.0, "calibration: %s", e.what());
    }
  }
  if (!actions.empty() && run_.state() != last_state_) publish_status(ros::Time::now());
}

void CalibrationNode::finish_fit(std::uint64_t ticket, const core::CalibrationReport* report,
                                 const core::AssemblerCounters& counters, const std::string& error,
                                 const ros::Time& stamp) {
  const bool publish = report != nullptr && !shutting_down_ && run_.fit_may_publish(ticket);
  if (publish) {
    if (report->analysis || !report->analysis_error.empty()) publish_analysis(*report, stamp);
    publish_certificate(*report, counters, stamp);
  }
  carry_out(run_.on_fit_finished(ticket, publish, report ? "" : error), nullptr);
}

void CalibrationNode::publish_certificate(const core::CalibrationReport& report,
                                          const core::AssemblerCounters& counters,
                                          const ros::Time& stamp) {
  result_ = to_msg(report.certificate);
  result_.quality_pass = report.quality.pass;
  result_.quality_reasons = report.quality.reasons;
  if (!report.quality.pass) {
    ROS_ERROR("calibration: the result fails the quality gate: %s",
              report.quality.summary().c_str());
  }
  result_.header.stamp = stamp;
  result_.header.frame_id = options_.frame_id;
  result_pub_.publish(result_);
  ++fits_published_;
  ROS_INFO(
      "calibration: %s fit of %zu dwells: |u| %.6f |v| %.6f |w| %.6f, angles uv %.4f vw "
      "%.4f wu %.4f deg, reduced chi2 %.3f",
      result_.model.c_str(),
      static_cast<std::size_t>(result_.positions[0] + result_.positions[1] + result_.positions[2]),
      result_.responsivity[0], result_.responsivity[1], result_.responsivity[2],
      result_.angles_deg[0], result_.angles_deg[1], result_.angles_deg[2], result_.reduced_chi2);
  ensure_run_directory();
  if (files_.enabled()) {
    io::ResultContext context = result_context(stamp);
    context.samples = counters;
    if (!write_result_files(files_, options_.exports, report, context)) return;
    const std::string device = !options_.archive_device.empty()       ? options_.archive_device
                               : device_serial_ != io::kUnnamedDevice ? device_serial_
                                                                      : "";
    archive_result_file(options_.archive, device, options_.archive_rig, files_.result_path(),
                        files_.table_path());
  }
}

io::ResultContext CalibrationNode::result_context(const ros::Time& stamp) const {
  io::ResultContext context;
  context.stamp_s = stamp.toSec();
  context.certificate = options_.certificate;
  context.gravity_source = options_.gravity_source;
  context.device_serial = device_serial_;
  context.imu_topic = nh_.resolveName(names::kImuTopic);
  std::string driver = "simulated";  // the controller's default
  nh_.getParamCached(options_.gimbal_controller + "/driver", driver);
  context.gimbal_driver = driver;
  context.time_utc = io::utc_iso_time(ros::WallTime::now().toSec());
  return context;
}

void CalibrationNode::ensure_run_directory() {
  if (!new_run_pending_ || mount_check_run_) return;
  // supervise --check-mount sets ~mount_check while it drives the gimbal: no run directory.
  bool mount_check = false;
  pnh_.getParam("mount_check", mount_check);
  if (mount_check) {
    mount_check_run_ = true;
    ROS_INFO("calibration: a mount check (~mount_check): no run directory, nothing written");
    return;
  }
  // supervise --device sets ~device_serial before it starts a run: read it now.
  std::string serial = options_.device_serial;
  pnh_.getParam("device_serial", serial);
  try {
    const std::string dir = runs_.start_run(serial, ros::WallTime::now().toSec());
    files_ = io::CheckpointFiles(dir, options_.file_prefix);
    device_serial_ = serial;
    new_run_pending_ = false;
    ROS_INFO("calibration: device %s: this run writes into %s", serial.c_str(), dir.c_str());
    std_msgs::String msg;
    msg.data = dir;
    run_directory_pub_.publish(msg);
  } catch (const io::IoError& e) {
    ROS_ERROR_THROTTLE(10.0, "calibration: %s", e.what());
  }
}

std::string CalibrationNode::publish_analysis(const core::CalibrationReport& report,
                                              const ros::Time& stamp) {
  if (!report.analysis) {
    ROS_ERROR("calibration: analysis failed: %s", report.analysis_error.c_str());
    return "analysis failed: " + report.analysis_error;
  }
  const io::ResultContext context = result_context(stamp);
  std_msgs::String msg;
  msg.data = io::analysis_json_text(report, context);
  analysis_pub_.publish(msg);
  ensure_run_directory();
  if (files_.enabled()) io::write_file_atomically(files_.analysis_path(), msg.data + "\n");
  const std::string summary = io::analysis_summary_line(report);
  ROS_INFO("calibration: analysis: %s", summary.c_str());
  return summary;
}

void CalibrationNode::fit_loop() {
  for (;;) {
    FitJob job;
    {
      std::unique_lock<std::mutex> lock(job_mutex_);
      job_cv_.wait(lock, [this] { return stop_worker_ || job_.has_value(); });
      if (stop_worker_) return;
      job = std::move(*job_);
      job_.reset();
    }
    // Without the lock: IMU handling, commands and services go on meanwhile.
    std::optional<core::CalibrationReport> report;
    std::string error;
    try {
      report = core::calibrate(job.table, &job.moves,
                               core::with_noise_model(options_.calibrate, job.noise_model));
    } catch (const std::exception& e) {
      error = e.what();
    }
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    try {
      finish_fit(job.ticket, report ? &*report : nullptr, job.counters, error, job.stamp);
    } catch (const std::exception& e) {
      ROS_ERROR("calibration: %s", e.what());
    }
    publish_status(job.stamp);
  }
}

// ---- Services ----------------------------------------------------------------------------------

bool CalibrationNode::on_get_intrinsics(GetIntrinsics::Request&, GetIntrinsics::Response& res) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  res.success = run_.has_result();
  if (!res.success) {
    res.message = run_.missing_message();
    return true;
  }
  res.result = result_;
  if (!result_.quality_pass) {
    // The result is there to look at, but it is not a calibration.
    res.success = false;
    res.message = quality_failure_message(result_);
    return true;
  }
  std::ostringstream s;
  s << result_.model << " fit of " << result_.positions[0] << "/" << result_.positions[1] << "/"
    << result_.positions[2] << " dwells (x/y/z), reduced chi2 " << result_.reduced_chi2
    << ", g = " << result_.local_gravity << " m/s^2";
  res.message = s.str();
  return true;
}

bool CalibrationNode::on_reset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  const std::size_t dwells = run_.table().rows.size();
  carry_out(run_.reset("reset requested"), nullptr);
  publish_status(ros::Time::now());
  res.success = true;
  res.message = "reset: discarded " + std::to_string(dwells) + " dwells";
  return true;
}

bool CalibrationNode::on_analyze(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  // On a copy of the table without the lock; applied under the lock unless a reset came.
  core::PositionTable table;
  core::RawStreams moves;
  std::optional<core::NoiseModel> noise_model;
  std::uint64_t resets = 0, fits = 0;
  {
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    table = run_.table();
    moves = {run_.recorded_moves().commands(), run_.recorded_moves().samples()};
    noise_model = run_.noise_model();
    resets = resets_;
    fits = fits_published_;
  }
  core::CalibrateOptions options = core::with_noise_model(options_.calibrate, noise_model);
  options.analyze = true;
  try {
    const core::CalibrationReport report = core::calibrate(table, &moves, options);
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    if (resets != resets_ || fits != fits_published_) {
      res.success = false;
      res.message = "analysis discarded: the run was reset or fitted again while it ran";
      return true;
    }
    if (!report.analysis) throw std::runtime_error(report.analysis_error);
    const ros::Time now = ros::Time::now();
    res.message = publish_analysis(report, now);
    if (run_.has_result() && options_.calibrate.certificate_refit) {
      publish_certificate(report, run_.status(now.toSec()).counters, now);
    }
    res.success = true;
  } catch (const std::exception& e) {
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    res.success = false;
    res.message = std::string("analysis failed: ") + e.what() + " (" + run_.missing_message() + ")";
  }
  return true;
}

// ---- Status and diagnostics --------------------------------------------------------------------

void CalibrationNode::publish_status(const ros::Time& now) {
  last_status_ = now;
  const core::RunStatus st = run_.status(now.toSec());
  last_state_ = st.state;
  // A result that fails the quality gate is there to look at but is no calibration: say so.
  const std::string message = !run_.has_result() ? run_.missing_message()
                              : result_.quality_pass
                                  ? std::string("result available")
                                  : "result fails the quality gate: " +
                                        core::Quality{false, result_.quality_reasons}.summary();
  diagnostic_msgs::DiagnosticStatus msg =
      to_status_msg(st, message, run_.has_result() ? result_.model : "", now.toSec(),
                    nh_.resolveName("calibration"));
  if (run_.has_result() && !result_.quality_pass)
    msg.level = diagnostic_msgs::DiagnosticStatus::ERROR;
  status_pub_.publish(msg);
}

void CalibrationNode::diagnose_imu(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  // The sensor's rate in its own time: samples over the span of their stamps since the last
  // report (arrival times jitter with transport and, in simulation, with time_scale).
  const double rate_hz =
      rate_count_ > 1 && rate_last_stamp_s_ > rate_first_stamp_s_
          ? static_cast<double>(rate_count_ - 1) / (rate_last_stamp_s_ - rate_first_stamp_s_)
          : 0.0;
  rate_count_ = 0;
  accel_intrinsics::diagnose_imu(run_.status(ros::Time::now().toSec()), rate_hz, imu_received_,
                                 &status);
}

void CalibrationNode::diagnose_run(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  accel_intrinsics::diagnose_run(run_.status(ros::Time::now().toSec()), result_, &status);
}

}  // namespace accel_intrinsics
