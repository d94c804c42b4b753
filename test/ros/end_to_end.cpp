// End to end on the simulated stand (test/ros/end_to_end.test), and the /diagnostics of its
// nodes (diagnostic_updater).
#include <diagnostic_msgs/DiagnosticArray.h>
#include <diagnostic_msgs/DiagnosticStatus.h>

#include <algorithm>
#include <map>
#include <mutex>

namespace {
std::mutex diag_mutex;
// Latest values per status name, and the largest IMU rate seen while running.
std::map<std::string, std::map<std::string, std::string>> diag;
std::map<std::string, int> diag_levels;
double max_imu_rate = 0.0;
bool saw_gimbal_running = false;
void on_diagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(diag_mutex);
  for (const auto& status : msg->status) {
    auto& values = diag[status.name];
    for (const auto& kv : status.values) values[kv.key] = kv.value;
    diag_levels[status.name] = status.level;
    if (status.name == "calibration: imu" && values.count("rate_hz")) {
      max_imu_rate = std::max(max_imu_rate, std::stod(values["rate_hz"]));
    }
    if (status.name == "gimbal_controller: protocol" &&
        (values["state"] == "MOVING" || values["state"] == "SETTLED") && !values["phase"].empty()) {
      saw_gimbal_running = true;
    }
  }
}
}  // namespace

#include "run_dirs.h"
#include "stand_checks.h"

TEST(EndToEnd, SuperviseThenServiceMatchTruth) {
  ros::NodeHandle pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  double timeout_s = 240.0;
  int steps = 12;
  std::string output_dir;
  pnh.getParam("timeout_s", timeout_s);
  pnh.getParam("steps", steps);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  ros::NodeHandle nh;
  ros::Subscriber diag_sub = nh.subscribe("/diagnostics", 100, on_diagnostics);
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(60.0)));

  // The supervisor: start, progress, get_intrinsics, table against the truth, JSON.
  stand_checks::supervise_and_check({""}, limits, timeout_s, output_dir + "/supervise.json");

  // The service directly.
  const accel_intrinsics::GetIntrinsics::Response res = stand_checks::get_intrinsics("");
  ASSERT_TRUE(res.success) << res.message;
  stand_checks::Truth truth;
  ASSERT_TRUE(stand_checks::load_truth("", &truth));
  stand_checks::expect_matches_truth(res.result, truth, limits, "stand");
  EXPECT_EQ(res.result.model, "joint");
  for (int p = 0; p < 3; ++p) EXPECT_EQ(res.result.positions[p], static_cast<unsigned>(steps));
  EXPECT_LT(res.result.reduced_chi2, 3.0);

  // The latched result topic carries the same numbers.
  const auto latched = ros::topic::waitForMessage<accel_intrinsics::IntrinsicResult>(
      "/calibration/result", ros::Duration(10.0));
  ASSERT_TRUE(latched);
  EXPECT_EQ(latched->responsivity, res.result.responsivity);

  // Checkpoints and result files.
  EXPECT_EQ(stand_checks::count_csv_rows(run_dirs::latest(output_dir) + "/position_table.csv"),
            static_cast<std::size_t>(3 * steps));
  std::ifstream yaml(run_dirs::latest(output_dir) + "/intrinsics.yaml");
  EXPECT_TRUE(yaml.good());

  // No bad samples on a healthy stand.
  const auto status = ros::topic::waitForMessage<diagnostic_msgs::DiagnosticStatus>(
      "/calibration/status", ros::Duration(10.0));
  ASSERT_TRUE(status);
  std::map<std::string, std::string> v;
  for (const auto& kv : status->values) v[kv.key] = kv.value;
  EXPECT_EQ(v["dropped_non_finite"], "0");
  EXPECT_EQ(v["dropped_backwards"], "0");
  EXPECT_EQ(v["commands_out_of_order"], "0");
  EXPECT_GT(std::stoll(v["samples_used"]), 3LL * steps * 150);

  // /diagnostics: the calibration node's IMU and run statuses, the controller's protocol.
  ros::WallDuration(3.0).sleep();  // one more period after the result
  std::lock_guard<std::mutex> lock(diag_mutex);
  ASSERT_TRUE(diag.count("calibration: imu"));
  ASSERT_TRUE(diag.count("calibration: run"));
  ASSERT_TRUE(diag.count("gimbal_controller: protocol"));
  // 100 Hz in the sensor's time (stamps).
  EXPECT_GT(max_imu_rate, 95.0);
  EXPECT_LT(max_imu_rate, 105.0);
  for (const char* key : {"received", "samples_used", "dropped_outside_dwell", "dropped_non_finite",
                          "dropped_backwards", "dropped_late", "dropped_settle_discard"}) {
    EXPECT_TRUE(diag["calibration: imu"].count(key)) << key;
  }
  EXPECT_EQ(diag["calibration: imu"]["dropped_non_finite"], "0");
  EXPECT_EQ(diag["calibration: run"]["dwells_x"], std::to_string(steps));
  EXPECT_TRUE(diag["calibration: run"].count("current_dwell"));
  EXPECT_EQ(diag_levels["calibration: run"], 0);
  EXPECT_TRUE(saw_gimbal_running);
  EXPECT_EQ(diag["gimbal_controller: protocol"]["state"], "DONE");
  for (const char* key : {"phase", "step", "position", "positions", "time_left_s"}) {
    EXPECT_TRUE(diag["gimbal_controller: protocol"].count(key)) << key;
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "end_to_end_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
