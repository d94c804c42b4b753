// kill_in_dwell.test: SIGKILL the calibration node inside the dwell of a chosen position with
// the simulated clock held, so that what happens next does not depend on the machine's load.
#include <sensor_msgs/Imu.h>

#include <algorithm>
#include <fstream>
#include <vector>

#include "kill_mid_protocol.h"
#include "run_dirs.h"

namespace {
using accel_intrinsics::GimbalCommand;

std::mutex seen_mutex;
std::vector<GimbalCommand> commands;  // as received (the controller publishes in stamp order)
std::vector<double> imu_stamps;
void on_cmd(const GimbalCommand::ConstPtr& msg) {
  on_command(msg);  // kill_mid_protocol.h: the last command, for hold_clock_in_dwell
  std::lock_guard<std::mutex> lock(seen_mutex);
  commands.push_back(*msg);
}
void on_imu(const sensor_msgs::Imu::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(seen_mutex);
  imu_stamps.push_back(msg->header.stamp.toSec());
}
std::size_t commands_seen() {
  std::lock_guard<std::mutex> lock(seen_mutex);
  return commands.size();
}
// Rows of the checkpoint file (lines after the header; a torn last line is not a row).
std::size_t checkpoint_rows(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::size_t rows = 0;
  bool header = true;
  while (std::getline(in, line)) {
    if (header) {
      header = false;
      continue;
    }
    if (!line.empty() && !in.eof()) ++rows;
  }
  return rows;
}
bool subscribes(const std::string& node, const std::string& topic) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, payload, false)) return false;
  XmlRpc::XmlRpcValue& subs = payload[1];
  for (int i = 0; i < subs.size(); ++i) {
    if (static_cast<std::string>(subs[i][0]) != topic) continue;
    for (int j = 0; j < subs[i][1].size(); ++j) {
      if (static_cast<std::string>(subs[i][1][j]) == node) return true;
    }
  }
  return false;
}
}  // namespace

TEST(KillInDwell, RestartInsideAChosenDwellLosesNothingAndDiscardsNothing) {
  namespace core = accel_intrinsics::core;
  ros::NodeHandle nh, pnh("~");
  double timeout_s = 300.0;
  int steps = 6, kill_step = 2, dwell_samples = 200;
  double rate_hz = 100.0;
  std::string output_dir, kill_phase = "y";
  pnh.getParam("timeout_s", timeout_s);
  pnh.getParam("steps", steps);
  pnh.getParam("kill_phase", kill_phase);
  pnh.getParam("kill_step", kill_step);
  pnh.getParam("dwell_samples", dwell_samples);
  pnh.getParam("rate_hz", rate_hz);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  const int kill_phase_index = kill_phase == "x" ? 0 : kill_phase == "y" ? 1 : 2;
  const int kill_position = kill_phase_index * steps + kill_step;  // 0-based, protocol order
  ros::Subscriber s =
      nh.subscribe("/calibration/status", 10, &test_wait::LatestValues::on_message, &status);
  ros::Subscriber c = nh.subscribe("/gimbal/command", 1000, on_cmd);
  ros::Subscriber i = nh.subscribe("/imu/data_raw", 100000, on_imu);
  stand_checks::reset_and_start({&c, &i});
  if (HasFatalFailure()) return;

  // The SETTLED of the chosen position: hold the clock there (the stand stops inside the dwell).
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  // The cut dwell (dwell_s 2 s) must not be complete when the clock stops: 1.5 s leaves 0.5 s.
  hold_clock_in_dwell(kill_position, steps, deadline, 1.5);
  if (HasFatalFailure()) return;
  const std::size_t commands_at_kill = commands_seen();
  // The checkpoint as the killed node leaves it: the run continues after its last row.
  const std::size_t rows_at_kill =
      checkpoint_rows(run_dirs::latest(output_dir) + "/position_table.csv");
  ASSERT_LT(rows_at_kill, static_cast<std::size_t>(kill_position)) << "the cut dwell is not in it";
  const int pid = test_wait::node_pid("/calibration");
  ASSERT_GT(pid, 1);
  ASSERT_EQ(kill(pid, SIGKILL), 0);
  std::printf(
      "killed /calibration (pid %d) in the dwell of phase %s step %d; checkpoint: %zu rows\n", pid,
      kill_phase.c_str(), kill_step, rows_at_kill);

  // Respawned (clock still held): its services are up once it has reloaded the checkpoint; then
  // its subscription to the gimbal commands, connected before the clock runs on.
  bool back = false;
  while (!back && ros::WallTime::now() < deadline) {
    const int now_pid = test_wait::node_pid("/calibration");
    back = now_pid > 1 && now_pid != pid &&
           ros::service::exists("/calibration/get_intrinsics", false) &&
           subscribes("/calibration", "/gimbal/command") &&
           subscribes("/calibration", "/imu/data_raw");
    if (!back) ros::WallDuration(0.1).sleep();
  }
  ASSERT_TRUE(back) << "/calibration did not come back";
  // Its connections to the publishers (subscribing is registering with the master; the
  // connections follow).
  ASSERT_TRUE(test_wait::wait_for(
      [] {
        const std::set<std::string> c = test_wait::connected_inbound_topics("/calibration");
        return c.count("/clock") && c.count("/gimbal/command") && c.count("/imu/data_raw");
      },
      60.0, "the restarted /calibration to connect to /clock, /gimbal/command and /imu/data_raw"));
  ASSERT_EQ(commands_seen(), commands_at_kill) << "the stand moved while the clock was held";
  ASSERT_TRUE(pause_clock(false));

  accel_intrinsics::GetIntrinsics::Response res;
  while (ros::WallTime::now() < deadline) {
    accel_intrinsics::GetIntrinsics srv;
    if (ros::service::call("/calibration/get_intrinsics", srv) && srv.response.success) {
      res = srv.response;
      break;
    }
    ros::WallDuration(0.5).sleep();
  }
  ASSERT_TRUE(res.success) << res.message;
  // The status after the fit (published with the result), waited for with a generous bound.
  for (const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(60.0);
       status("state") != "RESULT" && ros::WallTime::now() < end;) {
    ros::WallDuration(0.05).sleep();
  }
  ASSERT_EQ(status("state"), "RESULT");
  EXPECT_EQ(status("restored"), "true");
  // The restarted node saw the MOVING that ended the cut dwell and rewound the controller to the
  // position after its last checkpointed row before the next SETTLED: no dwell measured before
  // the rewind, none discarded.
  EXPECT_EQ(status("dwells_discarded"), "0");

  std::vector<GimbalCommand> cmds;
  std::vector<double> stamps;
  {
    std::lock_guard<std::mutex> lock(seen_mutex);
    cmds = commands;
    stamps = imu_stamps;
  }
  std::sort(stamps.begin(), stamps.end());
  ASSERT_GE(cmds.size(), commands_at_kill + 2);
  const GimbalCommand& next = cmds[commands_at_kill];
  const GimbalCommand& rewound = cmds[commands_at_kill + 1];
  EXPECT_EQ(next.state, GimbalCommand::MOVING);
  EXPECT_EQ(static_cast<int>(next.phase * steps + next.step), kill_position + 1);
  EXPECT_EQ(rewound.state, GimbalCommand::MOVING) << "a SETTLED came before the rewind";
  EXPECT_EQ(static_cast<int>(rewound.phase * steps + rewound.step), static_cast<int>(rows_at_kill))
      << "the rewound protocol does not start after the checkpoint's last row";

  // The table: every position once, in order, each a complete dwell of the rewound protocol.
  core::PositionTable table =
      core::read_position_table_file(run_dirs::latest(output_dir) + "/position_table.csv");
  ASSERT_EQ(table.rows.size(), static_cast<std::size_t>(3 * steps));
  for (std::size_t r = 0; r < table.rows.size(); ++r) {
    const core::DwellRecord& row = table.rows[r];
    EXPECT_EQ(core::index(row.phase), static_cast<int>(r) / steps) << "row " << r;
    EXPECT_EQ(row.step, r % steps) << "row " << r;
    // Its SETTLED and the command after it, as the test received them.
    std::size_t k = 0;
    while (k < cmds.size() && !(cmds[k].state == GimbalCommand::SETTLED &&
                                cmds[k].header.stamp.toSec() == row.t_start_s)) {
      ++k;
    }
    ASSERT_LT(k + 1, cmds.size()) << "row " << r << ": no SETTLED at its t_start";
    EXPECT_EQ(core::index(row.phase), cmds[k].phase) << "row " << r;
    EXPECT_EQ(row.step, cmds[k].step) << "row " << r;
    EXPECT_EQ(row.t_end_s, cmds[k + 1].header.stamp.toSec())
        << "row " << r << ": not a whole dwell";
    if (r >= rows_at_kill) {
      EXPECT_GT(k, commands_at_kill) << "row " << r << " was measured before the kill";
    } else {
      EXPECT_LT(k, commands_at_kill) << "row " << r << " of the checkpoint";
    }
    // Its samples: those the test received inside the dwell (a sample stamped exactly at a
    // boundary may fall on either side: the assembler orders equal stamps as they come).
    const auto lo = std::upper_bound(stamps.begin(), stamps.end(), row.t_start_s);
    const auto hi = std::lower_bound(stamps.begin(), stamps.end(), row.t_end_s);
    const std::uint64_t inside = static_cast<std::uint64_t>(hi - lo);
    const std::uint64_t ties = std::count(stamps.begin(), stamps.end(), row.t_start_s) +
                               std::count(stamps.begin(), stamps.end(), row.t_end_s);
    EXPECT_GE(row.n, inside) << "row " << r;
    EXPECT_LE(row.n, inside + ties) << "row " << r;
    // A whole dwell: at least dwell_s * rate_hz samples (one less for a sample on the edge), as
    // many as its length holds at rate_hz (moves end on a clock tick: dwells run a little long).
    EXPECT_GE(row.n + 1, static_cast<std::uint64_t>(dwell_samples)) << "row " << r;
    EXPECT_NEAR(static_cast<double>(row.n), (row.t_end_s - row.t_start_s) * rate_hz, 2.0)
        << "row " << r;
  }
  std::printf("cut dwell (row %d): n = %llu; %s\n", kill_position,
              static_cast<unsigned long long>(table.rows[kill_position].n), res.message.c_str());
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "kill_in_dwell_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
