// A reference for the ros_joint load row (bench/run ros_joint_load, issue 33): a roscpp node that
// subscribes to joint_states and does nothing with the messages, but is woken for each one by
// ros::spin. Its CPU share at 1 kHz is what a naive subscriber pays for the stream; the gimbal
// controller takes the messages from its own queue at each tick instead.
//
//   rosrun accel_intrinsics joint_state_sink &
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>

namespace {
void ignore(const sensor_msgs::JointState::ConstPtr&) {}
}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "joint_state_sink", ros::init_options::AnonymousName);
  ros::NodeHandle nh;
  // The same topic and queue depth as the ros_joint driver's subscription.
  ros::Subscriber sub = nh.subscribe("joint_states", 1000, ignore);
  ros::spin();
  return 0;
}
