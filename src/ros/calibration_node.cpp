// Calibration node: dwell assembly, checkpoints, fit, result, services.
#include "accel_intrinsics/ros/calibration_node.h"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <diagnostic_msgs/KeyValue.h>
#include <std_msgs/String.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iterator>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/calibrate.h"
#include "accel_intrinsics/core/constants.h"
#include "accel_intrinsics/core/position_table.h"
#include "accel_intrinsics/io/analysis_report.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/ros/conversions.h"
#include "accel_intrinsics/ros/names.h"
#include "accel_intrinsics/ros/params.h"

namespace accel_intrinsics {

namespace {

diagnostic_msgs::KeyValue kv(const std::string& key, const std::string& value) {
  diagnostic_msgs::KeyValue out;
  out.key = key;
  out.value = value;
  return out;
}

const char* const kPhase[3] = {"x", "y", "z"};

std::string position_label(core::Phase phase, std::uint32_t step, int approach) {
  std::ostringstream s;
  s << "phase " << core::phase_name(phase) << " step " << step;
  if (approach < 0) s << " (return sweep)";
  return s.str();
}

// The timing lag of the recorded moves, beside an analysis whose refit is `after_fit`; null when
// no gimbal event was recorded (analyze off, or nothing since a reset or a rewind).
std::unique_ptr<core::TimingLagEstimate> estimate_lag(
    const std::vector<core::GimbalEvent>& commands, const std::vector<core::ImuSample>& samples,
    const core::PositionTable& table, const core::FitResult& after_fit) {
  if (commands.empty()) return nullptr;
  return std::unique_ptr<core::TimingLagEstimate>(new core::TimingLagEstimate(
      core::estimate_timing_lag(commands, samples, table, after_fit,
                                core::timing_lag_options_beside_screen())));
}

}  // namespace

void ImmediateCallbackQueue::addCallback(const ros::CallbackInterfacePtr& callback, uint64_t) {
  if (coalesce_s_ > 0.0) {
    // roscpp reads messages already waiting in the socket back to back (a few microseconds
    // apart); a longer gap since the previous callback returned means this thread has just been
    // woken from its poll by a fresh message. Then nap, so that the next messages pile up in
    // the socket and are read in one go: one wake-up per period instead of one per message.
    constexpr std::chrono::microseconds kIdleGap(20);
    const auto now = std::chrono::steady_clock::now();
    if (now - last_return_ > kIdleGap) {
      std::this_thread::sleep_for(std::chrono::duration<double>(coalesce_s_));
    }
  }
  // TryAgain only happens for callbacks that refuse concurrent calls; a subscription queue with
  // a single subscriber never does. Retry a few times to be safe, then leave it.
  for (int i = 0; i < 100; ++i) {
    if (callback->ready() && callback->call() != ros::CallbackInterface::TryAgain) break;
  }
  last_return_ = std::chrono::steady_clock::now();
}

void ImmediateCallbackQueue::removeByID(uint64_t) {}

CalibrationOptions CalibrationOptions::load(const ros::NodeHandle& pnh) {
  CalibrationOptions o;
  std::string model = core::model_name(o.fit.model);
  read_param(pnh, "model", &model);
  try {
    o.fit.model = core::parse_model(model);
  } catch (const std::invalid_argument&) {
    throw ParamError("parameter " + param_name(pnh, "model") + ": unknown model '" + model +
                     "' (joint or eq4)");
  }
  const bool have_g = read_param(pnh, "local_gravity", &o.fit.local_gravity);
  double latitude_deg = 0.0, height_m = 0.0;
  const bool have_lat = read_param(pnh, "latitude_deg", &latitude_deg);
  read_param(pnh, "height_m", &height_m);
  require(!(have_g && have_lat), pnh, "local_gravity",
          "give either local_gravity or latitude_deg (with height_m), not both");
  if (have_lat) {
    try {
      o.fit.local_gravity = core::normal_gravity(latitude_deg, height_m);
    } catch (const std::invalid_argument& e) {
      throw ParamError("parameter " + param_name(pnh, "latitude_deg") + ": " + e.what());
    }
  }
  require(
      std::isfinite(o.fit.local_gravity) && o.fit.local_gravity > 9.7 && o.fit.local_gravity < 9.9,
      pnh, "local_gravity",
      "must be in (9.7, 9.9) m/s^2 (got " + std::to_string(o.fit.local_gravity) + ")");
  read_param(pnh, "min_positions_per_phase", &o.fit.min_positions_per_phase);
  require(o.fit.min_positions_per_phase >= 3, pnh, "min_positions_per_phase", "must be >= 3");
  read_param(pnh, "settle_discard_s", &o.assembler.settle_discard_s);
  require(std::isfinite(o.assembler.settle_discard_s) && o.assembler.settle_discard_s >= 0.0, pnh,
          "settle_discard_s", "must be finite and >= 0 s");
  read_param(pnh, "reorder_window_s", &o.assembler.reorder_window_s);
  require(std::isfinite(o.assembler.reorder_window_s) && o.assembler.reorder_window_s >= 0.0 &&
              o.assembler.reorder_window_s <= 60.0,
          pnh, "reorder_window_s", "must be in [0, 60] s");
  read_param(pnh, "flush_period_s", &o.flush_period_s);
  require(std::isfinite(o.flush_period_s) && o.flush_period_s > 0.0 && o.flush_period_s <= 10.0,
          pnh, "flush_period_s", "must be in (0, 10] s");
  read_param(pnh, "status_period_s", &o.status_period_s);
  require(std::isfinite(o.status_period_s) && o.status_period_s > 0.0, pnh, "status_period_s",
          "must be > 0 s");
  read_param(pnh, "steps", &o.steps);
  read_param(pnh, "frame_id", &o.frame_id);
  read_param(pnh, "immediate_imu", &o.immediate_imu);
  read_param(pnh, "imu_coalesce_s", &o.imu_coalesce_s);
  require(std::isfinite(o.imu_coalesce_s) && o.imu_coalesce_s >= 0.0 && o.imu_coalesce_s <= 0.05,
          pnh, "imu_coalesce_s", "must be in [0, 0.05] s");
  read_param(pnh, "file_prefix", &o.file_prefix);
  require(o.file_prefix.find('/') == std::string::npos, pnh, "file_prefix", "must not contain '/'");
  // Analysis.
  read_param(pnh, "analyze", &o.analyze);
  o.analysis.local_gravity = o.fit.local_gravity;
  read_param(pnh, "analysis/alpha", &o.analysis.alpha);
  read_param(pnh, "analysis/max_effects", &o.analysis.max_effects);
  read_param(pnh, "analysis/monte_carlo_draws", &o.analysis.monte_carlo_draws);
  int analysis_seed = static_cast<int>(o.analysis.seed % 2147483647ULL);
  if (read_param(pnh, "analysis/seed", &analysis_seed)) {
    require(analysis_seed >= 0, pnh, "analysis/seed", "must be >= 0");
    o.analysis.seed = static_cast<std::uint64_t>(analysis_seed);
  }
  try {
    core::validate(o.analysis);
  } catch (const std::invalid_argument& e) {
    throw ParamError("parameter " + param_name(pnh, "analysis") + ": " + e.what());
  }
  std::string certificate = "base";
  read_param(pnh, "certificate_model", &certificate);
  require(certificate == "base" || certificate == "refit", pnh, "certificate_model",
          "must be 'base' or 'refit' (got '" + certificate + "')");
  o.certificate_refit = certificate == "refit";

  // Resume and watchdogs.
  read_param(pnh, "resume", &o.resume);
  read_param(pnh, "imu_timeout_s", &o.imu_timeout_s);
  require(std::isfinite(o.imu_timeout_s) && o.imu_timeout_s >= 0.0, pnh, "imu_timeout_s",
          "must be finite and >= 0 s (0 = off)");
  read_param(pnh, "min_samples_per_dwell", &o.min_samples_per_dwell);
  std::string on_fault = "abort";
  read_param(pnh, "on_fault", &on_fault);
  require(on_fault == "abort" || on_fault == "retry", pnh, "on_fault",
          "must be 'abort' or 'retry' (got '" + on_fault + "')");
  o.retry_on_fault = on_fault == "retry";
  read_param(pnh, "max_retries", &o.max_retries);
  require(o.max_retries <= 100, pnh, "max_retries", "must be in [0, 100]");
  read_param(pnh, "gimbal_controller", &o.gimbal_controller);
  require(!o.gimbal_controller.empty(), pnh, "gimbal_controller", "must not be empty");

  read_param(pnh, "output_dir", &o.output_dir);
  require(!(o.resume && o.output_dir.empty()), pnh, "resume",
          "needs output_dir (the checkpoint lives there)");
  if (!o.output_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.output_dir, ec);
    require(!ec && std::filesystem::is_directory(o.output_dir), pnh, "output_dir",
            "cannot create directory '" + o.output_dir + "'" + (ec ? ": " + ec.message() : ""));
  }
  return o;
}

CalibrationNode::CalibrationNode(ros::NodeHandle nh, ros::NodeHandle pnh,
                                 const CalibrationOptions& options)
    : nh_(nh), pnh_(pnh), options_(options), assembler_(options.assembler) {
  connect_assembler();
  if (options_.resume) load_checkpoint();
  result_pub_ = nh_.advertise<IntrinsicResult>(names::kResultTopic, 1, true);
  status_pub_ =
      nh_.advertise<diagnostic_msgs::DiagnosticStatus>(names::kCalibrationStatusTopic, 1, true);
  analysis_pub_ = nh_.advertise<std_msgs::String>(names::kAnalysisTopic, 1, true);
  get_srv_ =
      nh_.advertiseService(names::kGetIntrinsicsService, &CalibrationNode::on_get_intrinsics, this);
  reset_srv_ = nh_.advertiseService(names::kResetService, &CalibrationNode::on_reset, this);
  analyze_srv_ = nh_.advertiseService(names::kAnalyzeService, &CalibrationNode::on_analyze, this);
  updater_.reset(new diagnostic_updater::Updater(nh_, pnh_));
  updater_->setHardwareID("accel_intrinsics " + nh_.getNamespace());
  updater_->add("imu", this, &CalibrationNode::diagnose_imu);
  updater_->add("run", this, &CalibrationNode::diagnose_run);
  command_sub_ = nh_.subscribe(names::kGimbalCommandTopic, 1000, &CalibrationNode::on_command, this,
                               ros::TransportHints().tcpNoDelay());
  ros::SubscribeOptions imu_options = ros::SubscribeOptions::create<sensor_msgs::Imu>(
      names::kImuTopic, 20000, boost::bind(&CalibrationNode::on_imu, this, boost::placeholders::_1),
      ros::VoidConstPtr(), options_.immediate_imu ? &immediate_queue_ : nullptr);
  immediate_queue_.set_coalesce_period(options_.imu_coalesce_s);
  imu_sub_ = nh_.subscribe(imu_options);
  progress_sub_ = nh_.subscribe(names::kProgressTopic, 10, &CalibrationNode::on_progress, this);
  timer_ =
      nh_.createTimer(ros::Duration(options_.flush_period_s), &CalibrationNode::on_timer, this);
  ROS_INFO("calibration: model %s, local_gravity %.6f m/s^2, reorder window %.3f s, output %s%s%s",
           core::model_name(options_.fit.model), options_.fit.local_gravity,
           options_.assembler.reorder_window_s,
           options_.output_dir.empty() ? "(none)" : options_.output_dir.c_str(),
           options_.analyze ? ", analysis after the fit" : "",
           options_.resume ? ", resume from the checkpoint" : "");
  // Last: nothing after this may throw (a joinable std::thread must not be destroyed).
  analysis_thread_ = std::thread(&CalibrationNode::analysis_loop, this);
}

CalibrationNode::~CalibrationNode() {
  imu_sub_.shutdown();
  command_sub_.shutdown();
  timer_.stop();
  {
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    ++analysis_generation_;  // a running analysis is discarded when it finishes
  }
  {
    std::lock_guard<std::mutex> lock(job_mutex_);
    stop_worker_ = true;
    job_pending_ = false;
  }
  job_cv_.notify_all();
  // Not under mutex_: the worker takes it to check the generation.
  if (analysis_thread_.joinable()) analysis_thread_.join();
}

std::string CalibrationNode::csv_path() const {
  if (options_.output_dir.empty()) return "";
  return (std::filesystem::path(options_.output_dir) /
          (options_.file_prefix + "position_table.csv"))
      .string();
}

std::string CalibrationNode::yaml_path() const {
  if (options_.output_dir.empty()) return "";
  return (std::filesystem::path(options_.output_dir) / (options_.file_prefix + "intrinsics.yaml"))
      .string();
}

std::string CalibrationNode::state_path() const {
  if (options_.output_dir.empty()) return "";
  return (std::filesystem::path(options_.output_dir) /
          (options_.file_prefix + "calibration_state.yaml"))
      .string();
}

std::string CalibrationNode::analysis_path() const {
  if (options_.output_dir.empty()) return "";
  return (std::filesystem::path(options_.output_dir) / (options_.file_prefix + "analysis.json"))
      .string();
}

core::AssemblerCounters CalibrationNode::counters() const {
  core::AssemblerCounters c = assembler_.counters();
  const core::AssemblerCounters& b = counters_before_;
  c.samples_used += b.samples_used;
  c.dropped_outside_dwell += b.dropped_outside_dwell;
  c.dropped_settle_discard += b.dropped_settle_discard;
  c.dropped_non_finite += b.dropped_non_finite;
  c.dropped_backwards += b.dropped_backwards;
  c.dropped_late += b.dropped_late;
  c.commands += b.commands;
  c.commands_out_of_order += b.commands_out_of_order;
  if (c.last_warning.empty()) c.last_warning = b.last_warning;
  return c;
}

void CalibrationNode::handle_command(const GimbalCommand& msg) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  ++commands_received_;
  // step == steps is the closing position at 2 pi (ProtocolOptions::closing_position).
  if (msg.phase > GimbalCommand::PHASE_Z || msg.state > GimbalCommand::DONE ||
      !std::isfinite(msg.angle) || !core::step_in_protocol(msg.step, msg.steps) ||
      msg.header.stamp.isZero()) {
    ++rejected_commands_;
    ROS_WARN_THROTTLE(5.0,
                      "calibration: rejected a malformed gimbal command (phase %u state %u step "
                      "%u/%u angle %f stamp %.3f); %llu so far",
                      msg.phase, msg.state, msg.step, msg.steps, msg.angle,
                      msg.header.stamp.toSec(),
                      static_cast<unsigned long long>(rejected_commands_));
    return;
  }
  const core::GimbalEvent event = to_core(msg);
  const bool run_start = event.state == core::GimbalState::Moving &&
                         event.phase == core::Phase::X && event.step == 0;
  if (resume_pending_) {
    // First command after a restart from a checkpoint: a fresh run, or the one to continue.
    if (run_start) {
      resume_pending_ = false;
      ROS_WARN("calibration: a new run starts; the checkpoint of %zu dwells is discarded",
               table_.rows.size());
      reset("a new run starts over the checkpoint");
    } else {
      begin_resume("calibration node restarted from its checkpoint");
    }
  }
  const bool new_run =
      run_start && (done_pending_ || assembler_.done() || has_result_ || !fit_error_.empty() ||
                    !fault_.empty()) &&
      blackouts_.empty();
  if (new_run) {
    if (done_pending_ && fault_.empty()) {
      // The previous run's DONE is still in the reorder window: finish it first.
      assembler_.flush();
      done_pending_ = false;
      run_fit(msg.header.stamp);
    }
    reset("a new run starts (MOVING to phase x step 0 after DONE)");
  }
  if (!std::isfinite(table_.time_origin_s)) {
    table_.time_origin_s = event.stamp_s;  // t0 of the drift term: the first command of the run
    steps_seen_ = msg.steps;
    write_state();
  }
  steps_seen_ = msg.steps;
  // Live view (arrival order) for the IMU watchdog, and the announced dwells (stamp order).
  live_in_dwell_ = event.state == core::GimbalState::Settled;
  if (live_in_dwell_) live_dwell_ = msg;
  if (!announced_.empty() && !std::isfinite(announced_.back().end_s)) {
    announced_.back().end_s = event.stamp_s;
  }
  if (event.state == core::GimbalState::Settled) {
    announced_.push_back({event.phase, event.step, event.stamp_s,
                          std::numeric_limits<double>::infinity(), false});
  }
  if (event.state == core::GimbalState::Done) {
    // A DONE inside an open blackout belongs to the protocol before the rewind: drop it.
    for (const Blackout& b : blackouts_) {
      if (event.stamp_s >= b.begin_s && event.stamp_s < b.end_s) {
        ROS_INFO("calibration: DONE at %.3f s ignored (waiting for the rewound protocol)",
                 event.stamp_s);
        return;
      }
    }
  }
  assembler_.add_command(event);
  if (event.state == core::GimbalState::Done) {
    done_pending_ = true;
    done_stamp_s_ = event.stamp_s;
    ROS_INFO("calibration: DONE received, fitting after the reorder window");
  }
  warn_on_new_drops();
}

void CalibrationNode::on_progress(const diagnostic_msgs::DiagnosticStatus::ConstPtr& msg) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  std::string state;
  for (const auto& kv : msg->values) {
    if (kv.key == "state") state = kv.value;
  }
  // A running controller never goes back to IDLE by itself: a new process has taken its place
  // (respawned after a crash). The run it drove is still open here: continue it.
  const bool was_running = controller_state_ == "MOVING" || controller_state_ == "SETTLED";
  if (state == "IDLE" && was_running && !done_pending_ && !assembler_.done() && !has_result_ &&
      fault_.empty() && controller_abort_.empty()) {
    controller_restarted_ = true;
    ROS_WARN("calibration: the gimbal controller restarted in the middle of the run");
  }
  controller_state_ = state;
  if (state == "ABORTED") {
    // "ABORTED: <reason>"
    const std::size_t colon = msg->message.find(": ");
    const std::string reason =
        colon == std::string::npos ? msg->message : msg->message.substr(colon + 2);
    if (reason != controller_abort_) {
      controller_abort_ = reason;
      if (fault_.empty()) ROS_ERROR("calibration: the gimbal controller aborted: %s", reason.c_str());
    }
  } else if (state == "STARTING" || state == "MOVING" || state == "SETTLED") {
    controller_abort_.clear();
  }
}

void CalibrationNode::handle_imu(const sensor_msgs::Imu& msg) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  ++imu_received_;
  const core::ImuSample sample = to_core(msg);
  if (std::isfinite(sample.stamp_s)) {
    if (rate_count_ == 0) rate_first_stamp_s_ = sample.stamp_s;
    rate_last_stamp_s_ = sample.stamp_s;
    ++rate_count_;
  }
  if (sample.stamp_s > newest_sample_stamp_s_) newest_sample_stamp_s_ = sample.stamp_s;
  assembler_.add_sample(sample);
  const core::AssemblerCounters& c = assembler_.counters();
  if (c.dropped_non_finite != warned_.dropped_non_finite ||
      c.dropped_backwards != warned_.dropped_backwards || c.dropped_late != warned_.dropped_late) {
    warn_on_new_drops();
  }
}

void CalibrationNode::warn_on_new_drops() {
  const core::AssemblerCounters& c = assembler_.counters();
  if (c.dropped_non_finite > warned_.dropped_non_finite) {
    ROS_WARN_THROTTLE(5.0,
                      "calibration: dropped IMU samples with NaN or infinite values (%llu so far)",
                      static_cast<unsigned long long>(c.dropped_non_finite));
  }
  if (c.dropped_backwards > warned_.dropped_backwards) {
    ROS_WARN_THROTTLE(5.0,
                      "calibration: dropped IMU samples whose stamp went backwards (%llu so far)",
                      static_cast<unsigned long long>(c.dropped_backwards));
  }
  if (c.dropped_late > warned_.dropped_late) {
    ROS_WARN_THROTTLE(5.0,
                      "calibration: dropped messages that arrived after the reorder window "
                      "(%llu so far; raise reorder_window_s?)",
                      static_cast<unsigned long long>(c.dropped_late));
  }
  if (c.commands_out_of_order > warned_.commands_out_of_order) {
    ROS_WARN_THROTTLE(5.0, "calibration: gimbal command out of protocol order (%llu so far): %s",
                      static_cast<unsigned long long>(c.commands_out_of_order),
                      c.last_warning.c_str());
  }
  warned_ = c;
}

void CalibrationNode::update(const ros::Time& now) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  if (now.isZero()) return;
  if (controller_restarted_ && !request_pending()) {
    controller_restarted_ = false;
    begin_resume("the gimbal controller restarted mid-run");
  }
  if (resume_pending_ && controller_state_ == "DONE") {
    // No gimbal command since the restart and the controller finished the protocol meanwhile
    // (this node died in the last dwells): resume after a grace period. An idle controller
    // (a fresh stand over an old checkpoint) is never started from here.
    if (resume_deadline_.isZero()) {
      resume_deadline_ =
          now + ros::Duration(std::max(2.0, 2.0 * options_.assembler.reorder_window_s));
    } else if (now >= resume_deadline_) {
      begin_resume("calibration node restarted from its checkpoint");
    }
  }
  if (restore_done_) {
    // The checkpoint holds a finished run: its result again.
    restore_done_ = false;
    run_fit(now);
  }
  const double window = options_.assembler.reorder_window_s;
  if (done_pending_ && now.toSec() >= done_stamp_s_ + window) {
    assembler_.flush();
    done_pending_ = false;
    warn_on_new_drops();
    check_watchdogs(now);
    if (!fault_.empty() || !controller_abort_.empty()) {
      // An aborted run gives no certificate, whatever it has measured.
      ROS_ERROR("calibration: the run was aborted; no fit: %s", missing_message().c_str());
      publish_status(now);
    } else if (!request_pending()) {
      run_fit(now);
    } else {
      ROS_WARN("calibration: DONE but a position is to be measured again; no fit yet");
    }
  } else if (now.toSec() > window) {
    assembler_.flush_until(now.toSec() - window);
    warn_on_new_drops();
  }
  check_watchdogs(now);
  if (pending_restart_) {
    pending_restart_ = false;
    counters_before_ = counters();
    assembler_.reset();
    connect_assembler();
    warned_ = core::AssemblerCounters();
    live_in_dwell_ = false;
    announced_.clear();
  }
  if (now < last_status_ || (now - last_status_).toSec() >= options_.status_period_s) {
    publish_status(now);
  }
  if (updater_) updater_->update();
}

void CalibrationNode::begin_resume(const std::string& cause) {
  // Have the controller go to the position after the last recorded dwell (or to the first one),
  // and discard everything measured before its MOVING (a dwell cut short, samples taken while
  // nobody drove the gimbal).
  resume_pending_ = false;
  request_ = ControllerRequest();
  request_.kind = ControllerRequest::Kind::Resume;
  request_after_ = ros::Time();
  blackouts_.push_back(Blackout());  // everything until the rewound MOVING
  move_samples_.clear();             // the lag is estimated on the moves after it
  if (!table_.rows.empty()) {
    const core::DwellRecord& last = table_.rows.back();
    request_.phase = last.phase;
    request_.step = last.step;
    request_.approach = core::dwell_geometries(table_).back().approach;
    request_.after = true;
    request_.reason = cause;
    ROS_WARN("calibration: %s: resuming after %s (%zu dwells recorded)", cause.c_str(),
             position_label(last.phase, last.step, request_.approach).c_str(),
             table_.rows.size());
  } else {
    request_.phase = core::Phase::X;
    request_.step = 0;
    request_.approach = +1;
    request_.after = false;
    request_.reason = cause + ", no dwell recorded";
    ROS_WARN("calibration: %s: resuming from the first position (no dwell recorded)",
             cause.c_str());
  }
}

bool CalibrationNode::request_pending() const {
  if (request_.kind != ControllerRequest::Kind::None) return true;
  for (const Blackout& b : blackouts_) {
    if (!std::isfinite(b.end_s)) return true;
  }
  return false;
}

void CalibrationNode::on_timer(const ros::TimerEvent&) {
  const ros::Time now = ros::Time::now();
  update(now);
  // Requests to the gimbal controller go out without the lock: the reply is read by roscpp's
  // network thread, which may be waiting for the lock in handle_imu (immediate_imu).
  ControllerRequest request = take_request();
  if (request.kind == ControllerRequest::Kind::None) return;
  const std::string controller = options_.gimbal_controller;
  bool called = false, success = false;
  std::string message;
  double stamp_s = 0.0;
  if (request.kind == ControllerRequest::Kind::Resume) {
    ResumeAt srv;
    srv.request.phase = static_cast<std::uint8_t>(core::index(request.phase));
    srv.request.step = request.step;
    srv.request.approach = static_cast<std::int8_t>(request.approach);
    srv.request.after = request.after;
    srv.request.reason = request.reason;
    ros::ServiceClient client = nh_.serviceClient<ResumeAt>(controller + "/resume");
    called = client.waitForExistence(ros::Duration(0.5)) && client.call(srv);
    success = srv.response.success;
    message = srv.response.message;
    stamp_s = srv.response.stamp.toSec();
  } else {
    nh_.setParam(controller + "/request/abort_reason", request.reason);
    std_srvs::Trigger srv;
    ros::ServiceClient client = nh_.serviceClient<std_srvs::Trigger>(controller + "/abort");
    called = client.waitForExistence(ros::Duration(0.5)) && client.call(srv);
    success = srv.response.success;
    message = srv.response.message;
  }
  apply_reply(request, called, success, message, stamp_s);
}

CalibrationNode::ControllerRequest CalibrationNode::take_request() {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  ControllerRequest r;
  if (request_.kind == ControllerRequest::Kind::None) return r;
  const ros::Time now = ros::Time::now();
  if (!request_after_.isZero() && now < request_after_) return r;
  r = request_;
  request_.kind = ControllerRequest::Kind::None;
  return r;
}

void CalibrationNode::apply_reply(const ControllerRequest& request, bool called, bool success,
                                  const std::string& message, double stamp_s) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  const std::string controller = nh_.resolveName(options_.gimbal_controller);
  if (!called) {
    // The controller is not there (yet): ask again in a moment.
    ROS_WARN_THROTTLE(10.0, "calibration: %s/%s not available; retrying", controller.c_str(),
                      request.kind == ControllerRequest::Kind::Resume ? "resume" : "abort");
    if (request_.kind == ControllerRequest::Kind::None) request_ = request;
    request_after_ = ros::Time::now() + ros::Duration(0.5);
    return;
  }
  if (request.kind == ControllerRequest::Kind::Abort) {
    ROS_ERROR("calibration: asked %s to abort: %s", controller.c_str(), message.c_str());
    return;
  }
  if (!success || !(std::isfinite(stamp_s) && stamp_s > 0.0)) {
    fault_ = "the gimbal controller refused to resume at " +
             position_label(request.phase, request.step, request.approach) +
             (request.after ? " (after)" : "") + ": " + message;
    ROS_ERROR("calibration: %s", fault_.c_str());
    blackouts_.clear();
    write_state();
    publish_status(ros::Time::now());
    return;
  }
  for (Blackout& b : blackouts_) {
    if (!std::isfinite(b.end_s)) b.end_s = stamp_s;
  }
  ROS_WARN("calibration: %s: %s", controller.c_str(), message.c_str());
}

void CalibrationNode::reset(const std::string& reason) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  const std::size_t dwells = table_.rows.size();
  assembler_.reset();
  connect_assembler();
  done_pending_ = false;
  has_result_ = false;
  have_fit_ = false;
  fit_error_.clear();
  result_ = IntrinsicResult();
  if (csv_.is_open()) csv_.close();
  warned_ = core::AssemblerCounters();
  counters_before_ = core::AssemblerCounters();
  rejected_commands_ = 0;
  table_ = core::PositionTable();
  rows_discarded_ = 0;
  restored_ = false;
  resume_pending_ = false;
  resume_deadline_ = ros::Time();
  restore_done_ = false;
  blackouts_.clear();
  request_ = ControllerRequest();
  fault_.clear();
  controller_abort_.clear();
  last_fault_.clear();
  retries_.clear();
  retries_total_ = 0;
  live_in_dwell_ = false;
  announced_.clear();
  analysis_json_.clear();
  analysis_error_.clear();
  // An analysis still running belongs to the discarded run: its result is dropped.
  ++analysis_generation_;
  analysis_running_ = false;
  {
    std::lock_guard<std::mutex> job_lock(job_mutex_);
    job_pending_ = false;
  }
  newest_sample_stamp_s_ = -std::numeric_limits<double>::infinity();
  ++runs_;
  clear_checkpoint();
  ROS_INFO("calibration: reset (%s); discarded %zu dwells", reason.c_str(), dwells);
  publish_status(ros::Time::now());
}

bool CalibrationNode::in_blackout(double t_start_s, double t_end_s) const {
  for (const Blackout& b : blackouts_) {
    if (t_end_s > b.begin_s && t_start_s < b.end_s) return true;
  }
  return false;
}

void CalibrationNode::on_dwell(const core::DwellRecord& row) {
  for (Announced& a : announced_) {
    if (a.begin_s + options_.assembler.settle_discard_s == row.t_start_s) a.recorded = true;
  }
  if (in_blackout(row.t_start_s, row.t_end_s)) {
    ++rows_discarded_;
    ROS_INFO("calibration: dwell %s %u/%u%s measured before the rewind: discarded",
             core::phase_name(row.phase), row.step + 1, steps_seen_,
             core::is_closing_step(row.step, steps_seen_) ? " (closing position)" : "");
    return;
  }
  if (!fault_.empty()) return;
  if (options_.min_samples_per_dwell > 0 && row.n < options_.min_samples_per_dwell) {
    std::ostringstream what;
    what << "dwell " << position_label(row.phase, row.step, approach_of_next_row(row.phase, row.step))
         << " has " << row.n << " samples (fewer than min_samples_per_dwell = "
         << options_.min_samples_per_dwell << ")";
    raise_fault(what.str(), row.phase, row.step, approach_of_next_row(row.phase, row.step),
                row.t_start_s - options_.assembler.settle_discard_s);
    return;
  }
  table_.rows.push_back(row);
  if (!options_.output_dir.empty()) {
    if (!csv_.is_open()) open_csv(restored_);
    if (csv_) core::write_position_row(csv_, row);  // flushed: the checkpoint of this dwell
  }
  ROS_INFO("calibration: dwell %s %u/%u%s: n = %llu, mean (%.5f, %.5f, %.5f) m/s^2",
           core::phase_name(row.phase), row.step + 1, steps_seen_,
           core::is_closing_step(row.step, steps_seen_) ? " (closing position, 360 deg)" : "",
           static_cast<unsigned long long>(row.n), row.mean(0), row.mean(1), row.mean(2));
}

int CalibrationNode::approach_of_next_row(core::Phase phase, std::uint32_t step) const {
  core::PositionTable t = table_;
  core::DwellRecord r;
  r.phase = phase;
  r.step = step;
  r.angle_rad = core::step_angle(step, steps_seen_ ? steps_seen_ : std::max(options_.steps, 1u));
  r.n = 1;
  t.rows.push_back(r);
  return core::dwell_geometries(t).back().approach;
}

void CalibrationNode::raise_fault(const std::string& what, core::Phase phase, std::uint32_t step,
                                  int approach, double dwell_start_s) {
  last_fault_ = what;
  const auto key = std::make_tuple(core::index(phase), step, approach);
  std::uint32_t& tries = retries_[key];
  if (options_.retry_on_fault && tries < options_.max_retries) {
    ++tries;
    ++retries_total_;
    ROS_WARN("calibration: %s; measuring it again (retry %u of %u)", what.c_str(), tries,
             options_.max_retries);
    Blackout b;
    b.begin_s = dwell_start_s;
    blackouts_.push_back(b);
    move_samples_.clear();  // the lag is estimated on the moves after the rewind
    request_ = ControllerRequest();
    request_.kind = ControllerRequest::Kind::Resume;
    request_.phase = phase;
    request_.step = step;
    request_.approach = approach;
    request_.after = false;
    request_.reason = what;
    request_after_ = ros::Time();
    done_pending_ = false;
    restart_assembler();
    return;
  }
  std::ostringstream reason;
  reason << what;
  if (options_.retry_on_fault) {
    reason << "; gave up after " << tries << (tries == 1 ? " retry" : " retries")
           << " (max_retries)";
  } else {
    reason << " (on_fault: abort)";
  }
  fault_ = reason.str();
  ROS_ERROR("calibration: run aborted: %s", fault_.c_str());
  request_ = ControllerRequest();
  request_.kind = ControllerRequest::Kind::Abort;
  request_.reason = fault_;
  request_after_ = ros::Time();
  has_result_ = false;
  write_state();
  publish_status(ros::Time::now());
}

void CalibrationNode::restart_assembler() {
  // Deferred to the end of update(): a fault may be raised inside the assembler's callback.
  // Events of the abandoned stretch still queued in the assembler are dropped with it; its
  // counters carry over. It runs before the rewind request goes out (on_timer), so nothing of
  // the rewound protocol is lost.
  pending_restart_ = true;
}

void CalibrationNode::check_watchdogs(const ros::Time& now) {
  if (!fault_.empty() || request_pending()) return;
  // A dwell that ended without a single sample (the assembler records nothing for it).
  const double released = now.toSec() - options_.assembler.reorder_window_s;
  for (std::size_t i = 0; i < announced_.size(); ++i) {
    const Announced& a = announced_[i];
    if (a.recorded || !std::isfinite(a.end_s) || a.end_s > released) continue;
    if (in_blackout(a.begin_s, a.end_s)) continue;
    if (options_.min_samples_per_dwell > 0 || options_.imu_timeout_s > 0.0) {
      const int approach = approach_of_next_row(a.phase, a.step);
      const Announced copy = a;
      announced_.clear();
      raise_fault("dwell " + position_label(copy.phase, copy.step, approach) +
                      " has no samples at all",
                  copy.phase, copy.step, approach, copy.begin_s);
      return;
    }
  }
  while (!announced_.empty() && (announced_.front().recorded ||
                                 (std::isfinite(announced_.front().end_s) &&
                                  announced_.front().end_s <= released))) {
    announced_.erase(announced_.begin());
  }
  // The IMU stream stopped during a dwell.
  if (options_.imu_timeout_s > 0.0 && live_in_dwell_) {
    const double since = std::max(live_dwell_.header.stamp.toSec(), newest_sample_stamp_s_);
    const double silent = now.toSec() - since;
    if (silent > options_.imu_timeout_s && !in_blackout(live_dwell_.header.stamp.toSec(),
                                                        live_dwell_.header.stamp.toSec() + 1e-9)) {
      const core::Phase phase = static_cast<core::Phase>(live_dwell_.phase);
      const int approach = approach_of_next_row(phase, live_dwell_.step);
      std::ostringstream what;
      what.setf(std::ios::fixed);
      what.precision(1);
      what << "IMU stream stopped: no samples for " << silent << " s during dwell "
           << position_label(phase, live_dwell_.step, approach) << " (imu_timeout_s = "
           << options_.imu_timeout_s << ")";
      live_in_dwell_ = false;
      // Dwells before this one are complete: process them before the assembler restarts.
      assembler_.flush_until(live_dwell_.header.stamp.toSec() - 1e-9);
      raise_fault(what.str(), phase, live_dwell_.step, approach,
                  live_dwell_.header.stamp.toSec());
    }
  }
}

std::array<int, 3> CalibrationNode::dwells_per_phase() const {
  std::array<int, 3> counts{{0, 0, 0}};
  for (const core::DwellRecord& r : table_.rows) ++counts[core::index(r.phase)];
  return counts;
}

std::string CalibrationNode::missing_message() const {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  const std::array<int, 3> counts = dwells_per_phase();
  const std::uint32_t n = steps_seen_ ? steps_seen_ : options_.steps;
  const int needed = n ? static_cast<int>(n) : options_.fit.min_positions_per_phase;
  std::ostringstream s;
  if (!fault_.empty()) {
    s << "run aborted: " << fault_ << "; ";
  } else if (!controller_abort_.empty()) {
    s << "run aborted by the gimbal controller: " << controller_abort_ << "; ";
  }
  s << "no result yet: ";
  if (!fit_error_.empty()) s << "the fit failed (" << fit_error_ << "); ";
  // Which phases are missing dwells, and how many.
  bool first = true;
  for (int p = 0; p < 3; ++p) {
    if (counts[p] >= needed) continue;
    s << (first ? "missing " : ", ") << "phase " << kPhase[p] << " (" << counts[p] << " of "
      << (n ? std::to_string(n) : ">= " + std::to_string(needed)) << " dwells)";
    first = false;
  }
  if (first) s << "all phases have their dwells";
  if (commands_received_ == 0) s << "; no gimbal command received yet";
  core::Phase phase;
  std::uint32_t step = 0;
  std::uint64_t samples = 0;
  if (assembler_.current_dwell(&phase, &step, &samples)) {
    s << "; in dwell phase " << core::phase_name(phase) << " step " << step << " (" << samples
      << " samples)";
  }
  if (done_pending_) s << "; DONE received, fitting after the reorder window";
  if (analysis_running_) s << "; fitted, the discrepancy analysis is running (result after it)";
  if (request_pending()) s << "; waiting for the gimbal controller to resume";
  if (retries_total_ > 0) s << "; " << retries_total_ << " position(s) measured again";
  const core::AssemblerCounters c = counters();
  s << "; samples used " << c.samples_used << ", dropped outside dwells "
    << c.dropped_outside_dwell;
  return s.str();
}

bool CalibrationNode::on_get_intrinsics(GetIntrinsics::Request&, GetIntrinsics::Response& res) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  if (has_result_) {
    res.success = true;
    res.result = result_;
    std::ostringstream s;
    s << result_.model << " fit of " << result_.positions[0] << "/" << result_.positions[1] << "/"
      << result_.positions[2] << " dwells (x/y/z), reduced chi2 " << result_.reduced_chi2
      << ", g = " << result_.local_gravity << " m/s^2";
    res.message = s.str();
  } else {
    res.success = false;
    res.message = missing_message();
  }
  return true;
}

bool CalibrationNode::on_reset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  const std::size_t dwells = assembler_.table().rows.size();
  reset("reset requested");
  res.success = true;
  res.message = "reset: discarded " + std::to_string(dwells) + " dwells";
  return true;
}

bool CalibrationNode::on_analyze(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  // The analysis runs on a copy of the table without the lock; its result is applied under the
  // lock unless a reset came meanwhile.
  core::PositionTable table;
  bool have_fit = false;
  core::FitResult base;
  std::uint64_t generation = 0;
  std::vector<core::GimbalEvent> commands;
  std::vector<core::ImuSample> move_samples;
  {
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    table = table_;
    have_fit = have_fit_;
    if (have_fit) base = base_fit_;
    generation = analysis_generation_;
    commands = move_samples_.commands();
    move_samples = move_samples_.samples();
  }
  try {
    if (!have_fit) base = core::fit(table, options_.fit);
    const core::AnalysisResult analysis = core::analyze(table, analysis_options());
    const std::unique_ptr<core::TimingLagEstimate> lag =
        estimate_lag(commands, move_samples, table, analysis.after_fit);
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    if (generation != analysis_generation_) {
      res.success = false;
      res.message = "analysis discarded: the run was reset or fitted again while it ran";
      return true;
    }
    res.message = apply_analysis(analysis, base, lag.get(), ros::Time::now());
    res.success = true;
  } catch (const std::exception& e) {
    res.success = false;
    res.message = std::string("analysis failed: ") + e.what() + " (" + missing_message() + ")";
  }
  return true;
}

void CalibrationNode::run_fit(const ros::Time& now) {
  const core::PositionTable& table = table_;
  try {
    const core::FitResult fit = core::fit(table, options_.fit);
    base_fit_ = fit;
    certificate_fit_ = fit;
    have_fit_ = true;
    result_ = to_msg(fit);
    result_.header.stamp = now;
    result_.header.frame_id = options_.frame_id;
    fit_error_.clear();
    if (options_.analyze) {
      // The result goes out when the analysis has finished (it may replace the certificate).
      start_analysis(now);
      publish_status(now);
      return;
    }
    publish_result(now);
  } catch (const std::exception& e) {
    has_result_ = false;
    fit_error_ = e.what();
    ROS_ERROR("calibration: no result after DONE: %s", missing_message().c_str());
  }
  publish_status(now);
}

void CalibrationNode::publish_result(const ros::Time& now) {
  // apply_analysis() replaced result_ when the certificate is the refit model.
  has_result_ = true;
  result_pub_.publish(result_);
  ROS_INFO(
      "calibration: %s fit of %zu dwells: |u| %.6f |v| %.6f |w| %.6f, angles uv %.4f vw "
      "%.4f wu %.4f deg, reduced chi2 %.3f",
      result_.model.c_str(), table_.rows.size(), result_.responsivity[0], result_.responsivity[1],
      result_.responsivity[2], result_.angles_deg[0], result_.angles_deg[1],
      result_.angles_deg[2], result_.reduced_chi2);
  write_result_yaml(certificate_fit_, now);
  write_state();
}

core::AnalysisOptions CalibrationNode::analysis_options() const {
  core::AnalysisOptions options = options_.analysis;
  options.local_gravity = options_.fit.local_gravity;
  return options;
}

void CalibrationNode::connect_assembler() {
  move_samples_.clear();
  assembler_.set_dwell_callback([this](const core::DwellRecord& row) { on_dwell(row); });
  if (options_.analyze) {
    assembler_.set_release_observers(
        [this](const core::GimbalEvent& e) { move_samples_.add_command(e); },
        [this](const core::ImuSample& sample) { move_samples_.add_sample(sample); });
  }
}

void CalibrationNode::start_analysis(const ros::Time& now) {
  // Under mutex_ (lock order: mutex_, then job_mutex_). A newer fit supersedes an analysis
  // still running for an older one.
  ++analysis_generation_;
  analysis_running_ = true;
  {
    std::lock_guard<std::mutex> lock(job_mutex_);
    job_.generation = analysis_generation_;
    job_.table = table_;
    job_.base = base_fit_;
    job_.stamp = now;
    job_.commands = move_samples_.commands();
    job_.move_samples = move_samples_.samples();
    job_pending_ = true;  // replaces a job not yet started (same run or a discarded one)
  }
  job_cv_.notify_one();
  ROS_INFO("calibration: fit done; discrepancy analysis of %zu dwells running, the result "
           "follows it",
           table_.rows.size());
}

void CalibrationNode::analysis_loop() {
  for (;;) {
    AnalysisJob job;
    {
      std::unique_lock<std::mutex> lock(job_mutex_);
      job_cv_.wait(lock, [this] { return stop_worker_ || job_pending_; });
      if (stop_worker_) return;
      job = std::move(job_);
      job_pending_ = false;
    }
    // Without the lock: IMU handling, commands and services go on meanwhile.
    std::unique_ptr<core::AnalysisResult> analysis;
    std::unique_ptr<core::TimingLagEstimate> lag;
    std::string error;
    try {
      analysis.reset(new core::AnalysisResult(core::analyze(job.table, analysis_options())));
      lag = estimate_lag(job.commands, job.move_samples, job.table, analysis->after_fit);
    } catch (const std::exception& e) {
      error = e.what();
    } catch (...) {
      error = "unknown exception";
    }
    std::lock_guard<std::recursive_mutex> lock(mutex_);
    if (job.generation != analysis_generation_) {
      ROS_INFO("calibration: the analysis of a reset or superseded run finished; dropped");
      continue;
    }
    analysis_running_ = false;
    if (analysis) {
      try {
        const std::string summary = apply_analysis(*analysis, job.base, lag.get(), job.stamp);
        ROS_INFO("calibration: analysis: %s", summary.c_str());
      } catch (const std::exception& e) {
        error = e.what();
      }
    }
    if (!error.empty()) {
      analysis_error_ = error;
      ROS_ERROR("calibration: analysis failed: %s", error.c_str());
    }
    if (!fault_.empty() || request_pending()) {
      // A watchdog fired after the fit: no certificate from this one.
      ROS_WARN("calibration: a fault came while the analysis ran; its fit is not published");
    } else {
      publish_result(job.stamp);
    }
    publish_status(job.stamp);
  }
}

std::string CalibrationNode::apply_analysis(const core::AnalysisResult& analysis,
                                            const core::FitResult& base,
                                            const core::TimingLagEstimate* lag,
                                            const ros::Time& now) {
  const bool refit = options_.certificate_refit && !analysis.effects.empty();
  certificate_fit_ = refit ? analysis.after_fit : base;
  if (have_fit_) {
    result_ = to_msg(certificate_fit_);
    result_.header.stamp = now;
    result_.header.frame_id = options_.frame_id;
    if (has_result_) result_pub_.publish(result_);
  }
  // The analysis document of io (which model is the certificate, which models it compared).
  core::CalibrationReport report;
  report.base_fit = base;
  report.certificate = certificate_fit_;
  report.certificate_is_refit = refit;
  report.certificate_refit_policy = options_.certificate_refit;
  report.analysis = analysis;
  if (lag != nullptr) report.timing_lag = *lag;
  io::ResultContext context;
  context.stamp_s = now.toSec();
  analysis_json_ = io::analysis_json_text(report, context);
  analysis_error_.clear();
  std_msgs::String msg;
  msg.data = analysis_json_;
  analysis_pub_.publish(msg);
  if (!options_.output_dir.empty()) {
    try {
      io::write_file_atomically(analysis_path(), analysis_json_ + '\n');
    } catch (const io::IoError& e) {
      ROS_ERROR("calibration: %s", e.what());
    }
  }
  std::ostringstream s;
  s.precision(4);
  s << "reduced chi2 " << analysis.before.summary.reduced_chi2 << " (" << analysis.before_fit.model_label()
    << ") -> " << analysis.after.summary.reduced_chi2 << " (" << analysis.after_fit.model_label()
    << "); named:";
  if (analysis.effects.empty()) s << " none";
  for (const core::NamedEffect& e : analysis.effects) {
    s << " " << e.effect.label() << " = " << e.effect.value << " +- " << e.std << " (p "
      << e.p_value << ")";
  }
  s << "; certificate: " << certificate_fit_.model_label();
  if (lag != nullptr) s << "; " << (lag->ok ? "" : "timing lag: no estimate: ") << lag->message;
  return s.str();
}

void CalibrationNode::write_result_yaml(const core::FitResult& fit, const ros::Time& stamp) {
  // (fit is the certificate: the base fit, or the refit with named effects.) One writer for the
  // node and offline_fit: io/result_document.h.
  if (options_.output_dir.empty()) return;
  core::CalibrationReport report;
  report.base_fit = base_fit_;
  report.certificate = fit;
  report.certificate_refit_policy = options_.certificate_refit;
  report.certificate_is_refit = fit.model_label() != base_fit_.model_label();
  io::ResultContext context;
  context.stamp_s = stamp.toSec();
  context.samples = counters();
  const std::string path = yaml_path();
  try {
    io::write_result_yaml(path, report, context);
  } catch (const io::IoError& e) {
    ROS_ERROR("calibration: %s", e.what());
    return;
  }
  ROS_INFO("calibration: wrote %s", path.c_str());
}

void CalibrationNode::publish_status(const ros::Time& now) {
  last_status_ = now;
  const core::AssemblerCounters c = counters();
  const std::array<int, 3> counts = dwells_per_phase();
  diagnostic_msgs::DiagnosticStatus msg;
  msg.name = nh_.resolveName("calibration");
  msg.hardware_id = "accel_intrinsics";
  std::string state = has_result_           ? "RESULT"
                      : !fault_.empty() || !controller_abort_.empty() ? "ABORTED"
                      : request_pending()   ? "RESUMING"
                      : !fit_error_.empty() ? "FAILED"
                      : done_pending_ || analysis_running_ ? "FITTING"
                      : commands_received_  ? "COLLECTING"
                                            : "WAITING";
  msg.level = fit_error_.empty() && fault_.empty() ? diagnostic_msgs::DiagnosticStatus::OK
                                                   : diagnostic_msgs::DiagnosticStatus::ERROR;
  msg.message = has_result_ ? "result available" : missing_message();
  msg.values.push_back(kv("state", state));
  for (int p = 0; p < 3; ++p)
    msg.values.push_back(kv(std::string("dwells_") + kPhase[p], std::to_string(counts[p])));
  msg.values.push_back(kv("steps", std::to_string(steps_seen_ ? steps_seen_ : options_.steps)));
  msg.values.push_back(kv("samples_used", std::to_string(c.samples_used)));
  msg.values.push_back(kv("dropped_outside_dwell", std::to_string(c.dropped_outside_dwell)));
  msg.values.push_back(kv("dropped_settle_discard", std::to_string(c.dropped_settle_discard)));
  msg.values.push_back(kv("dropped_non_finite", std::to_string(c.dropped_non_finite)));
  msg.values.push_back(kv("dropped_backwards", std::to_string(c.dropped_backwards)));
  msg.values.push_back(kv("dropped_late", std::to_string(c.dropped_late)));
  msg.values.push_back(kv("commands", std::to_string(c.commands)));
  msg.values.push_back(kv("commands_out_of_order", std::to_string(c.commands_out_of_order)));
  msg.values.push_back(kv("commands_rejected", std::to_string(rejected_commands_)));
  msg.values.push_back(kv("last_warning", c.last_warning));
  msg.values.push_back(kv("fault", !fault_.empty() ? fault_ : controller_abort_));
  msg.values.push_back(kv("last_fault", last_fault_));
  msg.values.push_back(kv("retries", std::to_string(retries_total_)));
  msg.values.push_back(kv("dwells_discarded", std::to_string(rows_discarded_)));
  msg.values.push_back(kv("restored", restored_ ? "true" : "false"));
  msg.values.push_back(kv("model", has_result_ ? result_.model : ""));
  msg.values.push_back(kv("stamp", std::to_string(now.toSec())));
  status_pub_.publish(msg);
}

// ---- Checkpoint ------------------------------------------------------------------------------
// position_table.csv: the accepted rows, one flushed line per dwell (the contract's CSV).
// calibration_state.yaml: time_origin_s (t0 of the drift term: the first gimbal command of the
// run), steps, rows, done, fault; rewritten atomically (tmp + rename) when one of them changes.

void CalibrationNode::open_csv(bool append) {
  std::error_code ec;
  const bool exists = std::filesystem::exists(csv_path()) &&
                      std::filesystem::file_size(csv_path(), ec) > 0 && !ec;
  csv_.open(csv_path(), append ? std::ios::out | std::ios::app : std::ios::out | std::ios::trunc);
  if (!csv_) {
    ROS_ERROR_THROTTLE(10.0, "calibration: cannot write %s", csv_path().c_str());
    return;
  }
  if (!append || !exists) csv_ << core::kPositionTableHeader << '\n' << std::flush;
}

void CalibrationNode::write_state() {
  if (options_.output_dir.empty()) return;
  YAML::Emitter y;
  y << YAML::BeginMap;
  y << YAML::Key << "time_origin_s" << YAML::Value << YAML::Precision(17) << table_.time_origin_s;
  y << YAML::Key << "steps" << YAML::Value << steps_seen_;
  y << YAML::Key << "rows" << YAML::Value << table_.rows.size();
  y << YAML::Key << "done" << YAML::Value << has_result_;
  y << YAML::Key << "fault" << YAML::Value << fault_;
  y << YAML::EndMap;
  const std::string path = state_path();
  {
    std::ofstream out(path + ".tmp", std::ios::out | std::ios::trunc);
    out << "# accel_intrinsics calibration checkpoint (with position_table.csv)\n"
        << y.c_str() << '\n';
    if (!out) {
      ROS_ERROR_THROTTLE(10.0, "calibration: cannot write %s", path.c_str());
      return;
    }
  }
  if (std::rename((path + ".tmp").c_str(), path.c_str()) != 0) {
    ROS_ERROR_THROTTLE(10.0, "calibration: cannot rename %s.tmp", path.c_str());
  }
}

void CalibrationNode::clear_checkpoint() {
  if (options_.output_dir.empty()) return;
  std::error_code ec;
  std::filesystem::remove(state_path(), ec);
  std::filesystem::remove(csv_path(), ec);
}

void CalibrationNode::load_checkpoint() {
  if (!std::filesystem::exists(state_path())) {
    ROS_INFO("calibration: resume: no checkpoint in %s, starting fresh",
             options_.output_dir.c_str());
    return;
  }
  try {
    const YAML::Node state = YAML::LoadFile(state_path());
    const double t0 = state["time_origin_s"].as<double>();
    const std::uint32_t steps = state["steps"].as<std::uint32_t>();
    const bool done = state["done"] && state["done"].as<bool>();
    const std::string fault = state["fault"] ? state["fault"].as<std::string>() : "";
    core::PositionTable table;
    if (std::filesystem::exists(csv_path())) {
      // A kill in the middle of a line leaves it incomplete: drop it (its dwell is measured again).
      std::string text;
      {
        std::ifstream in(csv_path(), std::ios::binary);
        text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
      }
      if (!text.empty() && text.back() != '\n') {
        text.erase(text.rfind('\n') == std::string::npos ? 0 : text.rfind('\n') + 1);
        std::ofstream out(csv_path(), std::ios::binary | std::ios::trunc);
        out << text;
        ROS_WARN("calibration: resume: dropped an incomplete last line of %s", csv_path().c_str());
      }
      std::istringstream in(text);
      if (!text.empty()) table = core::read_position_table(in, csv_path());
    }
    table.time_origin_s = t0;
    table_ = table;
    steps_seen_ = steps;
    restored_ = true;
    fault_ = fault;
    if (!fault_.empty()) {
      ROS_WARN("calibration: resume: the checkpointed run was aborted (%s)", fault_.c_str());
    } else if (done) {
      restore_done_ = true;
    } else {
      resume_pending_ = true;  // rewind the controller when it shows up
    }
    ROS_WARN("calibration: resume: restored %zu dwells (N = %u, t0 = %.6f s)%s from %s",
             table_.rows.size(), steps, t0, done ? ", run complete" : "",
             options_.output_dir.c_str());
  } catch (const std::exception& e) {
    // A checkpoint that cannot be read is not silently replaced by a fresh run.
    throw ParamError("parameter " + param_name(pnh_, "resume") + ": cannot read the checkpoint in " +
                     options_.output_dir + ": " + e.what());
  }
}

// ---- Diagnostics ---------------------------------------------------------------------------

void CalibrationNode::diagnose_imu(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  const ros::Time now = ros::Time::now();
  // The sensor's rate in its own time: samples over the span of their stamps since the last
  // report (arrival times jitter with transport and, in simulation, with time_scale).
  imu_rate_hz_ = rate_count_ > 1 && rate_last_stamp_s_ > rate_first_stamp_s_
                     ? static_cast<double>(rate_count_ - 1) /
                           (rate_last_stamp_s_ - rate_first_stamp_s_)
                     : 0.0;
  rate_count_ = 0;
  const core::AssemblerCounters c = counters();
  const std::uint64_t dropped_bad = c.dropped_non_finite + c.dropped_backwards + c.dropped_late;
  if (options_.imu_timeout_s > 0.0 && live_in_dwell_ &&
      now.toSec() - std::max(live_dwell_.header.stamp.toSec(), newest_sample_stamp_s_) >
          options_.imu_timeout_s) {
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "no IMU samples during a dwell");
  } else if (dropped_bad > 0) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "bad IMU samples dropped");
  } else {
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, "IMU stream ok");
  }
  status.add("rate_hz", imu_rate_hz_);
  status.add("received", imu_received_);
  status.add("samples_used", c.samples_used);
  status.add("dropped_outside_dwell", c.dropped_outside_dwell);
  status.add("dropped_settle_discard", c.dropped_settle_discard);
  status.add("dropped_non_finite", c.dropped_non_finite);
  status.add("dropped_backwards", c.dropped_backwards);
  status.add("dropped_late", c.dropped_late);
  status.add("newest_stamp_s", std::isfinite(newest_sample_stamp_s_) ? newest_sample_stamp_s_ : 0.0);
}

void CalibrationNode::diagnose_run(diagnostic_updater::DiagnosticStatusWrapper& status) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  const std::array<int, 3> counts = dwells_per_phase();
  if (!fault_.empty() || !controller_abort_.empty()) {
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR,
                   "run aborted: " + (fault_.empty() ? controller_abort_ : fault_));
  } else if (!fit_error_.empty()) {
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "fit failed: " + fit_error_);
  } else if (request_pending()) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                   "waiting for the gimbal controller to resume" +
                       (last_fault_.empty() ? std::string() : " (" + last_fault_ + ")"));
  } else if (has_result_) {
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, "result available (" + result_.model + ")");
  } else {
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, "collecting");
  }
  core::Phase phase;
  std::uint32_t step = 0;
  std::uint64_t samples = 0;
  if (assembler_.current_dwell(&phase, &step, &samples)) {
    status.add("current_dwell", position_label(phase, step, +1));
    status.add("current_dwell_samples", samples);
  } else {
    status.add("current_dwell", "");
    status.add("current_dwell_samples", 0);
  }
  for (int p = 0; p < 3; ++p) status.add(std::string("dwells_") + kPhase[p], counts[p]);
  status.add("steps", steps_seen_ ? steps_seen_ : options_.steps);
  status.add("retries", retries_total_);
  status.add("dwells_discarded", rows_discarded_);
  status.add("last_fault", last_fault_);
  status.add("restored", restored_);
}

}  // namespace accel_intrinsics
