// Conversions between ROS messages and the ROS-free core types. The only place that knows both.
#pragma once

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <diagnostic_updater/DiagnosticStatusWrapper.h>
#include <sensor_msgs/Imu.h>

#include <string>

#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/IntrinsicResult.h"
#include "accel_intrinsics/ResumeAt.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/run/calibration_run.h"

namespace accel_intrinsics {

core::GimbalEvent to_core(const GimbalCommand& msg);
GimbalCommand to_msg(const core::GimbalEvent& event);

// linear_acceleration x, y, z carry R_u, R_v, R_w.
core::ImuSample to_core(const sensor_msgs::Imu& msg);
// Fills the contract: orientation_covariance[0] = -1 and angular_velocity_covariance[0] = -1;
// linear_acceleration_covariance diagonal = variance_per_axis (0 = unknown).
sensor_msgs::Imu to_msg(const core::ImuSample& sample, const std::string& frame_id,
                        double variance_per_axis = 0.0);

IntrinsicResult to_msg(const core::FitResult& result);

// A gimbal command the calibration run may take: known phase and state, finite angle, step within
// the protocol (step == steps is the closing position), non-zero stamp.
bool is_well_formed(const GimbalCommand& msg);

// calibration/status: the run's status as key/values; "state" is WAITING, COLLECTING, RESUMING,
// FITTING, RESULT, FAILED or ABORTED (scripts/supervise and the rostests read it).
diagnostic_msgs::DiagnosticStatus to_status_msg(const core::RunStatus& status,
                                                const std::string& message,
                                                const std::string& model, double stamp_s,
                                                const std::string& name);

// The calibration node's diagnostics (diagnostic_updater tasks "imu" and "run"): summary level
// and message, and the key/values. `rate_hz`: the IMU's rate in its own stamps; `received`: IMU
// messages so far; `result`: the latest certificate (its quality gate).
void diagnose_imu(const core::RunStatus& status, double rate_hz, std::uint64_t received,
                  diagnostic_updater::DiagnosticStatusWrapper* out);
void diagnose_run(const core::RunStatus& status, const IntrinsicResult& result,
                  diagnostic_updater::DiagnosticStatusWrapper* out);

// "the result fails the quality gate: <reasons>" of a certificate that failed it.
std::string quality_failure_message(const IntrinsicResult& result);

// The gimbal_controller/resume request of the run's ResumeAt.
ResumeAt::Request to_resume_request(const core::ControllerRequest& request);

}  // namespace accel_intrinsics
