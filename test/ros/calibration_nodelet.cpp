// calibration_nodelet.test: end_to_end's checks on a stand whose calibration node is a nodelet in
// a nodelet manager (accel_intrinsics/CalibrationNodelet loaded into /imu_manager).
#include <xmlrpcpp/XmlRpcValue.h>

#include "end_to_end.cpp"

// Runs after EndToEnd (definition order): the calibration topics come from the manager's process.
TEST(CalibrationNodelet, RunsInsideTheManager) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  ASSERT_TRUE(ros::master::execute("getSystemState", args, result, payload, true));
  std::vector<std::string> publishers;
  for (int i = 0; i < payload[0].size(); ++i) {
    if (static_cast<std::string>(payload[0][i][0]) != "/calibration/status") continue;
    for (int j = 0; j < payload[0][i][1].size(); ++j) {
      publishers.push_back(static_cast<std::string>(payload[0][i][1][j]));
    }
  }
  EXPECT_EQ(publishers, std::vector<std::string>{"/imu_manager"});
}
