// Gimbal controller node: protocol state machine, gimbal/command, tf, start/abort, progress.
#include "accel_intrinsics/ros/gimbal_controller_node.h"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <diagnostic_msgs/KeyValue.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/constants.h"
#include "accel_intrinsics/drivers/grbl_driver.h"
#include "accel_intrinsics/drivers/smc100_driver.h"
#include "accel_intrinsics/ros/names.h"
#include "accel_intrinsics/ros/params.h"

namespace accel_intrinsics {

namespace {

geometry_msgs::TransformStamped make_transform(const ros::Time& stamp, const std::string& parent,
                                               const std::string& child,
                                               const Eigen::Quaterniond& q) {
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = parent;
  t.child_frame_id = child;
  t.transform.rotation.w = q.w();
  t.transform.rotation.x = q.x();
  t.transform.rotation.y = q.y();
  t.transform.rotation.z = q.z();
  return t;
}

diagnostic_msgs::KeyValue kv(const std::string& key, const std::string& value) {
  diagnostic_msgs::KeyValue out;
  out.key = key;
  out.value = value;
  return out;
}

std::string num(double v, int precision = 3) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(precision);
  s << v;
  return s.str();
}

// ~<driver>/...: the serial gimbal and its per-phase axis map.
void read_serial_options(const ros::NodeHandle& pnh, const std::string& driver,
                         GimbalControllerOptions* o) {
  const ros::NodeHandle dn(pnh, driver);
  SerialGimbalOptions& s = o->serial;
  s.baud = driver == "smc100" ? 57600 : 115200;
  s.settle_s = o->protocol.settle_s;
  read_param(dn, "port", &s.port);
  read_param(dn, "baud", &s.baud);
  s.xon_xoff = driver == "smc100";
  read_param(dn, "xon_xoff", &s.xon_xoff);
  read_param(dn, "connect_timeout_s", &s.connect_timeout_s);
  read_param(dn, "reply_timeout_s", &s.reply_timeout_s);
  read_param(dn, "poll_interval_s", &s.poll_interval_s);
  read_param(dn, "tolerance_deg", &s.tolerance_deg);
  read_param(dn, "settle_s", &s.settle_s);
  read_param(dn, "home_at_start", &s.home_at_start);
  read_param(dn, "home_timeout_s", &s.home_timeout_s);
  read_param(dn, "unlock_at_start", &s.unlock_at_start);
  read_param(dn, "reset_at_start", &s.reset_at_start);
  for (int p = 0; p < 3; ++p) {
    const std::string key = std::string("phases/") + "xyz"[p];
    if (!dn.hasParam(key)) {
      throw ParamError("parameter " + param_name(dn, key) + " is missing: the axis map of phase " +
                       "xyz"[p] + " (see config/" + driver + "_gimbal.yaml)");
    }
    const ros::NodeHandle ph(dn, key);
    PhaseAxes& axes = s.axis_map.phases[p];
    XmlRpc::XmlRpcValue axis;
    if (ph.getParam("axis", axis)) {
      if (axis.getType() == XmlRpc::XmlRpcValue::TypeString) {
        axes.axis = static_cast<std::string>(axis);
      } else if (axis.getType() == XmlRpc::XmlRpcValue::TypeInt) {
        axes.axis = std::to_string(static_cast<int>(axis));
      } else {
        throw ParamError("parameter " + param_name(ph, "axis") +
                         " must be an axis letter (grbl) or a controller address (smc100)");
      }
    }
    read_param(ph, "sign", &axes.sign);
    read_param(ph, "zero_deg", &axes.zero_deg);
    read_param(ph, "manual_remount", &axes.manual_remount);
    XmlRpc::XmlRpcValue hold;
    if (ph.getParam("hold", hold)) {
      if (hold.getType() != XmlRpc::XmlRpcValue::TypeStruct) {
        throw ParamError("parameter " + param_name(ph, "hold") +
                         " must be a map axis: position_deg ({Y: 90.0})");
      }
      for (auto it = hold.begin(); it != hold.end(); ++it) {
        const XmlRpc::XmlRpcValue& v = it->second;
        if (v.getType() == XmlRpc::XmlRpcValue::TypeDouble) {
          axes.hold[it->first] = static_cast<double>(const_cast<XmlRpc::XmlRpcValue&>(v));
        } else if (v.getType() == XmlRpc::XmlRpcValue::TypeInt) {
          axes.hold[it->first] = static_cast<int>(const_cast<XmlRpc::XmlRpcValue&>(v));
        } else {
          throw ParamError("parameter " + param_name(ph, "hold/" + it->first) +
                           " must be a number (deg)");
        }
      }
    }
  }
  try {
    s.validate();
    s.axis_map.validate({});
  } catch (const std::invalid_argument& e) {
    throw ParamError("parameter " + dn.getNamespace() + "/" + e.what());
  }
}

}  // namespace

tf2_msgs::TFMessage make_tf_message(const GimbalTransforms& transforms, const ros::Time& stamp,
                                    const std::string& world_frame, const std::string& gimbal_frame,
                                    const std::string& dut_frame) {
  tf2_msgs::TFMessage msg;
  msg.transforms.push_back(
      make_transform(stamp, world_frame, gimbal_frame, transforms.world_gimbal));
  msg.transforms.push_back(make_transform(stamp, gimbal_frame, dut_frame, transforms.gimbal_dut));
  return msg;
}

GimbalControllerOptions GimbalControllerOptions::load(const ros::NodeHandle& pnh) {
  GimbalControllerOptions o;
  o.protocol = read_protocol(pnh);
  read_param(pnh, "autostart", &o.autostart);
  read_param(pnh, "start_delay_s", &o.start_delay_s);
  require(std::isfinite(o.start_delay_s) && o.start_delay_s >= 0.0, pnh, "start_delay_s",
          "must be finite and >= 0 s");
  read_param(pnh, "tick_hz", &o.tick_hz);
  require(std::isfinite(o.tick_hz) && o.tick_hz >= 1.0 && o.tick_hz <= 10000.0, pnh, "tick_hz",
          "must be in [1, 10000] Hz");
  read_param(pnh, "progress_hz", &o.progress_hz);
  require(std::isfinite(o.progress_hz) && o.progress_hz > 0.0, pnh, "progress_hz",
          "must be > 0 Hz");
  read_param(pnh, "settle_timeout_s", &o.settle_timeout_s);
  require(std::isfinite(o.settle_timeout_s) && o.settle_timeout_s > 0.0, pnh, "settle_timeout_s",
          "must be > 0 s");
  read_param(pnh, "resume_phase", &o.resume_phase);
  require(o.resume_phase.empty() || o.resume_phase == "x" || o.resume_phase == "y" ||
              o.resume_phase == "z",
          pnh, "resume_phase", "must be x, y or z (or empty: from the start)");
  read_param(pnh, "resume_step", &o.resume_step);
  // Step N is the closing position at 2 pi, part of the schedule only with closing_position.
  require(o.resume_step < o.protocol.steps_per_phase ||
              (o.protocol.closing_position && o.resume_step == o.protocol.steps_per_phase),
          pnh, "resume_step",
          "must be below steps (" + std::to_string(o.protocol.steps_per_phase) + ")" +
              (o.protocol.closing_position ? ", or equal to it (the closing position)" : ""));
  read_param(pnh, "resume_approach", &o.resume_approach);
  require(o.resume_approach == 1 || o.resume_approach == -1, pnh, "resume_approach",
          "must be +1 (up sweep) or -1 (return sweep)");
  require(o.resume_approach == 1 || o.protocol.two_way, pnh, "resume_approach",
          "-1 needs two_way: true");
  require(o.resume_approach == 1 || o.resume_step < o.protocol.steps_per_phase, pnh,
          "resume_approach", "the closing position is only approached from below (+1)");
  read_param(pnh, "driver", &o.driver);
  require(o.driver == "simulated" || o.driver == "grbl" || o.driver == "smc100", pnh, "driver",
          "unknown gimbal driver '" + o.driver + "' (known: simulated, grbl, smc100)");
  if (o.driver != "simulated") read_serial_options(pnh, o.driver, &o);
  read_param(pnh, "world_frame", &o.world_frame);
  read_param(pnh, "gimbal_frame", &o.gimbal_frame);
  read_param(pnh, "dut_frame", &o.dut_frame);
  require(!o.world_frame.empty(), pnh, "world_frame", "must not be empty");
  require(!o.gimbal_frame.empty(), pnh, "gimbal_frame", "must not be empty");
  require(!o.dut_frame.empty(), pnh, "dut_frame", "must not be empty");

  // The simulated gimbal: by default it moves and settles in the protocol's times.
  const ros::NodeHandle sim(pnh, "simulated");
  o.simulated.move_s = o.protocol.move_s;
  o.simulated.settle_s = o.protocol.settle_s;
  o.simulated.phase_change_s = o.protocol.phase_change_s;
  read_param(sim, "move_s", &o.simulated.move_s);
  read_param(sim, "settle_s", &o.simulated.settle_s);
  read_param(sim, "phase_change_s", &o.simulated.phase_change_s);
  read_param(sim, "ringing_rad", &o.simulated.ringing_rad);
  read_param(sim, "ringing_hz", &o.simulated.ringing_hz);
  read_effects(sim, "effects", &o.simulated.effects);
  read_param(sim, "never_settle_phase", &o.simulated.never_settle_phase);
  read_param(sim, "never_settle_at_step", &o.simulated.never_settle_at_step);
  try {
    o.simulated.validate();
  } catch (const std::invalid_argument& e) {
    throw ParamError("parameter " + sim.getNamespace() + "/" + e.what());
  }
  return o;
}

std::unique_ptr<GimbalDriver> make_gimbal_driver(const GimbalControllerOptions& options) {
  if (options.driver == "simulated") {
    return std::unique_ptr<GimbalDriver>(new SimulatedGimbalDriver(options.simulated));
  }
  // A serial gimbal that cannot be brought up (port missing, no reply, alarm at start) keeps the
  // node from starting, with the device's words.
  try {
    if (options.driver == "grbl") {
      return std::unique_ptr<GimbalDriver>(new GrblDriver(options.serial));
    }
    if (options.driver == "smc100") {
      return std::unique_ptr<GimbalDriver>(new Smc100Driver(options.serial));
    }
  } catch (const GimbalFault& e) {
    throw ParamError(std::string("the gimbal did not start: ") + e.what());
  }
  throw ParamError("unknown gimbal driver '" + options.driver + "'");
}

const char* GimbalControllerNode::state_name(State state) {
  switch (state) {
    case State::Idle: return "IDLE";
    case State::Starting: return "STARTING";
    case State::Moving: return "MOVING";
    case State::Dwelling: return "SETTLED";
    case State::Remount: return "REMOUNT";
    case State::Done: return "DONE";
    case State::Aborted: return "ABORTED";
  }
  return "?";
}

GimbalControllerNode::GimbalControllerNode(ros::NodeHandle nh, ros::NodeHandle pnh,
                                           const GimbalControllerOptions& options,
                                           std::unique_ptr<GimbalDriver> driver)
    : nh_(nh), pnh_(pnh), options_(options), driver_(std::move(driver)) {
  schedule_ = core::build_schedule(options_.protocol);
  command_pub_ = nh_.advertise<GimbalCommand>(names::kGimbalCommandTopic, 100);
  tf_pub_ = nh_.advertise<tf2_msgs::TFMessage>(names::kTfTopic, 100);
  progress_pub_ = nh_.advertise<diagnostic_msgs::DiagnosticStatus>(names::kProgressTopic, 10, true);
  start_srv_ = nh_.advertiseService(names::kStartService, &GimbalControllerNode::on_start, this);
  abort_srv_ = nh_.advertiseService(names::kAbortService, &GimbalControllerNode::on_abort, this);
  abort_run_srv_ =
      nh_.advertiseService(names::kAbortRunService, &GimbalControllerNode::on_abort_run, this);
  resume_srv_ = nh_.advertiseService(names::kResumeService, &GimbalControllerNode::on_resume, this);
  continue_srv_ =
      nh_.advertiseService(names::kContinueService, &GimbalControllerNode::on_continue, this);
  updater_.reset(new diagnostic_updater::Updater(nh_, pnh_));
  updater_->setHardwareID(driver_->name() + " gimbal " + nh_.getNamespace());
  updater_->add("protocol", this, &GimbalControllerNode::diagnose);
  autostart_pending_ = options_.autostart;
  if (!options_.resume_phase.empty()) {
    const core::Phase phase = options_.resume_phase == "x"   ? core::Phase::X
                              : options_.resume_phase == "y" ? core::Phase::Y
                                                             : core::Phase::Z;
    start_index_ = find_position(phase, options_.resume_step, options_.resume_approach, false);
    ROS_WARN("gimbal controller: runs begin at phase %s step %u (position %zu of %zu)",
             options_.resume_phase.c_str(), options_.resume_step, start_index_ + 1,
             schedule_.size());
  }
  timer_ =
      nh_.createTimer(ros::Duration(1.0 / options_.tick_hz), &GimbalControllerNode::on_timer, this);
  ROS_INFO("gimbal controller: %s driver, %zu positions (N = %u per phase%s%s), about %.0f s; %s",
           driver_->name().c_str(), schedule_.size(), options_.protocol.steps_per_phase,
           options_.protocol.two_way ? ", two-way" : "",
           options_.protocol.closing_position ? ", closing position at 360 deg" : "",
           schedule_.empty() ? 0.0 : schedule_.back().dwell_end_s + options_.start_delay_s,
           options_.autostart ? "autostart"
                              : ("waiting for " + nh_.resolveName(names::kStartService)).c_str());
}

void GimbalControllerNode::on_timer(const ros::TimerEvent&) {
  const ros::Time now = ros::Time::now();
  if (now.isZero()) return;  // no clock yet (use_sim_time)
  tick(now);
}

bool GimbalControllerNode::start(const ros::Time& now, std::string* message) {
  if (state_ == State::Starting || running()) {
    std::ostringstream s;
    s << "already running (" << state_name(state_) << " phase "
      << core::phase_name(schedule_[index_].phase) << " step " << schedule_[index_].step << ")";
    *message = s.str();
    return false;
  }
  if (!recover_driver(now)) {
    *message = "start refused: " + last_error_;
    return false;
  }
  state_ = State::Starting;
  state_since_ = now;
  start_at_ = now + ros::Duration(options_.start_delay_s);
  index_ = start_index_;
  start_index_ = 0;  // the resume_* parameters place the first run only
  last_error_.clear();
  std::ostringstream s;
  s << "started: " << schedule_.size() << " positions, about " << num(time_left_s(now), 0) << " s";
  *message = s.str();
  ROS_INFO("gimbal controller: %s", message->c_str());
  publish_progress(now, false);
  return true;
}

bool GimbalControllerNode::abort(const ros::Time& now, const std::string& reason,
                                 std::string* message) {
  if (state_ != State::Starting && !running()) {
    *message = std::string("not running (") + state_name(state_) + ")";
    return false;
  }
  const bool had_commands = state_ != State::Starting;
  driver_->stop(now.toSec());
  if (had_commands) {
    // DONE ends the run and closes the open dwell; the calibration node then reports what is
    // missing. The progress topic says ABORTED.
    publish_command(now, GimbalCommand::DONE, schedule_[index_]);
  }
  state_ = State::Aborted;
  state_since_ = now;
  last_error_ = reason;
  *message = "aborted: " + reason;
  ROS_WARN("gimbal controller: %s", message->c_str());
  publish_progress(now, false);
  return true;
}

bool GimbalControllerNode::continue_after_remount(const ros::Time& now, std::string* message) {
  if (state_ != State::Remount) {
    *message = std::string("not waiting for a remount (") + state_name(state_) + ")";
    return false;
  }
  const core::ScheduledPosition& p = schedule_[index_];
  state_ = State::Moving;
  state_since_ = now;
  // The move again: the settling time starts now, after the operator's hands left the DUT.
  if (!drive(now)) {
    *message = "continue failed: " + last_error_;
    return false;
  }
  *message = std::string("continuing with phase ") + core::phase_name(p.phase);
  ROS_INFO("gimbal controller: remount done, %s", message->c_str());
  publish_progress(now, false);
  return true;
}

bool GimbalControllerNode::on_continue(std_srvs::Trigger::Request&,
                                       std_srvs::Trigger::Response& res) {
  res.success = continue_after_remount(ros::Time::now(), &res.message);
  return true;
}

bool GimbalControllerNode::on_start(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  res.success = start(ros::Time::now(), &res.message);
  return true;
}

bool GimbalControllerNode::on_abort(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  // The contract's Trigger: no reason travels with it (abort_run takes one).
  res.success = abort(ros::Time::now(), "abort requested", &res.message);
  return true;
}

bool GimbalControllerNode::on_abort_run(AbortRun::Request& req, AbortRun::Response& res) {
  res.success =
      abort(ros::Time::now(), req.reason.empty() ? "abort requested" : req.reason, &res.message);
  return true;
}

std::size_t GimbalControllerNode::find_position(core::Phase phase, std::uint32_t step, int approach,
                                                bool after) const {
  for (std::size_t i = 0; i < schedule_.size(); ++i) {
    const core::ScheduledPosition& p = schedule_[i];
    if (p.phase == phase && p.step == step && p.approach == approach) return after ? i + 1 : i;
  }
  return schedule_.size();
}

bool GimbalControllerNode::on_resume(ResumeAt::Request& req, ResumeAt::Response& res) {
  const std::string reason = req.reason.empty() ? "resume requested" : req.reason;
  if (req.phase > ResumeAt::Request::PHASE_Z || (req.approach != 1 && req.approach != -1)) {
    res.success = false;
    res.message = "phase must be 0, 1 or 2 (x, y, z) and approach +1 or -1 (got phase " +
                  std::to_string(req.phase) + ", approach " + std::to_string(req.approach) + ")";
    return true;
  }
  const core::Phase phase = static_cast<core::Phase>(req.phase);
  const std::size_t index = find_position(phase, req.step, req.approach, false);
  if (index >= schedule_.size()) {
    res.success = false;
    res.message = std::string("no position phase ") + core::phase_name(phase) + " step " +
                  std::to_string(req.step) + " approach " + std::to_string(req.approach) +
                  " in the protocol";
    return true;
  }
  const ros::Time now = ros::Time::now();
  res.success = resume(now, req.after ? index + 1 : index, reason, &res.message);
  res.stamp = now;
  return true;
}

bool GimbalControllerNode::resume(const ros::Time& now, std::size_t index,
                                  const std::string& reason, std::string* message) {
  ++resumes_;
  if (!recover_driver(now)) {
    *message = "resume refused: " + last_error_;
    return false;
  }
  std::ostringstream s;
  s.precision(17);
  if (index >= schedule_.size()) {
    // Nothing left after that position: the protocol is complete.
    if (running()) driver_->stop(now.toSec());
    index_ = schedule_.size() - 1;
    publish_command(now, GimbalCommand::DONE, schedule_[index_]);
    state_ = State::Done;
    state_since_ = now;
    s << "resume (" << reason << "): nothing left, DONE stamp=" << now.toSec();
  } else {
    begin_move(index, now);
    const core::ScheduledPosition& p = schedule_[index];
    s << "resume (" << reason << "): moving to phase " << core::phase_name(p.phase) << " step "
      << p.step << (p.approach < 0 ? " (return sweep)" : "") << ", position " << index + 1 << " of "
      << schedule_.size() << ", MOVING stamp=" << now.toSec();
  }
  last_error_.clear();
  *message = s.str();
  ROS_WARN("gimbal controller: %s", message->c_str());
  publish_progress(now, false);
  return true;
}

void GimbalControllerNode::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  const ros::Time now = ros::Time::now();
  const core::ScheduledPosition& p = schedule_[std::min(index_, schedule_.size() - 1)];
  const bool running = this->running();
  if (state_ == State::Aborted) {
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "aborted: " + last_error_);
  } else if (state_ == State::Remount) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                   std::string("waiting for the operator to remount the DUT for phase ") +
                       core::phase_name(p.phase));
  } else if (state_ == State::Moving &&
             (now - state_since_).toSec() > 0.5 * options_.settle_timeout_s) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "the gimbal is slow to settle");
  } else {
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, state_name(state_));
  }
  status.add("state", state_name(state_));
  status.add("phase", running ? core::phase_name(p.phase) : "");
  status.add("step", running ? std::to_string(p.step) : "");
  status.add("steps", options_.protocol.steps_per_phase);
  status.add("position", running ? index_ + 1 : (state_ == State::Done ? schedule_.size() : 0));
  status.add("positions", schedule_.size());
  status.add("time_left_s", time_left_s(now));
  status.add("in_state_s", state_since_.isZero() ? 0.0 : (now - state_since_).toSec());
  status.add("resumes", resumes_);
  status.add("last_error", last_error_);
}

void GimbalControllerNode::begin_move(std::size_t index, const ros::Time& now) {
  index_ = index;
  const core::ScheduledPosition& p = schedule_[index_];
  // The command goes out first with this stamp; the gimbal starts moving at the same instant,
  // so every sample stamped before it was taken at rest.
  publish_command(now, GimbalCommand::MOVING, p);
  state_ = State::Moving;
  state_since_ = now;
  drive(now);
}

bool GimbalControllerNode::drive(const ros::Time& now) {
  try {
    driver_->move_to(target_of(schedule_[index_]), now.toSec());
  } catch (const GimbalFault& e) {
    driver_fault(now, e.what());
    return false;
  }
  return true;
}

bool GimbalControllerNode::recover_driver(const ros::Time& now) {
  if (!faulted_) return true;
  try {
    driver_->recover(now.toSec());
  } catch (const GimbalFault& e) {
    last_error_ = std::string("could not recover the gimbal after its fault: ") + e.what();
    ROS_ERROR("gimbal controller: %s", last_error_.c_str());
    publish_progress(now, false);
    return false;
  }
  faulted_ = false;
  ROS_WARN("gimbal controller: the %s gimbal recovered from its fault", driver_->name().c_str());
  return true;
}

void GimbalControllerNode::driver_fault(const ros::Time& now, const std::string& what) {
  faulted_ = true;
  std::string message;
  if (!abort(now, std::string("gimbal fault: ") + what, &message)) {
    last_error_ = std::string("gimbal fault: ") + what;
  }
  ROS_ERROR("gimbal controller: %s", last_error_.c_str());
}

void GimbalControllerNode::tick(const ros::Time& now) {
  if (autostart_pending_) {
    autostart_pending_ = false;
    std::string message;
    start(now, &message);
  }
  // The hardware first: status polls, which may find a fault. A faulted device is left alone
  // until a start or resume recovers it (a silent one would block every tick).
  try {
    if (!faulted_) driver_->update(now.toSec());
  } catch (const GimbalFault& e) {
    if (state_ == State::Starting || running()) {
      driver_fault(now, e.what());
    } else {
      ROS_WARN_THROTTLE(10.0, "gimbal controller: %s", e.what());
    }
  }
  bool changed = false;
  switch (state_) {
    case State::Starting:
      if (now >= start_at_) {
        begin_move(index_, now);
        changed = true;
      }
      break;
    case State::Moving:
      if (driver_->settled(now.toSec())) {
        // Stamped when the gimbal settled, which the driver may know better than this tick
        // (the simulated one does; the timing-lag estimator reads the move from these stamps).
        ros::Time settled_stamp = now;
        const double settled_s = driver_->settled_at(now.toSec());
        if (std::isfinite(settled_s) && settled_s > state_since_.toSec() && settled_s < now.toSec())
          settled_stamp.fromSec(settled_s);
        publish_command(settled_stamp, GimbalCommand::SETTLED, schedule_[index_]);
        state_ = State::Dwelling;
        state_since_ = settled_stamp;
        changed = true;
      } else if ((now - state_since_).toSec() > options_.settle_timeout_s) {
        std::string message;
        std::ostringstream reason;
        reason << "the gimbal did not settle at phase " << core::phase_name(schedule_[index_].phase)
               << " step " << schedule_[index_].step
               << " within settle_timeout_s = " << options_.settle_timeout_s << " s";
        const std::string device = driver_->status_text();
        if (!device.empty()) reason << " (" << driver_->name() << " reports " << device << ")";
        abort(now, reason.str(), &message);
        ROS_ERROR("gimbal controller: %s", message.c_str());
      }
      break;
    case State::Dwelling:
      if ((now - state_since_).toSec() >= options_.protocol.dwell_s) {
        if (index_ + 1 < schedule_.size()) {
          const core::Phase from = schedule_[index_].phase;
          begin_move(index_ + 1, now);
          const core::Phase to = schedule_[index_].phase;
          if (state_ == State::Moving && to != from && driver_->manual_remount(to)) {
            // MOVING went out (the dwell is closed) and the stage turns to the phase's first
            // position; the operator remounts the DUT there and calls continue.
            state_ = State::Remount;
            ROS_WARN(
                "gimbal controller: remount the DUT for phase %s (it turns about its own %s "
                "axis), then call %s",
                core::phase_name(to), core::phase_name(to),
                nh_.resolveName(names::kContinueService).c_str());
          }
        } else {
          publish_command(now, GimbalCommand::DONE, schedule_[index_]);
          state_ = State::Done;
          state_since_ = now;
          ROS_INFO("gimbal controller: protocol done (%zu positions)", schedule_.size());
        }
        changed = true;
      }
      break;
    default: break;
  }
  publish_tf(now);
  if (updater_) updater_->update();
  const bool periodic = (now - last_progress_).toSec() >= 1.0 / options_.progress_hz;
  if (changed || periodic || now < last_progress_) publish_progress(now, periodic);
}

void GimbalControllerNode::publish_command(const ros::Time& now, std::uint8_t state,
                                           const core::ScheduledPosition& p) {
  GimbalCommand msg;
  msg.header.stamp = now;
  msg.header.frame_id = options_.gimbal_frame;
  msg.phase = static_cast<std::uint8_t>(core::index(p.phase));
  msg.step = p.step;
  msg.steps = p.steps;
  msg.angle = p.angle_rad;
  msg.state = state;
  command_pub_.publish(msg);
  ROS_DEBUG("gimbal/command %s phase %s step %u/%u angle %.4f rad",
            state == GimbalCommand::MOVING    ? "MOVING"
            : state == GimbalCommand::SETTLED ? "SETTLED"
                                              : "DONE",
            core::phase_name(p.phase), p.step, p.steps, p.angle_rad);
}

void GimbalControllerNode::publish_tf(const ros::Time& now) {
  if (now <= last_tf_ && !(now < last_tf_ - ros::Duration(1.0))) return;  // one per stamp
  // The tf stream keeps tick_hz resolution on the node clock even when that clock advances in
  // coarser steps (a simulated clock at time_scale): the stamps in between are filled in, so the
  // sensor's tf lookups interpolate over one tick, not over a clock step. Not across a jump.
  tf2_msgs::TFMessage msg;
  const ros::Duration tick(1.0 / options_.tick_hz);
  if (!last_tf_.isZero() && now > last_tf_ && now - last_tf_ <= ros::Duration(1.0)) {
    for (ros::Time t = last_tf_ + tick; t < now; t += tick) {
      const tf2_msgs::TFMessage at =
          make_tf_message(driver_->orientation(t.toSec()), t, options_.world_frame,
                          options_.gimbal_frame, options_.dut_frame);
      msg.transforms.insert(msg.transforms.end(), at.transforms.begin(), at.transforms.end());
    }
  }
  const tf2_msgs::TFMessage at_now =
      make_tf_message(driver_->orientation(now.toSec()), now, options_.world_frame,
                      options_.gimbal_frame, options_.dut_frame);
  msg.transforms.insert(msg.transforms.end(), at_now.transforms.begin(), at_now.transforms.end());
  last_tf_ = now;
  tf_pub_.publish(msg);
}

double GimbalControllerNode::time_left_s(const ros::Time& now) const {
  if (schedule_.empty()) return 0.0;
  const double total = schedule_.back().dwell_end_s;
  const double since = std::max(0.0, (now - state_since_).toSec());
  const core::ScheduledPosition& p = schedule_[index_];
  switch (state_) {
    case State::Idle: return total + options_.start_delay_s;
    case State::Starting: return total + std::max(0.0, (start_at_ - now).toSec());
    case State::Moving:
    case State::Remount:
      return std::max(0.0, total - std::min(p.settled_s, p.move_start_s + since));
    case State::Dwelling:
      return std::max(0.0, total - std::min(p.dwell_end_s, p.settled_s + since));
    default: return 0.0;
  }
}

void GimbalControllerNode::publish_progress(const ros::Time& now, bool log) {
  last_progress_ = now;
  const core::ScheduledPosition& p = schedule_[std::min(index_, schedule_.size() - 1)];
  const bool running = this->running();
  // 1-based number of the position being visited; all of them once done.
  const std::size_t position =
      state_ == State::Done ? schedule_.size() : (running ? index_ + 1 : 0);
  const double left = time_left_s(now);
  const double total = schedule_.back().dwell_end_s;
  const double fraction =
      state_ == State::Done ? 1.0 : std::min(1.0, std::max(0.0, 1.0 - left / total));

  diagnostic_msgs::DiagnosticStatus msg;
  msg.name = nh_.resolveName("gimbal_controller");
  msg.hardware_id = driver_->name();
  msg.level = state_ == State::Aborted   ? diagnostic_msgs::DiagnosticStatus::ERROR
              : state_ == State::Remount ? diagnostic_msgs::DiagnosticStatus::WARN
                                         : diagnostic_msgs::DiagnosticStatus::OK;
  std::ostringstream text;
  text << state_name(state_);
  if (running) {
    text << " phase " << core::phase_name(p.phase) << " step " << p.step + 1 << "/" << p.steps;
    if (core::is_closing_step(p.step, p.steps)) text << " (closing position, 360 deg)";
  }
  if (state_ == State::Aborted) text << ": " << last_error_;
  if (state_ == State::Remount) {
    text << ": remount the DUT to turn about its own " << core::phase_name(p.phase)
         << " axis, then call " << nh_.resolveName(names::kContinueService);
  }
  msg.message = text.str();
  msg.values.push_back(kv("state", state_name(state_)));
  msg.values.push_back(kv("phase", running ? core::phase_name(p.phase) : ""));
  msg.values.push_back(kv("step", running ? std::to_string(p.step) : ""));
  msg.values.push_back(kv("steps", std::to_string(options_.protocol.steps_per_phase)));
  msg.values.push_back(kv("position", std::to_string(position)));
  msg.values.push_back(kv("positions", std::to_string(schedule_.size())));
  msg.values.push_back(kv("fraction", num(fraction, 4)));
  msg.values.push_back(kv("time_left_s", num(left, 1)));
  msg.values.push_back(kv("stamp", num(now.toSec(), 3)));
  progress_pub_.publish(msg);
  if (log && running) {
    ROS_INFO("gimbal controller: %s, %.0f%%, %.0f s left", msg.message.c_str(), 100.0 * fraction,
             left);
  }
}

}  // namespace accel_intrinsics
