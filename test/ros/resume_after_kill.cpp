// SIGKILL the calibration node mid-protocol; it respawns, reloads its checkpoint and has the
// gimbal controller continue (test/ros/resume_after_kill.test).
#include "kill_mid_protocol.h"

TEST(ResumeAfterKill, FinalResultIsTheFitOfTheCompleteCheckpointedTable) {
  kill_mid_protocol_and_check("/calibration");
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "resume_after_kill_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}
