// The one way the tests write bags: a recorded run (gimbal commands, IMU samples, channel readings
// such as temperatures) as a recorder would write it. Bag (receive) time = stamp +
// receive_delay_s unless a message says otherwise; topics and frame id as the stand's defaults.
// Used by the tests that build bags by hand or from a simulated core::Recording.
#pragma once

#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/Temperature.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>

#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/ros/conversions.h"

namespace accel_intrinsics {
namespace test_support {

class BagWriter {
 public:
  std::string imu_topic = "/imu/data_raw";
  std::string command_topic = "/gimbal/command";
  std::string temperature_topic = "/imu/temperature";
  std::string frame_id = "dut";
  bool padded_imu = false;       // IMU messages with other fields filled (see sample())
  double receive_delay_s = 0.0;  // bag time after the stamp (a recorder's transport delay)
  // Added to every stamp (and so to the bag time): a run recorded later than the simulation's 0.
  double stamp_offset_s = 0.0;

  explicit BagWriter(const std::string& path) { bag_.open(path, rosbag::bagmode::Write); }
  ~BagWriter() { close(); }
  rosbag::Bag& bag() { return bag_; }  // compression etc., before the first write
  void close() {
    if (open_) bag_.close();
    open_ = false;
  }

  // Any message on any topic at bag time `receive_s` (a topic of another type, a hand-made
  // message).
  template <class Msg>
  void write(const std::string& topic, double receive_s, const Msg& msg) {
    bag_.write(topic, ros::Time(receive_s), msg);
  }
  template <class Msg>
  void write(const std::string& topic, const ros::Time& receive, const Msg& msg) {
    bag_.write(topic, receive, msg);
  }

  void command(core::GimbalEvent e, double receive_s = kAtStamp) {
    e.stamp_s += stamp_offset_s;
    write(command_topic, receive_time(e.stamp_s, receive_s), to_msg(e));
  }
  // The message's own numbers (GimbalCommand::PHASE_X.., ::MOVING..), malformed ones too.
  void command(double stamp_s, int phase, std::uint32_t step, std::uint32_t steps, double angle_rad,
               int state, double receive_s = kAtStamp) {
    GimbalCommand msg;
    msg.header.stamp.fromSec(stamp_s + stamp_offset_s);
    msg.phase = static_cast<std::uint8_t>(phase);
    msg.step = step;
    msg.steps = steps;
    msg.angle = angle_rad;
    msg.state = static_cast<std::uint8_t>(state);
    write(command_topic, receive_time(stamp_s + stamp_offset_s, receive_s), msg);
  }
  // Returns the message written (tests compare what a node received).
  // The IMU message of a sample (stamp as given), as sample() writes it.
  sensor_msgs::Imu imu_message(const core::ImuSample& s) const {
    sensor_msgs::Imu msg = to_msg(s, frame_id);
    if (padded_imu) {
      // Fields around linear_acceleration that a reader must skip, never read as it.
      msg.angular_velocity.x = 123.0;
      for (int i = 0; i < 9; ++i) msg.linear_acceleration_covariance[i] = 1e-6 * (i + 1);
    }
    return msg;
  }
  sensor_msgs::Imu sample(core::ImuSample s, double receive_s = kAtStamp) {
    s.stamp_s += stamp_offset_s;
    const sensor_msgs::Imu msg = imu_message(s);
    write(imu_topic, receive_time(s.stamp_s, receive_s), msg);
    return msg;
  }
  sensor_msgs::Imu sample(double stamp_s, const Eigen::Vector3d& outputs,
                          double receive_s = kAtStamp) {
    return sample(core::ImuSample{stamp_s, outputs}, receive_s);
  }
  void temperature(double stamp_s, double celsius, double receive_s = kAtStamp) {
    sensor_msgs::Temperature msg;
    msg.header.stamp.fromSec(stamp_s + stamp_offset_s);
    msg.header.frame_id = frame_id;
    msg.temperature = celsius;
    msg.variance = 0.0;
    write(temperature_topic, receive_time(stamp_s + stamp_offset_s, receive_s), msg);
  }

  // A simulated recording merged by stamp, a command first at equal stamps, as the messages
  // would arrive; temperatures (when recorded) before the sample of the same stamp. The callbacks
  // see each command and IMU message as it is written.
  void recording(const core::Recording& rec,
                 const std::function<void(const core::GimbalEvent&)>& on_command = {},
                 const std::function<void(const sensor_msgs::Imu&)>& on_sample = {}) {
    std::size_t c = 0, k = 0;
    for (const core::ImuSample& s : rec.samples) {
      while (c < rec.commands.size() && rec.commands[c].stamp_s <= s.stamp_s) {
        command(rec.commands[c]);
        if (on_command) on_command(rec.commands[c]);
        ++c;
      }
      while (k < rec.temperatures.size() && rec.temperatures[k].stamp_s <= s.stamp_s) {
        temperature(rec.temperatures[k].stamp_s, rec.temperatures[k].temperature_c);
        ++k;
      }
      const sensor_msgs::Imu msg = sample(s);
      if (on_sample) on_sample(msg);
    }
    for (; c < rec.commands.size(); ++c) {  // DONE, when the recording ends with it
      command(rec.commands[c]);
      if (on_command) on_command(rec.commands[c]);
    }
    for (; k < rec.temperatures.size(); ++k)
      temperature(rec.temperatures[k].stamp_s, rec.temperatures[k].temperature_c);
  }

  static constexpr double kAtStamp = std::numeric_limits<double>::quiet_NaN();

 private:
  double receive_time(double stamp_s, double receive_s) const {
    return std::isnan(receive_s) ? stamp_s + receive_delay_s : receive_s;
  }
  rosbag::Bag bag_;
  bool open_ = true;
};

}  // namespace test_support
}  // namespace accel_intrinsics
