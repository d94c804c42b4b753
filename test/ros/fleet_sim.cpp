// Eight rigs at 1 kHz on one roscore (test/ros/fleet_sim.test).
#include <diagnostic_msgs/DiagnosticArray.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <mutex>

#include "run_dirs.h"
#include "stand_checks.h"

namespace {
std::mutex mutex;
std::map<std::string, double> max_rate;  // "rigK/calibration: imu" -> largest rate_hz seen
void on_diagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(mutex);
  for (const auto& status : msg->status) {
    for (const auto& kv : status.values) {
      if (kv.key == "rate_hz")
        max_rate[status.name] = std::max(max_rate[status.name], std::stod(kv.value));
    }
  }
}
}  // namespace

TEST(FleetSim, EightRigsAtOneKilohertzAllMatchTheirTruth) {
  ros::NodeHandle nh, pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  std::vector<std::string> namespaces;
  double timeout_s = 500.0, rate_hz = 1000.0;
  int steps = 6;
  std::string output_dir;
  ASSERT_TRUE(pnh.getParam("namespaces", namespaces));
  ASSERT_EQ(namespaces.size(), 8u);
  pnh.getParam("timeout_s", timeout_s);
  pnh.getParam("steps", steps);
  pnh.getParam("rate_hz", rate_hz);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  ros::Subscriber sub = nh.subscribe("/diagnostics", 1000, on_diagnostics);
  for (const std::string& ns : namespaces) {
    ASSERT_TRUE(ros::service::waitForService(
        stand_checks::join_ns(ns, "calibration/get_intrinsics"), ros::Duration(120.0)));
    ASSERT_TRUE(ros::service::waitForService(stand_checks::join_ns(ns, "gimbal_controller/start"),
                                             ros::Duration(120.0)));
  }
  const auto t0 = std::chrono::steady_clock::now();
  stand_checks::supervise_and_check(namespaces, limits, timeout_s, output_dir + "/supervise.json");
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("fleet of %zu rigs at %.0f Hz: %.1f s wall\n", namespaces.size(), rate_hz, wall_s);

  for (const std::string& ns : namespaces) {
    stand_checks::Truth truth;
    ASSERT_TRUE(stand_checks::load_truth(ns, &truth)) << ns;
    const accel_intrinsics::GetIntrinsics::Response res = stand_checks::get_intrinsics(ns);
    ASSERT_TRUE(res.success) << ns << ": " << res.message;
    stand_checks::expect_matches_truth(res.result, truth, limits, ns);
    for (int p = 0; p < 3; ++p)
      EXPECT_EQ(res.result.positions[p], static_cast<unsigned>(steps)) << ns;
    EXPECT_EQ(stand_checks::count_csv_rows(run_dirs::latest(output_dir + "/" + ns) +
                                           "/position_table.csv"),
              static_cast<std::size_t>(3 * steps))
        << ns;
    // Each calibration node saw the full rate (sensor time).
    std::lock_guard<std::mutex> lock(mutex);
    const double rate = max_rate[ns + "/calibration: imu"];
    EXPECT_GT(rate, 0.95 * rate_hz) << ns;
    EXPECT_LT(rate, 1.05 * rate_hz) << ns;
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "fleet_sim_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
