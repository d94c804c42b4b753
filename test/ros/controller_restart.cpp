// SIGKILL the gimbal controller mid-protocol; roslaunch respawns it and the calibration node has
// it continue after the last recorded dwell (test/ros/controller_restart.test).
#include "kill_mid_protocol.h"

TEST(ControllerRestart, FinalResultIsTheFitOfTheCompleteTable) {
  kill_mid_protocol_and_check("/gimbal_controller");
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "controller_restart_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
