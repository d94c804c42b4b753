// Shared by the fault-injection rostests (never_settle, imu_stall_retry, imu_stall_abort,
// few_samples): run the stand under scripts/supervise with one injected fault and check the
// behaviour (success or abort, retries, table) and the message (supervise's output,
// get_intrinsics, calibration/status). Expectations come from the test's private parameters:
//   expect_success (bool), expect_messages (list of substrings of supervise's output and of the
//   reason the node gives), expect_min_retries (int), steps, timeout_s, output_dir.
#pragma once

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <std_srvs/Trigger.h>

#include <map>
#include <mutex>
#include <set>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "run_dirs.h"
#include "stand_checks.h"

namespace fault_checks {

class StatusWatcher {
 public:
  explicit StatusWatcher(ros::NodeHandle& nh) {
    status_sub_ = nh.subscribe("/calibration/status", 10, &StatusWatcher::on_status, this);
    progress_sub_ =
        nh.subscribe("/gimbal_controller/progress", 10, &StatusWatcher::on_progress, this);
  }
  std::string status(const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    return status_[key];
  }
  std::string progress(const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    return progress_[key];
  }

 private:
  void on_status(const diagnostic_msgs::DiagnosticStatus::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& kv : msg->values) status_[kv.key] = kv.value;
  }
  void on_progress(const diagnostic_msgs::DiagnosticStatus::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& kv : msg->values) progress_[kv.key] = kv.value;
    progress_["_message"] = msg->message;
  }
  std::mutex mutex_;
  std::map<std::string, std::string> status_, progress_;
  ros::Subscriber status_sub_, progress_sub_;
};

inline void check_case() {
  ros::NodeHandle nh, pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  bool expect_success = false;
  std::vector<std::string> expect_messages;
  int expect_min_retries = 0, steps = 4;
  double timeout_s = 300.0;
  std::string output_dir;
  pnh.getParam("expect_success", expect_success);
  pnh.getParam("expect_messages", expect_messages);
  pnh.getParam("expect_min_retries", expect_min_retries);
  pnh.getParam("steps", steps);
  pnh.getParam("timeout_s", timeout_s);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  StatusWatcher watch(nh);
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(60.0)));
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/start", ros::Duration(60.0)));

  // supervise: reset, start, wait; exit status 0 only with a result.
  const std::string json = output_dir + "/supervise.json";
  std::remove(json.c_str());
  std::string command = "rosrun accel_intrinsics supervise --quiet --timeout " +
                        std::to_string(timeout_s) + " --json " + json;
  if (expect_success) command += " --max-sigma " + std::to_string(limits.max_sigma);
  const stand_checks::CommandResult run = stand_checks::run(command);
  std::printf("%s\n", run.output.c_str());
  if (expect_success) {
    ASSERT_EQ(run.exit_code, 0) << run.output;
  } else {
    EXPECT_NE(run.exit_code, 0) << run.output;
  }
  for (const std::string& m : expect_messages) {
    EXPECT_NE(run.output.find(m), std::string::npos) << "supervise does not say '" << m << "':\n"
                                                     << run.output;
  }

  // The service.
  const ros::WallTime settle = ros::WallTime::now() + ros::WallDuration(5.0);
  accel_intrinsics::GetIntrinsics::Response res = stand_checks::get_intrinsics("");
  while (!expect_success && ros::WallTime::now() < settle &&
         res.message.find("aborted") == std::string::npos) {
    ros::WallDuration(0.2).sleep();
    res = stand_checks::get_intrinsics("");
  }
  EXPECT_EQ(res.success, expect_success) << res.message;
  if (!expect_success) {
    EXPECT_NE(res.message.find("aborted"), std::string::npos) << res.message;
    for (const std::string& m : expect_messages) {
      EXPECT_NE(res.message.find(m), std::string::npos)
          << "get_intrinsics does not say '" << m << "': " << res.message;
    }
    EXPECT_EQ(watch.progress("state"), "ABORTED") << watch.progress("_message");
    EXPECT_EQ(watch.status("state"), "ABORTED");
  } else {
    // Every position once, in protocol order; the retried ones measured again.
    const accel_intrinsics::core::PositionTable table =
        accel_intrinsics::core::read_position_table_file(run_dirs::latest(output_dir) +
                                                         "/position_table.csv");
    ASSERT_EQ(table.rows.size(), static_cast<std::size_t>(3 * steps));
    for (std::size_t i = 0; i < table.rows.size(); ++i) {
      EXPECT_EQ(accel_intrinsics::core::index(table.rows[i].phase), static_cast<int>(i) / steps);
      EXPECT_EQ(table.rows[i].step, i % steps);
    }
    for (int p = 0; p < 3; ++p) EXPECT_EQ(res.result.positions[p], static_cast<unsigned>(steps));
    for (const std::string& m : expect_messages) {
      EXPECT_NE(watch.status("last_fault").find(m), std::string::npos)
          << "calibration/status last_fault does not say '" << m
          << "': " << watch.status("last_fault");
    }
  }
  if (expect_min_retries > 0) {
    EXPECT_GE(std::stoi("0" + watch.status("retries")), expect_min_retries);
  }
}

}  // namespace fault_checks
