// A two-axis gimbal on GRBL 1.1: see test/ros/grbl_stand.test.
#include <map>

#include "serial_checks.h"
#include "stand_checks.h"

TEST(GrblStand, ProtocolOnTheEmulatorMatchesTruth) {
  ros::NodeHandle pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  double timeout_s = 240.0;
  int steps = 6;
  std::string output_dir, log;
  pnh.getParam("timeout_s", timeout_s);
  pnh.getParam("steps", steps);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  ASSERT_TRUE(pnh.getParam("log", log));
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(90.0)));
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/start", ros::Duration(90.0)));

  stand_checks::supervise_and_check({""}, limits, timeout_s, output_dir + "/supervise.json");
  const accel_intrinsics::GetIntrinsics::Response res = stand_checks::get_intrinsics("");
  ASSERT_TRUE(res.success) << res.message;
  stand_checks::Truth truth;
  ASSERT_TRUE(stand_checks::load_truth("", &truth));
  stand_checks::expect_matches_truth(res.result, truth, limits, "grbl stand");
  for (int p = 0; p < 3; ++p) EXPECT_EQ(res.result.positions[p], static_cast<unsigned>(steps));

  // The moves the protocol needs, from the axis map of config/grbl_gimbal.yaml as the test reads
  // it from the parameter server: "G21 G90 G0" with every axis of the phase, in order.
  std::vector<std::string> expected;
  const char* phases[] = {"x", "y", "z"};
  for (const char* phase : phases) {
    const std::string key = std::string("/gimbal_controller/grbl/phases/") + phase;
    std::string axis;
    double sign = 1.0, zero = 0.0;
    std::map<std::string, double> hold;
    ASSERT_TRUE(ros::param::get(key + "/axis", axis));
    ros::param::get(key + "/sign", sign);
    ros::param::get(key + "/zero_deg", zero);
    ros::param::get(key + "/hold", hold);
    for (int n = 0; n < steps; ++n) {
      std::map<std::string, double> positions = hold;
      positions[axis] = zero + sign * serial_checks::alpha_deg(n, steps);
      std::string line = "G21 G90 G0";
      for (const auto& p : positions) line += " " + p.first + serial_checks::fixed4(p.second);
      expected.push_back(line);
    }
  }
  const std::vector<std::string> commands = serial_checks::read_lines(log);
  ASSERT_FALSE(commands.empty()) << log;
  EXPECT_EQ(commands.front(), "^X") << "the driver starts with a soft reset";
  std::vector<std::string> moves;
  std::size_t polls = 0, resets = 0;
  for (const std::string& c : commands) {
    if (c == "?") {
      ++polls;
    } else if (c == "^X") {
      ++resets;
    } else if (c.rfind("G21 G90 G0", 0) == 0) {
      moves.push_back(c);
    } else {
      ADD_FAILURE() << "a command the protocol does not need: '" << c << "'";
    }
  }
  EXPECT_EQ(resets, 1u) << "one soft reset, at start (no abort)";
  EXPECT_EQ(moves, expected);
  EXPECT_GT(polls, moves.size()) << "status polls";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "grbl_stand_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
