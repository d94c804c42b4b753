// Gimbal controller node: the shell of core::GimbalProtocol (parameters in
// gimbal_controller_options.cpp): timer, services, gimbal/command, tf, progress, diagnostics.
#include "accel_intrinsics/ros/gimbal_controller_node.h"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <diagnostic_msgs/KeyValue.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64.h>
#include <tf2_msgs/TFMessage.h>

#include <sstream>

#include "accel_intrinsics/ros/conversions.h"
#include "accel_intrinsics/ros/names.h"

namespace accel_intrinsics {

namespace {

static_assert(GimbalCommand::MOVING == static_cast<int>(core::GimbalState::Moving) &&
                  GimbalCommand::SETTLED == static_cast<int>(core::GimbalState::Settled) &&
                  GimbalCommand::DONE == static_cast<int>(core::GimbalState::Done),
              "core::GimbalState mirrors GimbalCommand's constants");

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

// The stamp of an action: `now` itself when the protocol stamped it now (no round trip through
// double, which would move a wall-clock stamp by up to a microsecond), else the time it names.
ros::Time stamp_of(double stamp_s, const ros::Time& now) {
  if (stamp_s == now.toSec()) return now;
  ros::Time t;
  t.fromSec(stamp_s);
  return t;
}

core::GimbalProtocolOptions protocol_options(const GimbalControllerOptions& o,
                                             const ros::NodeHandle& nh) {
  core::GimbalProtocolOptions p;
  p.protocol = o.protocol;
  p.autostart = o.autostart;
  p.start_delay_s = o.start_delay_s;
  p.settle_timeout_s = o.settle_timeout_s;
  p.progress_hz = o.progress_hz;
  p.continue_service = nh.resolveName(names::kContinueService);
  return p;
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

GimbalControllerNode::GimbalControllerNode(ros::NodeHandle nh, ros::NodeHandle pnh,
                                           const GimbalControllerOptions& options,
                                           std::unique_ptr<GimbalDriver> driver)
    : nh_(nh), pnh_(pnh), options_(options), driver_(std::move(driver)) {
  protocol_.reset(new core::GimbalProtocol(protocol_options(options_, nh_), driver_.get()));
  const std::vector<core::ScheduledPosition>& schedule = protocol_->schedule();
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
  wire_driver_topics();
  updater_.reset(new diagnostic_updater::Updater(nh_, pnh_));
  updater_->setHardwareID(driver_->name() + " gimbal " + nh_.getNamespace());
  updater_->add("protocol", this, &GimbalControllerNode::diagnose);
  if (!options_.resume_phase.empty()) {
    core::Phase phase = core::Phase::X;
    core::parse_phase(options_.resume_phase, &phase);
    const std::size_t first =
        find_position(phase, options_.resume_step, options_.resume_approach, false);
    protocol_->start_next_run_at(first);
    ROS_WARN("gimbal controller: runs begin at phase %s step %u (position %zu of %zu)",
             options_.resume_phase.c_str(), options_.resume_step, first + 1, schedule.size());
  }
  timer_ =
      nh_.createTimer(ros::Duration(1.0 / options_.tick_hz), &GimbalControllerNode::on_timer, this);
  ROS_INFO("gimbal controller: %s driver, %zu positions (N = %u per phase%s%s), about %.0f s; %s",
           driver_->name().c_str(), schedule.size(), options_.protocol.steps_per_phase,
           options_.protocol.two_way ? ", two-way" : "",
           options_.protocol.closing_position ? ", closing position at 360 deg" : "",
           schedule.back().dwell_end_s + options_.start_delay_s,
           options_.autostart ? "autostart"
                              : ("waiting for " + nh_.resolveName(names::kStartService)).c_str());
}

void GimbalControllerNode::wire_driver_topics() {
  const GimbalDriverTopics topics = driver_->topics();
  for (const std::string& topic : topics.command_topics) {
    if (joint_command_pubs_.count(topic) == 0)
      joint_command_pubs_[topic] = nh_.advertise<std_msgs::Float64>(topic, 10);
  }
  // The messages go to the driver as plain calls, at the time they arrive on the node clock
  // (JointState: taken at each tick, before the driver's update, at the tick's time).
  if (!topics.joint_states.empty()) {
    ros::NodeHandle joint_nh(nh_);
    joint_nh.setCallbackQueue(&joint_state_queue_);
    joint_state_sub_ = joint_nh.subscribe<sensor_msgs::JointState>(
        topics.joint_states, 1000, [this](const sensor_msgs::JointState::ConstPtr& msg) {
          driver_->on_joint_state(ros::Time::now().toSec(), msg->name, msg->position);
        });
  }
  if (!topics.imu.empty()) {
    imu_sub_ = nh_.subscribe<sensor_msgs::Imu>(
        topics.imu, 1000, [this](const sensor_msgs::Imu::ConstPtr& msg) {
          // Arrival time: only samples after the operator's continue count, whatever the IMU's
          // own clock says.
          driver_->on_imu(ros::Time::now().toSec(),
                          Eigen::Vector3d(msg->linear_acceleration.x, msg->linear_acceleration.y,
                                          msg->linear_acceleration.z));
        });
  }
  driver_->connect(this);
}

void GimbalControllerNode::publish_command(const std::string& topic, double position_rad) {
  const auto it = joint_command_pubs_.find(topic);
  if (it == joint_command_pubs_.end()) return;
  std_msgs::Float64 msg;
  msg.data = position_rad;
  it->second.publish(msg);
}

void GimbalControllerNode::on_timer(const ros::TimerEvent&) {
  const ros::Time now = ros::Time::now();
  if (now.isZero()) return;  // no clock yet (use_sim_time)
  tick(now);
}

void GimbalControllerNode::tick(const ros::Time& now) {
  joint_state_queue_.callAvailable();
  carry_out(protocol_->tick(now.toSec()), now);
  publish_tf(now);
  if (updater_) updater_->update();
}

bool GimbalControllerNode::reply(const core::ProtocolReply& r, const ros::Time& now,
                                 std::string* message) {
  carry_out(r.actions, now);
  *message = r.message;
  return r.success;
}

bool GimbalControllerNode::start(const ros::Time& now, std::string* message) {
  return reply(protocol_->start(now.toSec()), now, message);
}

bool GimbalControllerNode::abort(const ros::Time& now, const std::string& reason,
                                 std::string* message) {
  return reply(protocol_->abort(now.toSec(), reason), now, message);
}

bool GimbalControllerNode::continue_after_remount(const ros::Time& now, std::string* message) {
  return reply(protocol_->continue_after_remount(now.toSec()), now, message);
}

bool GimbalControllerNode::resume(const ros::Time& now, std::size_t index,
                                  const std::string& reason, std::string* message) {
  return reply(protocol_->resume(now.toSec(), index, reason), now, message);
}

void GimbalControllerNode::carry_out(const core::ProtocolActions& actions, const ros::Time& now) {
  using Action = core::ProtocolAction;
  for (const Action& a : actions) {
    switch (a.kind) {
      case Action::Kind::Command: {
        GimbalCommand msg = to_msg(a.command);
        msg.header.stamp = stamp_of(a.command.stamp_s, now);
        msg.header.frame_id = options_.gimbal_frame;
        command_pub_.publish(msg);
        ROS_DEBUG("gimbal/command %s phase %s step %u/%u angle %.4f rad",
                  msg.state == GimbalCommand::MOVING    ? "MOVING"
                  : msg.state == GimbalCommand::SETTLED ? "SETTLED"
                                                        : "DONE",
                  core::phase_name(a.command.phase), msg.step, msg.steps, msg.angle);
        break;
      }
      case Action::Kind::Log:
        if (a.repeating) {
          ROS_WARN_THROTTLE(10.0, "gimbal controller: %s", a.text.c_str());
        } else if (a.level == Action::Level::Error) {
          ROS_ERROR("gimbal controller: %s", a.text.c_str());
        } else if (a.level == Action::Level::Warn) {
          ROS_WARN("gimbal controller: %s", a.text.c_str());
        } else {
          ROS_INFO("gimbal controller: %s", a.text.c_str());
        }
        break;
      case Action::Kind::Progress: publish_progress(now, a.status, a.log); break;
    }
  }
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

bool GimbalControllerNode::on_continue(std_srvs::Trigger::Request&,
                                       std_srvs::Trigger::Response& res) {
  res.success = continue_after_remount(ros::Time::now(), &res.message);
  return true;
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
  if (index >= protocol_->schedule().size()) {
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

void GimbalControllerNode::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status) {
  const core::ProtocolStatus s = protocol_->status(ros::Time::now().toSec());
  if (s.state == State::Aborted) {
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "aborted: " + s.last_error);
  } else if (s.state == State::WaitOperator) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                   "waiting for the operator: " + s.operator_request);
  } else if (s.state == State::Remount) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                   std::string("waiting for the operator to remount the DUT for phase ") +
                       core::phase_name(s.position.phase));
  } else if (s.slow_to_settle) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "the gimbal is slow to settle");
  } else {
    status.summary(diagnostic_msgs::DiagnosticStatus::OK, state_name(s.state));
  }
  status.add("state", state_name(s.state));
  status.add("phase", s.running ? core::phase_name(s.position.phase) : "");
  status.add("step", s.running ? std::to_string(s.position.step) : "");
  status.add("steps", options_.protocol.steps_per_phase);
  status.add("position", s.position_number);
  status.add("positions", s.positions);
  status.add("time_left_s", s.time_left_s);
  status.add("in_state_s", s.in_state_s);
  status.add("resumes", s.resumes);
  status.add("last_error", s.last_error);
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

void GimbalControllerNode::publish_progress(const ros::Time& now, const core::ProtocolStatus& s,
                                            bool log) {
  diagnostic_msgs::DiagnosticStatus msg;
  msg.name = nh_.resolveName("gimbal_controller");
  msg.hardware_id = driver_->name();
  msg.level =
      s.level == core::ProtocolStatus::Level::Error  ? diagnostic_msgs::DiagnosticStatus::ERROR
      : s.level == core::ProtocolStatus::Level::Warn ? diagnostic_msgs::DiagnosticStatus::WARN
                                                     : diagnostic_msgs::DiagnosticStatus::OK;
  msg.message = s.text;
  msg.values.push_back(kv("state", state_name(s.state)));
  msg.values.push_back(kv("phase", s.running ? core::phase_name(s.position.phase) : ""));
  msg.values.push_back(kv("step", s.running ? std::to_string(s.position.step) : ""));
  msg.values.push_back(kv("steps", std::to_string(options_.protocol.steps_per_phase)));
  msg.values.push_back(kv("position", std::to_string(s.position_number)));
  msg.values.push_back(kv("positions", std::to_string(s.positions)));
  msg.values.push_back(kv("fraction", num(s.fraction, 4)));
  msg.values.push_back(kv("time_left_s", num(s.time_left_s, 1)));
  msg.values.push_back(kv("stamp", num(now.toSec(), 3)));
  msg.values.push_back(kv("operator_waits", std::to_string(s.operator_waits)));
  if (s.state == State::WaitOperator) {
    // What supervise asks the operator, and the target's stage positions (deg).
    msg.values.push_back(kv("request", s.operator_request));
    msg.values.push_back(kv("pose_check", s.operator_complaint));
    for (const auto& a : s.stage_deg)
      msg.values.push_back(kv("stage_" + a.first + "_deg", num(a.second, 3)));
  }
  progress_pub_.publish(msg);
  if (log && s.running) {
    ROS_INFO("gimbal controller: %s, %.0f%%, %.0f s left", msg.message.c_str(), 100.0 * s.fraction,
             s.time_left_s);
  }
}

}  // namespace accel_intrinsics
