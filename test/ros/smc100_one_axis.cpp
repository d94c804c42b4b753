// A one-axis stage on an SMC100 with manual remounts: see test/ros/smc100_one_axis.test.
#include <std_srvs/Trigger.h>

#include <mutex>

#include "accel_intrinsics/GimbalCommand.h"
#include "serial_checks.h"
#include "stand_checks.h"
#include "wait_for.h"

namespace {

std::mutex mutex;
test_wait::LatestValues progress;  // gimbal_controller/progress
std::vector<accel_intrinsics::GimbalCommand> commands;

void on_command(const accel_intrinsics::GimbalCommand::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(mutex);
  commands.push_back(*msg);
}

std::size_t command_count() {
  std::lock_guard<std::mutex> lock(mutex);
  return commands.size();
}

}  // namespace

TEST(Smc100OneAxis, ManualRemountThroughContinue) {
  ros::NodeHandle nh, pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  double timeout_s = 240.0, remount_wait_s = 2.0;
  int steps = 6;
  std::string log;
  pnh.getParam("timeout_s", timeout_s);
  pnh.getParam("steps", steps);
  pnh.getParam("remount_wait_s", remount_wait_s);
  ASSERT_TRUE(pnh.getParam("log", log));
  ros::Subscriber progress_sub = nh.subscribe("/gimbal_controller/progress", 100,
                                              &test_wait::LatestValues::on_message, &progress);
  ros::Subscriber command_sub = nh.subscribe("/gimbal/command", 1000, on_command);
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(90.0)));
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/start", ros::Duration(90.0)));
  // The controller advertises its services one after the other: start up does not mean continue.
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/continue", ros::Duration(90.0)));

  // continue before any remount is refused.
  std_srvs::Trigger early;
  ASSERT_TRUE(ros::service::call("/gimbal_controller/continue", early));
  EXPECT_FALSE(early.response.success);

  std_srvs::Trigger reset, start;
  ASSERT_TRUE(ros::service::call("/calibration/reset", reset));
  ros::WallDuration(0.5).sleep();
  ASSERT_TRUE(ros::service::call("/gimbal_controller/start", start));
  ASSERT_TRUE(start.response.success) << start.response.message;

  std::vector<std::string> remounted;  // phases, in order
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::WallTime::now() < deadline && progress("state") != "DONE") {
    ASSERT_NE(progress("state"), "ABORTED") << progress.message();
    if (progress("state") == "REMOUNT") {
      const std::string phase = progress("phase");
      EXPECT_NE(progress.message().find("remount the DUT"), std::string::npos)
          << progress.message();
      EXPECT_NE(progress.message().find("gimbal_controller/continue"), std::string::npos);
      // The stage waits for the operator: no further gimbal command, state unchanged.
      const std::size_t before = command_count();
      ros::WallDuration(remount_wait_s).sleep();
      EXPECT_EQ(command_count(), before) << "the controller went on during the remount";
      EXPECT_EQ(progress("state"), "REMOUNT");
      std_srvs::Trigger go;
      ASSERT_TRUE(ros::service::call("/gimbal_controller/continue", go));
      ASSERT_TRUE(go.response.success) << go.response.message;
      remounted.push_back(phase);
      while (progress("state") == "REMOUNT" && ros::WallTime::now() < deadline) {
        ros::WallDuration(0.05).sleep();
      }
    }
    ros::WallDuration(0.05).sleep();
  }
  ASSERT_EQ(progress("state"), "DONE") << progress.message();
  EXPECT_EQ(remounted, (std::vector<std::string>{"y", "z"}));

  // The last command before each remount is the MOVING that closed the phase's last dwell.
  {
    std::lock_guard<std::mutex> lock(mutex);
    int moving_y0 = 0;
    for (const auto& c : commands) {
      moving_y0 +=
          c.state == accel_intrinsics::GimbalCommand::MOVING && c.phase == 1 && c.step == 0;
    }
    EXPECT_EQ(moving_y0, 1) << "one MOVING for y/0, published before the remount";
  }

  // The result, once fitted.
  accel_intrinsics::GetIntrinsics::Response res;
  const ros::WallTime fit_deadline = ros::WallTime::now() + ros::WallDuration(60.0);
  do {
    ros::WallDuration(0.5).sleep();
    res = stand_checks::get_intrinsics("");
  } while (!res.success && ros::WallTime::now() < fit_deadline);
  ASSERT_TRUE(res.success) << res.message;
  stand_checks::Truth truth;
  ASSERT_TRUE(stand_checks::load_truth("", &truth));
  stand_checks::expect_matches_truth(res.result, truth, limits, "smc100 one-axis stage");
  for (int p = 0; p < 3; ++p) EXPECT_EQ(res.result.positions[p], static_cast<unsigned>(steps));

  // The emulator's log: homing once, then per position "1PA<deg>" checked by "1TE?" (the first
  // position of y and z twice: the stage turns there before the remount and again after
  // continue), status and position queries, nothing else.
  std::vector<std::string> expected_moves;
  for (int phase = 0; phase < 3; ++phase) {
    for (int n = 0; n < steps; ++n) {
      const std::string pa = "1PA" + serial_checks::fixed4(serial_checks::alpha_deg(n, steps));
      expected_moves.push_back(pa);
      if (phase > 0 && n == 0) expected_moves.push_back(pa);
    }
  }
  const std::vector<std::string> lines = serial_checks::read_lines(log);
  std::vector<std::string> moves;
  std::size_t homes = 0, checks = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::string& c = lines[i];
    if (c == "1OR") {
      ++homes;
    } else if (c.rfind("1PA", 0) == 0) {
      moves.push_back(c);
      // The next command asks for the error of this one.
      EXPECT_TRUE(i + 1 < lines.size() && lines[i + 1] == "1TE?") << "after " << c;
    } else if (c == "1TE?") {
      ++checks;
    } else if (c != "1TS?" && c != "1TP?") {
      ADD_FAILURE() << "a command the protocol does not need: '" << c << "'";
    }
  }
  EXPECT_EQ(homes, 1u);
  EXPECT_EQ(checks, moves.size() + homes);
  EXPECT_EQ(moves, expected_moves);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "smc100_one_axis_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
