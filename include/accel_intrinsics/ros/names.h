// Topic, service and node names, all relative so they remap and namespace (docs/design.md section
// 2).
#pragma once

namespace accel_intrinsics {
namespace names {

constexpr char kGimbalCommandTopic[] = "gimbal/command";
constexpr char kImuTopic[] = "imu/data_raw";
// The per-dwell channels' topics (imu/temperature, ...) are in core::kChannels (dwell_record.h).
constexpr char kResultTopic[] = "calibration/result";
constexpr char kStartService[] = "gimbal_controller/start";
constexpr char kAbortService[] = "gimbal_controller/abort";
// accel_intrinsics/AbortRun: abort with a reason (the calibration node's watchdogs use it).
constexpr char kAbortRunService[] = "gimbal_controller/abort_run";
constexpr char kResetService[] = "calibration/reset";
constexpr char kGetIntrinsicsService[] = "calibration/get_intrinsics";
// Not in the contract table, added by the online stand (additive):
// tf is published on the relative topic "tf" (resolves to /tf without a namespace) so that two
// rigs in two namespaces do not mix their world -> gimbal -> dut chains.
constexpr char kTfTopic[] = "tf";
// diagnostic_msgs/DiagnosticStatus: state, phase, step, positions done/total, time left.
constexpr char kProgressTopic[] = "gimbal_controller/progress";
// diagnostic_msgs/DiagnosticStatus: dwells per phase and the dropped-sample counters.
constexpr char kCalibrationStatusTopic[] = "calibration/status";
constexpr char kClockTopic[] = "/clock";
// std_msgs/String, latched: the JSON of io::analysis_json_text() after an analysis (issue 5).
constexpr char kAnalysisTopic[] = "calibration/analysis";
// std_msgs/String, not latched: the directory a run writes into, published when the calibration
// node opens it (record.launch's recorder moves its bag there).
constexpr char kRunDirectoryTopic[] = "calibration/run_directory";
// std_srvs/Trigger: run the analysis on the current position table.
constexpr char kAnalyzeService[] = "calibration/analyze";
// accel_intrinsics/ResumeAt: continue the protocol at (phase, step, approach), or after it.
constexpr char kResumeService[] = "gimbal_controller/resume";
// std_srvs/Trigger: the operator has remounted the DUT by hand; continue (docs/design.md section
// 10).
constexpr char kContinueService[] = "gimbal_controller/continue";

// sensor_msgs/Imu: the apply node's output, linear_acceleration = P (R - O) (docs/design.md section
// 7).
constexpr char kCalibratedImuTopic[] = "imu/data_calibrated";

constexpr char kWorldFrame[] = "world";
constexpr char kGimbalFrame[] = "gimbal";
constexpr char kDutFrame[] = "dut";

}  // namespace names
}  // namespace accel_intrinsics
