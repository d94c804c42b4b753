// A serial fault on the GRBL gimbal: see test/ros/grbl_alarm.test and fault_checks.h.
#include "fault_checks.h"
#include "run_dirs.h"

TEST(SerialFault, grbl_alarm) {
  fault_checks::check_case();
  // Nothing of the completed dwells is lost: x/0..x/5 and y/0 (closed by the MOVING of y/1, the
  // move that failed) reach the checkpointed table once the reorder window has passed.
  std::string output_dir;
  ASSERT_TRUE(ros::NodeHandle("~").getParam("output_dir", output_dir));
  const std::string table = run_dirs::latest(output_dir) + "/position_table.csv";
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(20.0);
  while (stand_checks::count_csv_rows(table) < 7 && ros::WallTime::now() < end) {
    ros::WallDuration(0.2).sleep();
  }
  EXPECT_EQ(stand_checks::count_csv_rows(table), 7u);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "grbl_alarm_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
