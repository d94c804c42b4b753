// Promises of the README and config/*.yaml that no other test held the stand to (issue 15), one
// scenario per .test file (each selects its TEST with --gtest_filter):
//   stand_promises.test   gimbal_controller ~resume_phase/~resume_step start the run there, and
//                         calibration/reset deletes the checkpoint files
//   site_gravity.test     calibration ~latitude_deg/~height_m set the g of the fit
//   eq4_on_stand.test     model:=eq4 on the live stand
#include <diagnostic_msgs/DiagnosticStatus.h>
#include <std_srvs/Trigger.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "run_dirs.h"
#include "stand_checks.h"
#include "wait_for.h"

namespace {
using accel_intrinsics::GimbalCommand;
std::mutex mutex;
std::vector<GimbalCommand> commands;
void on_command(const GimbalCommand::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(mutex);
  commands.push_back(*msg);
}
bool exists(const std::string& path) {
  return ::access(path.c_str(), F_OK) == 0;
}
test_wait::LatestValues status_value;  // the latest calibration/status

accel_intrinsics::GetIntrinsics::Response wait_for_result(double timeout_s) {
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  accel_intrinsics::GetIntrinsics srv;
  while (ros::WallTime::now() < deadline) {
    if (ros::service::call("/calibration/get_intrinsics", srv) && srv.response.success) break;
    ros::WallDuration(0.5).sleep();
  }
  return srv.response;
}

// WGS 84 normal gravity, written here from NIMA TR8350.2 (3rd ed.) independently of
// core::normal_gravity: Somigliana's closed formula (eq. 4-1) and the free-air reduction to
// height h above the ellipsoid (eq. 4-3).
double wgs84_normal_gravity(double latitude_deg, double h) {
  const double a = 6378137.0;            // semi-major axis, m
  const double f = 1.0 / 298.257223563;  // flattening
  const double m = 0.00344978650684;     // omega^2 a^2 b / GM
  const double gamma_e = 9.7803253359;   // normal gravity at the equator, m/s^2
  const double k = 0.00193185265241;     // Somigliana's constant
  const double e2 = 6.69437999014e-3;    // first eccentricity squared
  const double s2 = std::pow(std::sin(latitude_deg * M_PI / 180.0), 2);
  const double gamma = gamma_e * (1.0 + k * s2) / std::sqrt(1.0 - e2 * s2);
  return gamma * (1.0 - 2.0 / a * (1.0 + f + m - 2.0 * f * s2) * h + 3.0 / (a * a) * h * h);
}
}  // namespace

// gimbal_controller ~resume_phase y, ~resume_step 3: the first command of the run is the MOVING
// to y/3, the table fills from there; then calibration/reset keeps the run's files in its run
// directory (a reset never deletes a run: docs/design.md section 15) and starts no new one.
TEST(StandPromises, ResumeParamsStartTheRunThereAndResetKeepsTheRun) {
  ros::NodeHandle nh, pnh("~");
  std::string output_dir, resume_phase = "y";
  int resume_step = 3;
  double timeout_s = 200.0;
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  pnh.getParam("resume_phase", resume_phase);
  pnh.getParam("resume_step", resume_step);
  pnh.getParam("timeout_s", timeout_s);
  ros::Subscriber c = nh.subscribe("/gimbal/command", 1000, on_command);
  ros::Subscriber st =
      nh.subscribe("/calibration/status", 10, &test_wait::LatestValues::on_message, &status_value);
  // A reset keeps earlier runs: an earlier invocation's run must not pass for this one's.
  std::filesystem::remove_all(output_dir + "/unnamed");
  stand_checks::reset_and_start({&c});
  if (HasFatalFailure()) return;
  const std::string table = run_dirs::latest(output_dir) + "/position_table.csv";
  const std::string state = run_dirs::latest(output_dir) + "/calibration_state.yaml";
  // Two dwells checkpointed.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (stand_checks::count_csv_rows(table) < 2 && ros::WallTime::now() < deadline) {
    ros::WallDuration(0.2).sleep();
  }
  ASSERT_GE(stand_checks::count_csv_rows(table), 2u) << table;
  ASSERT_TRUE(exists(state)) << state;
  {
    std::lock_guard<std::mutex> lock(mutex);
    ASSERT_FALSE(commands.empty());
    const GimbalCommand& first = commands.front();
    EXPECT_EQ(first.state, GimbalCommand::MOVING);
    EXPECT_EQ(first.phase, resume_phase == "x" ? 0 : resume_phase == "y" ? 1 : 2);
    EXPECT_EQ(static_cast<int>(first.step), resume_step);
    EXPECT_NEAR(first.angle, 2.0 * M_PI * resume_step / first.steps, 1e-12);
  }
  // The rows are the positions from there on, in protocol order.
  accel_intrinsics::core::PositionTable t = accel_intrinsics::core::read_position_table_file(table);
  ASSERT_GE(t.rows.size(), 2u);
  EXPECT_EQ(std::string(accel_intrinsics::core::phase_name(t.rows[0].phase)), resume_phase);
  EXPECT_EQ(static_cast<int>(t.rows[0].step), resume_step);
  EXPECT_EQ(static_cast<int>(t.rows[1].step), resume_step + 1);

  // Stop the gimbal (no further commands to start a new checkpoint), then reset.
  std_srvs::Trigger abort, reset;
  ASSERT_TRUE(ros::service::call("/gimbal_controller/abort", abort));
  // The calibration node has taken in the controller's abort (its status names it).
  ASSERT_TRUE(test_wait::wait_for([] { return !status_value("fault").empty(); }, 60.0,
                                  "calibration/status to name the controller's abort"));
  const std::string run = std::filesystem::canonical(run_dirs::latest(output_dir)).string();
  const std::size_t rows_at_reset = stand_checks::count_csv_rows(table);
  ASSERT_TRUE(ros::service::call("/calibration/reset", reset));
  EXPECT_TRUE(reset.response.success) << reset.response.message;
  EXPECT_EQ(stand_checks::count_csv_rows(run + "/position_table.csv"), rows_at_reset)
      << run << ": calibration/reset changed the run's table";
  EXPECT_TRUE(exists(run + "/calibration_state.yaml")) << run << ": the state went at the reset";
  // Still gone once the node has run on past its reorder window (a command still in flight at
  // the reset would have been released by then) and two status periods: a status of the node
  // stamped that late (the run ticks, and writes its checkpoint, in the same timer callback).
  double window_s = 0.0, period_s = 1.0;
  ASSERT_TRUE(ros::param::get("/calibration/reorder_window_s", window_s));
  ros::param::get("/calibration/status_period_s", period_s);
  const double until_s = ros::Time::now().toSec() + window_s + 2.0 * period_s;
  EXPECT_TRUE(test_wait::wait_for(
      [&] {
        const std::string stamp = status_value("stamp");
        return !stamp.empty() && std::stod(stamp) >= until_s;
      },
      60.0, "a calibration/status stamped " + std::to_string(until_s) + " s (reset + window)"));
  // No command in flight at the reset started a new run (a new directory behind `latest`), and
  // none added to the old one.
  EXPECT_EQ(std::filesystem::canonical(run_dirs::latest(output_dir)).string(), run)
      << "a new run directory appeared after calibration/reset";
  EXPECT_EQ(stand_checks::count_csv_rows(run + "/position_table.csv"), rows_at_reset) << run;
}

// calibration ~latitude_deg, ~height_m (and no local_gravity): the fit uses WGS 84 normal gravity
// there. The simulated device feels ~device_gravity, so every responsivity comes out scaled by
// device_gravity / g_site.
TEST(StandPromises, SiteLatitudeAndHeightSetTheGravityOfTheFit) {
  ros::NodeHandle pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  double latitude_deg = 0.0, height_m = 0.0, device_gravity = 9.80665, timeout_s = 200.0;
  ASSERT_TRUE(pnh.getParam("latitude_deg", latitude_deg));
  ASSERT_TRUE(pnh.getParam("height_m", height_m));
  ASSERT_TRUE(ros::param::get("/accelerometer/local_gravity", device_gravity));
  pnh.getParam("timeout_s", timeout_s);
  stand_checks::reset_and_start();
  if (HasFatalFailure()) return;
  const accel_intrinsics::GetIntrinsics::Response res = wait_for_result(timeout_s);
  ASSERT_TRUE(res.success) << res.message;
  const double g_site = wgs84_normal_gravity(latitude_deg, height_m);
  EXPECT_NEAR(res.result.local_gravity, g_site, 1e-9);
  ASSERT_GT(std::abs(g_site - device_gravity), 0.01) << "choose a site whose g differs visibly";
  stand_checks::Truth truth;
  ASSERT_TRUE(stand_checks::load_truth("", &truth));
  for (int s = 0; s < 3; ++s) {
    const double expected = truth.responsivity[s] * device_gravity / g_site;
    EXPECT_LE(std::abs(res.result.responsivity[s] - expected),
              limits.max_sigma * res.result.responsivity_std[s])
        << "|"
        << "uvw"[s] << "| " << res.result.responsivity[s] << " expected " << expected;
    // ... and visibly not the truth itself (the shift is many standard uncertainties).
    EXPECT_GT(std::abs(res.result.responsivity[s] - truth.responsivity[s]),
              10.0 * res.result.responsivity_std[s]);
  }
}

// model:=eq4 on the live stand: the service answers an eq4 result that matches the truth.
TEST(StandPromises, Eq4ModelOnTheLiveStand) {
  ros::NodeHandle pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  double timeout_s = 200.0;
  int steps = 6;
  pnh.getParam("timeout_s", timeout_s);
  pnh.getParam("steps", steps);
  stand_checks::reset_and_start();
  if (HasFatalFailure()) return;
  const accel_intrinsics::GetIntrinsics::Response res = wait_for_result(timeout_s);
  ASSERT_TRUE(res.success) << res.message;
  EXPECT_EQ(res.result.model, "eq4");
  for (int p = 0; p < 3; ++p) EXPECT_EQ(res.result.positions[p], static_cast<unsigned>(steps));
  stand_checks::Truth truth;
  ASSERT_TRUE(stand_checks::load_truth("", &truth));
  stand_checks::expect_matches_truth(res.result, truth, limits, "eq4");
  // eq4's per-phase offsets: each near its accelerometer's offset.
  for (int s = 0; s < 3; ++s) {
    for (int p = 0; p < 3; ++p) {
      EXPECT_NEAR(res.result.offset_per_phase[3 * s + p], truth.O[s], 5.0 * limits.max_offset_std)
          << "O_"
          << "uvw"[s] << " phase "
          << "xyz"[p];
    }
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "stand_promises_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
