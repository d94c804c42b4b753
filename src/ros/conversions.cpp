// Conversions between ROS messages and the ROS-free core types (conversions.h).
#include "accel_intrinsics/ros/conversions.h"

#include <diagnostic_msgs/KeyValue.h>

#include <algorithm>
#include <cmath>

#include "accel_intrinsics/core/fit/quality.h"

namespace accel_intrinsics {

namespace {

core::Phase phase_from_msg(std::uint8_t phase) {
  switch (phase) {
    case GimbalCommand::PHASE_X: return core::Phase::X;
    case GimbalCommand::PHASE_Y: return core::Phase::Y;
    default: return core::Phase::Z;
  }
}

geometry_msgs::Vector3 to_vector3(const Eigen::Vector3d& v) {
  geometry_msgs::Vector3 out;
  out.x = v.x();
  out.y = v.y();
  out.z = v.z();
  return out;
}

}  // namespace

core::GimbalEvent to_core(const GimbalCommand& msg) {
  core::GimbalEvent event;
  event.stamp_s = msg.header.stamp.toSec();
  event.phase = phase_from_msg(msg.phase);
  event.step = msg.step;
  event.steps = msg.steps;
  event.angle_rad = msg.angle;
  switch (msg.state) {
    case GimbalCommand::SETTLED: event.state = core::GimbalState::Settled; break;
    case GimbalCommand::DONE: event.state = core::GimbalState::Done; break;
    default: event.state = core::GimbalState::Moving; break;
  }
  return event;
}

GimbalCommand to_msg(const core::GimbalEvent& event) {
  GimbalCommand msg;
  msg.header.stamp.fromSec(std::max(0.0, event.stamp_s));
  msg.phase = static_cast<std::uint8_t>(core::index(event.phase));
  msg.step = event.step;
  msg.steps = event.steps;
  msg.angle = event.angle_rad;
  msg.state = static_cast<std::uint8_t>(event.state);
  return msg;
}

core::ImuSample to_core(const sensor_msgs::Imu& msg) {
  core::ImuSample sample;
  sample.stamp_s = msg.header.stamp.toSec();
  sample.outputs = Eigen::Vector3d(msg.linear_acceleration.x, msg.linear_acceleration.y,
                                   msg.linear_acceleration.z);
  return sample;
}

sensor_msgs::Imu to_msg(const core::ImuSample& sample, const std::string& frame_id,
                        double variance_per_axis) {
  sensor_msgs::Imu msg;
  msg.header.stamp.fromSec(std::max(0.0, sample.stamp_s));
  msg.header.frame_id = frame_id;
  // Orientation and angular velocity are not provided (REP 145, sensor_msgs/Imu comments).
  msg.orientation.w = 1.0;
  msg.orientation_covariance.fill(0.0);
  msg.orientation_covariance[0] = -1.0;
  msg.angular_velocity_covariance.fill(0.0);
  msg.angular_velocity_covariance[0] = -1.0;
  msg.linear_acceleration.x = sample.outputs.x();
  msg.linear_acceleration.y = sample.outputs.y();
  msg.linear_acceleration.z = sample.outputs.z();
  msg.linear_acceleration_covariance.fill(0.0);
  for (int i = 0; i < 3; ++i) msg.linear_acceleration_covariance[4 * i] = variance_per_axis;
  return msg;
}

IntrinsicResult to_msg(const core::FitResult& result) {
  IntrinsicResult msg;
  msg.model = result.model_label();
  const core::Intrinsics& in = result.intrinsics;
  for (int i = 0; i < 3; ++i) {
    msg.responsivity[i] = in.responsivity(i);
    msg.responsivity_std[i] = in.responsivity_std(i);
    msg.angles_deg[i] = core::rad_to_deg(in.angles_rad(i));
    msg.angles_std_deg[i] = core::rad_to_deg(in.angles_std_rad(i));
    msg.offset[i] = result.O(i);
    msg.offset_std[i] = result.O_std(i);
    msg.positions[i] = static_cast<std::uint32_t>(std::max(0, result.positions[i]));
  }
  msg.u = to_vector3(result.S.row(0).transpose());
  msg.v = to_vector3(result.S.row(1).transpose());
  msg.w = to_vector3(result.S.row(2).transpose());
  // offset_per_phase: u_x u_y u_z v_x ... = row-major of (accelerometer x phase).
  for (int s = 0; s < 3; ++s) {
    for (int p = 0; p < 3; ++p) {
      msg.offset_per_phase[3 * s + p] = result.offset_per_phase(s, p);
      msg.cross_sensitivity[3 * s + p] = result.cross_sensitivity(s, p);
    }
  }
  msg.local_gravity = result.local_gravity;
  msg.reduced_chi2 = result.reduced_chi2;
  msg.residual_rms = result.residual_rms;
  for (std::size_t i = 0; i < result.effects.size(); ++i) {
    msg.effect_names.push_back(result.effects[i].name());
    msg.effect_targets.push_back(result.effects[i].target_name());
    msg.effect_values.push_back(result.effects[i].value);
    msg.effect_std.push_back(i < result.effects_std.size() ? result.effects_std[i] : 0.0);
  }
  return msg;
}

namespace {

diagnostic_msgs::KeyValue kv(const std::string& key, const std::string& value) {
  diagnostic_msgs::KeyValue out;
  out.key = key;
  out.value = value;
  return out;
}

// The calibration/status "state" values (scripts/supervise and the rostests read them).
const char* status_word(core::RunState state) {
  switch (state) {
    case core::RunState::Idle: return "WAITING";
    case core::RunState::Running:
    case core::RunState::Dwelling: return "COLLECTING";
    case core::RunState::WaitingForResume: return "RESUMING";
    case core::RunState::Fitting: return "FITTING";
    case core::RunState::Done: return "RESULT";
    case core::RunState::FitFailed: return "FAILED";
    case core::RunState::Aborted: return "ABORTED";
  }
  return "?";
}

// Malformed commands are refused before they reach the run (step == steps is the closing
// position at 2 pi, ProtocolOptions::closing_position).
bool is_well_formed_impl(const GimbalCommand& msg) {
  return msg.phase <= GimbalCommand::PHASE_Z && msg.state <= GimbalCommand::DONE &&
         std::isfinite(msg.angle) && core::step_in_protocol(msg.step, msg.steps) &&
         !msg.header.stamp.isZero();
}

}  // namespace

bool is_well_formed(const GimbalCommand& msg) {
  return is_well_formed_impl(msg);
}

diagnostic_msgs::DiagnosticStatus to_status_msg(const core::RunStatus& st,
                                                const std::string& message,
                                                const std::string& model, double stamp_s,
                                                const std::string& name) {
  const core::AssemblerCounters& c = st.counters;
  diagnostic_msgs::DiagnosticStatus msg;
  msg.name = name;
  msg.hardware_id = "accel_intrinsics";
  msg.level = st.fit_error.empty() && st.state != core::RunState::Aborted
                  ? diagnostic_msgs::DiagnosticStatus::OK
                  : diagnostic_msgs::DiagnosticStatus::ERROR;
  msg.message = message;
  msg.values.push_back(kv("state", status_word(st.state)));
  msg.values.push_back(kv("run_state", core::run_state_name(st.state)));
  for (core::Phase p : core::kPhases) {
    msg.values.push_back(kv(std::string("dwells_") + core::phase_name(p),
                            std::to_string(st.dwells_per_phase[core::index(p)])));
  }
  msg.values.push_back(kv("steps", std::to_string(st.steps)));
  msg.values.push_back(kv("samples_used", std::to_string(c.samples_used)));
  msg.values.push_back(kv("dropped_outside_dwell", std::to_string(c.dropped_outside_dwell)));
  msg.values.push_back(kv("dropped_settle_discard", std::to_string(c.dropped_settle_discard)));
  msg.values.push_back(kv("dropped_non_finite", std::to_string(c.dropped_non_finite)));
  msg.values.push_back(kv("dropped_backwards", std::to_string(c.dropped_backwards)));
  msg.values.push_back(kv("duplicates", std::to_string(c.duplicates)));
  msg.values.push_back(kv("dropped_late", std::to_string(c.dropped_late)));
  msg.values.push_back(kv("commands", std::to_string(c.commands)));
  msg.values.push_back(kv("commands_out_of_order", std::to_string(c.commands_out_of_order)));
  msg.values.push_back(kv("commands_rejected", std::to_string(st.commands_rejected)));
  msg.values.push_back(kv("last_warning", c.last_warning));
  msg.values.push_back(kv("fault", st.fault));
  msg.values.push_back(kv("last_fault", st.last_fault));
  msg.values.push_back(kv("retries", std::to_string(st.retries)));
  msg.values.push_back(kv("dwells_discarded", std::to_string(st.dwells_discarded)));
  msg.values.push_back(kv("restored", st.restored ? "true" : "false"));
  msg.values.push_back(kv("model", model));
  msg.values.push_back(kv("stamp", std::to_string(stamp_s)));
  return msg;
}

void diagnose_imu(const core::RunStatus& st, double rate_hz, std::uint64_t received,
                  diagnostic_updater::DiagnosticStatusWrapper* out) {
  const core::AssemblerCounters& c = st.counters;
  if (st.imu_silent) {
    out->summary(diagnostic_msgs::DiagnosticStatus::ERROR, "no IMU samples during a dwell");
  } else if (c.dropped_non_finite + c.dropped_backwards + c.dropped_late > 0) {
    out->summary(diagnostic_msgs::DiagnosticStatus::WARN, "bad IMU samples dropped");
  } else {
    out->summary(diagnostic_msgs::DiagnosticStatus::OK, "IMU stream ok");
  }
  out->add("rate_hz", rate_hz);
  out->add("received", received);
  out->add("samples_used", c.samples_used);
  out->add("dropped_outside_dwell", c.dropped_outside_dwell);
  out->add("dropped_settle_discard", c.dropped_settle_discard);
  out->add("dropped_non_finite", c.dropped_non_finite);
  out->add("dropped_backwards", c.dropped_backwards);
  out->add("duplicates", c.duplicates);
  out->add("dropped_late", c.dropped_late);
  out->add("newest_stamp_s",
           std::isfinite(st.newest_sample_stamp_s) ? st.newest_sample_stamp_s : 0.0);
}

void diagnose_run(const core::RunStatus& st, const IntrinsicResult& result,
                  diagnostic_updater::DiagnosticStatusWrapper* out) {
  switch (st.state) {
    case core::RunState::Aborted:
      out->summary(diagnostic_msgs::DiagnosticStatus::ERROR, "run aborted: " + st.fault);
      break;
    case core::RunState::FitFailed:
      out->summary(diagnostic_msgs::DiagnosticStatus::ERROR, "fit failed: " + st.fit_error);
      break;
    case core::RunState::WaitingForResume:
      out->summary(diagnostic_msgs::DiagnosticStatus::WARN,
                   "waiting for the gimbal controller to resume" +
                       (st.last_fault.empty() ? std::string() : " (" + st.last_fault + ")"));
      break;
    case core::RunState::Done:
      if (result.quality_pass) {
        out->summary(diagnostic_msgs::DiagnosticStatus::OK,
                     "result available (" + result.model + ")");
      } else {
        out->summary(diagnostic_msgs::DiagnosticStatus::ERROR, quality_failure_message(result));
      }
      break;
    default: out->summary(diagnostic_msgs::DiagnosticStatus::OK, "collecting");
  }
  out->add("state", core::run_state_name(st.state));
  out->add("current_dwell", st.in_dwell ? std::string("phase ") + core::phase_name(st.dwell_phase) +
                                              " step " + std::to_string(st.dwell_step)
                                        : std::string());
  out->add("current_dwell_samples", st.in_dwell ? st.dwell_samples : 0);
  for (core::Phase p : core::kPhases) {
    out->add(std::string("dwells_") + core::phase_name(p), st.dwells_per_phase[core::index(p)]);
  }
  out->add("steps", st.steps);
  out->add("retries", st.retries);
  out->add("dwells_discarded", st.dwells_discarded);
  out->add("last_fault", st.last_fault);
  out->add("restored", st.restored);
}

std::string quality_failure_message(const IntrinsicResult& result) {
  return "the result fails the quality gate: " +
         core::Quality{false, result.quality_reasons}.summary();
}

ResumeAt::Request to_resume_request(const core::ControllerRequest& r) {
  ResumeAt::Request out;
  out.phase = static_cast<std::uint8_t>(core::index(r.phase));
  out.step = r.step;
  out.approach = static_cast<std::int8_t>(r.approach);
  out.after = r.after;
  out.reason = r.reason;
  return out;
}

}  // namespace accel_intrinsics
