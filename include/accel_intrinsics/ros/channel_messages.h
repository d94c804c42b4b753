// The ROS message of each per-dwell channel (core::kChannels): how a message becomes a
// core::ChannelSample, live (a subscription) and from a bag (a serialized message). The one place
// that names the message types; everything else iterates over channel_messages().
#pragma once

#include <ros/ros.h>
#include <rosbag/message_instance.h>

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_record.h"

namespace accel_intrinsics {

struct ChannelMessage {
  core::Channel channel;
  std::string datatype;  // "sensor_msgs/Temperature"; equals the channel's message_type
  std::string md5sum;
  using Sink = std::function<void(const core::ChannelSample&)>;
  // Subscribes `sink` to `topic` (the value and the header stamp of each message).
  std::function<ros::Subscriber(ros::NodeHandle&, const std::string& topic, std::uint32_t queue,
                                Sink sink)>
      subscribe;
  // The sample of a serialized message (bag chunk scan); throws
  // ros::serialization::StreamOverrunException when the data is short.
  std::function<core::ChannelSample(std::uint8_t* data, std::uint32_t length)> deserialize;
  // The sample of a bag message; nothing when it is of another type.
  std::function<std::optional<core::ChannelSample>(const rosbag::MessageInstance&)> instantiate;
};

// One per channel, indexed by core::channel_index().
const std::vector<ChannelMessage>& channel_messages();

// The default topic of each channel (core::ChannelSpec::topic).
core::PerChannel<std::string> default_channel_topics();

}  // namespace accel_intrinsics
