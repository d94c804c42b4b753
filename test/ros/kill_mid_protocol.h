// Shared by the "nothing lost" rostests: SIGKILL a node of the stand mid-protocol; roslaunch
// respawns it and the run continues after the last recorded dwell. The final result must be the
// fit of a complete table (every position once, in protocol order, t0 = the run's first
// command) and match the truth. resume_after_kill.test kills the calibration node (it reloads its
// checkpoint), controller_restart.test the gimbal controller (the calibration node rewinds it).
#pragma once

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <signal.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <yaml-cpp/yaml.h>

#include <mutex>
#include <set>

#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "run_dirs.h"
#include "stand_checks.h"
#include "wait_for.h"

namespace {
std::mutex mutex;
test_wait::LatestValues progress;  // gimbal_controller/progress
test_wait::LatestValues status;    // calibration/status
double first_moving_stamp = -1.0;
accel_intrinsics::GimbalCommand last_command;
bool have_command = false;
void on_command(const accel_intrinsics::GimbalCommand::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(mutex);
  if (first_moving_stamp < 0 && msg->state == accel_intrinsics::GimbalCommand::MOVING &&
      msg->phase == 0 && msg->step == 0) {
    first_moving_stamp = msg->header.stamp.toSec();
  }
  last_command = *msg;
  have_command = true;
}
// Whether the last gimbal command received is the SETTLED of `position` (0-based, protocol order).
bool settled_at(int position, int steps) {
  std::lock_guard<std::mutex> lock(mutex);
  return have_command && last_command.state == accel_intrinsics::GimbalCommand::SETTLED &&
         static_cast<int>(last_command.phase) * steps + static_cast<int>(last_command.step) ==
             position;
}
// A persistent connection to sim_clock ~pause, made before the test waits for its moment: holding
// the clock then costs no master lookup and no TCP connect (on a loaded machine those took long
// enough to let the clock run far into the dwell).
ros::ServiceClient& pause_client() {
  static ros::ServiceClient client =
      ros::NodeHandle().serviceClient<std_srvs::SetBool>("/sim_clock/pause", true);
  return client;
}
// Holds or releases the simulated clock (sim_clock ~pause); *at_s: the clock's time then (its
// answer: "paused at 123.456000 s").
bool pause_clock(bool pause, double* at_s = nullptr) {
  std_srvs::SetBool srv;
  srv.request.data = pause;
  // A broken persistent connection (never expected: sim_clock is not restarted) falls back to a
  // one-off call.
  const bool called = (pause_client().isValid() && pause_client().call(srv)) ||
                      ros::service::call("/sim_clock/pause", srv);
  if (!called || !srv.response.success) return false;
  if (at_s) {
    const std::size_t at = srv.response.message.find(" at ");
    if (at == std::string::npos) return false;
    *at_s = std::stod(srv.response.message.substr(at + 4));
  }
  return true;
}
}  // namespace

// Waits for the SETTLED of `position` (0-based, protocol order) and holds the simulated clock
// inside that dwell, at most `max_into_dwell_s` after its start (so the test's margins, in
// simulated seconds, do not depend on how fast it reacted). Needs on_command subscribed.
// max_into_dwell_s: the latest stop the caller's expectations allow (its test file says why).
inline void hold_clock_in_dwell(int position, int steps, const ros::WallTime& deadline,
                                double max_into_dwell_s) {
  ASSERT_TRUE(ros::service::waitForService("/sim_clock/pause", ros::Duration(10.0)));
  ASSERT_TRUE(pause_client().isValid()) << "no connection to /sim_clock/pause";
  while (!settled_at(position, steps) && ros::WallTime::now() < deadline) {
    ros::WallDuration(0.005).sleep();
  }
  ASSERT_TRUE(settled_at(position, steps)) << "no SETTLED of position " << position + 1;
  double held_s = 0.0;
  ASSERT_TRUE(pause_clock(true, &held_s));
  // The clock messages in flight have arrived once this process's clock reads the held time
  // (sim_clock publishes that time again and again while paused; 1e-6: the answer's digits).
  ASSERT_TRUE(
      test_wait::wait_for([&] { return ros::Time::now().toSec() >= held_s - 1e-6; }, 30.0,
                          "the test's clock to reach the held " + std::to_string(held_s) + " s"));
  ASSERT_TRUE(settled_at(position, steps)) << "the clock did not stop in the dwell";
  double settled_s = 0.0;
  {
    std::lock_guard<std::mutex> lock(mutex);
    settled_s = last_command.header.stamp.toSec();
  }
  const double into_s = ros::Time::now().toSec() - settled_s;
  ASSERT_LE(into_s, max_into_dwell_s) << "the clock stopped " << into_s << " s into the dwell";
}

// The whole scenario; `victim` is the node to kill ("/calibration" or "/gimbal_controller").
inline void kill_mid_protocol_and_check(const std::string& victim) {
  ros::NodeHandle nh, pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  double timeout_s = 300.0;
  int steps = 6, kill_at = 8;
  std::string output_dir;
  pnh.getParam("timeout_s", timeout_s);
  pnh.getParam("steps", steps);
  pnh.getParam("kill_at_position", kill_at);
  bool hold_clock = false;
  int expected_discarded = -1;  // < 0: printed, not checked
  pnh.getParam("hold_clock", hold_clock);
  pnh.getParam("expected_dwells_discarded", expected_discarded);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  ros::Subscriber p = nh.subscribe("/gimbal_controller/progress", 10,
                                   &test_wait::LatestValues::on_message, &progress);
  ros::Subscriber s =
      nh.subscribe("/calibration/status", 10, &test_wait::LatestValues::on_message, &status);
  ros::Subscriber c = nh.subscribe("/gimbal/command", 100, on_command);
  stand_checks::reset_and_start({&c});
  if (::testing::Test::HasFatalFailure()) return;

  // Mid-protocol: SIGKILL. With hold_clock, inside the dwell of position kill_at: the test waits
  // for its SETTLED, holds the simulated clock, kills, and runs the clock on once the victim is
  // back, so where the kill lands does not depend on the machine's load. Otherwise as soon as the
  // controller reports position kill_at, in a move or a dwell.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  if (hold_clock) {
    double max_into_dwell_s = 1.0;
    pnh.getParam("max_into_dwell_s", max_into_dwell_s);
    hold_clock_in_dwell(kill_at - 1, steps, deadline, max_into_dwell_s);
    if (::testing::Test::HasFatalFailure()) return;
  } else {
    while (ros::WallTime::now() < deadline) {
      const std::string position = progress("position");
      if (!position.empty() && std::stoi(position) >= kill_at) break;
      ros::WallDuration(0.05).sleep();
    }
    ASSERT_GE(std::stoi(progress("position")), kill_at);
  }
  const int pid = test_wait::node_pid(victim);
  ASSERT_GT(pid, 1);
  ASSERT_EQ(kill(pid, SIGKILL), 0);
  std::printf("killed %s (pid %d) at position %s (phase %s step %s)%s\n", victim.c_str(), pid,
              progress("position").c_str(), progress("phase").c_str(), progress("step").c_str(),
              hold_clock ? ", clock held in its dwell" : "");
  if (hold_clock) {
    const std::uint64_t progress_before = progress.messages();
    bool back = false;
    while (!back && ros::WallTime::now() < deadline) {
      const int now_pid = test_wait::node_pid(victim);
      back = now_pid > 1 && now_pid != pid;
      if (!back) ros::WallDuration(0.1).sleep();
    }
    ASSERT_TRUE(back) << victim << " did not come back";
    // Before the clock runs on, the new process is wired up: its services answer, its
    // subscriptions are connected, and a restarted controller's latched progress has gone out
    // (this test got it; the calibration node has its connection to the new controller).
    const bool calibration = victim == "/calibration";
    const std::set<std::string> inputs =
        calibration ? std::set<std::string>{"/clock", "/gimbal/command", "/imu/data_raw",
                                            "/gimbal_controller/progress"}
                    : std::set<std::string>{"/clock"};
    const std::string service =
        calibration ? "/calibration/get_intrinsics" : "/gimbal_controller/start";
    ASSERT_TRUE(test_wait::wait_for(
        [&] {
          if (!ros::service::exists(service, false)) return false;
          const std::set<std::string> connected = test_wait::connected_inbound_topics(victim);
          for (const std::string& topic : inputs) {
            if (!connected.count(topic)) return false;
          }
          return calibration || (progress.messages() > progress_before &&
                                 test_wait::connected_inbound_topics("/calibration")
                                     .count("/gimbal_controller/progress"));
        },
        60.0, "the restarted " + victim + " to answer " + service + " and connect its inputs"));
    ASSERT_TRUE(settled_at(kill_at - 1, steps)) << "the stand moved while the clock was held";
    ASSERT_TRUE(pause_clock(false));
  }

  // roslaunch respawns it; it resumes; the protocol ends with a result.
  accel_intrinsics::GetIntrinsics::Response res;
  bool respawned = false;
  while (ros::WallTime::now() < deadline) {
    const int now_pid = test_wait::node_pid(victim);
    if (now_pid > 1 && now_pid != pid) respawned = true;
    if (respawned) {
      accel_intrinsics::GetIntrinsics srv;
      if (ros::service::call("/calibration/get_intrinsics", srv) && srv.response.success) {
        res = srv.response;
        break;
      }
    }
    ros::WallDuration(0.5).sleep();
  }
  ASSERT_TRUE(respawned) << victim << " did not come back";
  ASSERT_TRUE(res.success) << res.message;
  // Only a restarted calibration node restores its checkpoint.
  EXPECT_EQ(status("restored"), victim == "/calibration" ? "true" : "false");
  for (int i = 0; i < 3; ++i) EXPECT_EQ(res.result.positions[i], static_cast<unsigned>(steps));

  // The checkpoint: every position once, in protocol order, and the run's time origin.
  namespace core = accel_intrinsics::core;
  core::PositionTable table =
      core::read_position_table_file(run_dirs::latest(output_dir) + "/position_table.csv");
  ASSERT_EQ(table.rows.size(), static_cast<std::size_t>(3 * steps));
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    EXPECT_EQ(core::index(table.rows[i].phase), static_cast<int>(i) / steps) << "row " << i;
    EXPECT_EQ(table.rows[i].step, i % steps) << "row " << i;
    if (i > 0) {
      EXPECT_GT(table.rows[i].t_start_s, table.rows[i - 1].t_end_s - 1e-9) << "row " << i;
    }
  }
  const YAML::Node state = YAML::LoadFile(run_dirs::latest(output_dir) + "/calibration_state.yaml");
  ASSERT_GT(first_moving_stamp, 0.0);
  EXPECT_DOUBLE_EQ(state["time_origin_s"].as<double>(), first_moving_stamp);
  EXPECT_TRUE(state["done"].as<bool>());
  table.time_origin_s = state["time_origin_s"].as<double>();

  // The result is the fit of exactly these dwells.
  core::FitOptions options;  // joint, standard gravity: config/calibration.yaml
  const core::FitResult fit = core::fit(table, options);
  const accel_intrinsics::IntrinsicResult& r = res.result;
  const double vec[3][3] = {{r.u.x, r.u.y, r.u.z}, {r.v.x, r.v.y, r.v.z}, {r.w.x, r.w.y, r.w.z}};
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(vec[i][k], fit.S(i, k), 1e-12);
    EXPECT_NEAR(r.offset[i], fit.O(i), 1e-12);
    EXPECT_NEAR(r.responsivity[i], fit.S.row(i).norm(), 1e-12);
  }
  EXPECT_NEAR(r.reduced_chi2, fit.reduced_chi2, 1e-9);

  // And it is as good as an uninterrupted run's.
  stand_checks::Truth truth;
  ASSERT_TRUE(stand_checks::load_truth("", &truth));
  stand_checks::expect_matches_truth(r, truth, limits, "resumed");
  std::printf("restored run: %s; %s dwells discarded, %s\n", res.message.c_str(),
              status("dwells_discarded").c_str(), status("last_warning").c_str());
  if (expected_discarded >= 0) {
    EXPECT_EQ(status("dwells_discarded"), std::to_string(expected_discarded));
  }
}
