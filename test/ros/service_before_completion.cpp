// get_intrinsics before completion (test/ros/service_before_completion.test).
#include <diagnostic_msgs/DiagnosticStatus.h>
#include <std_srvs/Trigger.h>

#include "stand_checks.h"
#include "wait_for.h"

namespace {
test_wait::LatestValues progress_value;  // gimbal_controller/progress
test_wait::LatestValues status_value;    // calibration/status, latched
}  // namespace

TEST(ServiceBeforeCompletion, NamesTheMissingPhase) {
  ros::NodeHandle nh, pnh("~");
  int steps = 6;
  double timeout_s = 120.0;
  pnh.getParam("steps", steps);
  pnh.getParam("timeout_s", timeout_s);
  ros::Subscriber sub = nh.subscribe("/gimbal_controller/progress", 10,
                                     &test_wait::LatestValues::on_message, &progress_value);
  ros::Subscriber status_sub =
      nh.subscribe("/calibration/status", 10, &test_wait::LatestValues::on_message, &status_value);
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(60.0)));
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/start", ros::Duration(60.0)));

  // Before anything ran: every phase is missing, phase x first.
  accel_intrinsics::GetIntrinsics::Response r = stand_checks::get_intrinsics("");
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message.find("phase x (0 of " + std::to_string(steps) + " dwells)"),
            std::string::npos)
      << r.message;

  std_srvs::Trigger start;
  ASSERT_TRUE(ros::service::call("/gimbal_controller/start", start));
  ASSERT_TRUE(start.response.success) << start.response.message;
  // A second start while running is refused with a reason.
  std_srvs::Trigger again;
  ASSERT_TRUE(ros::service::call("/gimbal_controller/start", again));
  EXPECT_FALSE(again.response.success);
  EXPECT_NE(again.response.message.find("already running"), std::string::npos);

  // Wait until the gimbal is in phase y, past its second dwell.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::WallTime::now() < deadline &&
         !(progress_value("phase") == "y" && !progress_value("step").empty() &&
           std::stoi(progress_value("step")) >= 2)) {
    ros::WallDuration(0.05).sleep();
  }
  ASSERT_EQ(progress_value("phase"), "y") << "the gimbal never reached phase y";
  // Past the reorder window of the dwells before: the node has released phase x's dwells.
  ASSERT_TRUE(test_wait::wait_for([&] { return status_value("dwells_x") == std::to_string(steps); },
                                  60.0, "calibration/status to count the phase x dwells"))
      << "dwells_x " << status_value("dwells_x");

  r = stand_checks::get_intrinsics("");
  EXPECT_FALSE(r.success);
  // Phase x is complete; y is partly done; z has nothing.
  EXPECT_EQ(r.message.find("phase x ("), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("phase y ("), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("phase z (0 of " + std::to_string(steps) + " dwells)"),
            std::string::npos)
      << r.message;

  // Abort: DONE closes the run, the fit fails, and the message still names what is missing.
  std_srvs::Trigger abort;
  ASSERT_TRUE(ros::service::call("/gimbal_controller/abort", abort));
  EXPECT_TRUE(abort.response.success) << abort.response.message;
  // The abort reaches the calibration node (its run is ABORTED), waited for, not slept.
  ASSERT_TRUE(test_wait::wait_for([] { return status_value("state") == "ABORTED"; }, 60.0,
                                  "calibration/status ABORTED"))
      << "calibration state " << status_value("state");
  r = stand_checks::get_intrinsics("");
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message.find("phase z (0 of"), std::string::npos) << r.message;
  EXPECT_EQ(progress_value("state"), "ABORTED");
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "service_before_completion_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
