#include "accel_intrinsics/ros/channel_messages.h"

#include <sensor_msgs/Temperature.h>

#include <stdexcept>

namespace accel_intrinsics {

namespace {

// The binding of channel `c` to message type Msg, whose value `value_of` reads.
template <class Msg, class ValueOf>
ChannelMessage bind(core::Channel c, ValueOf value_of) {
  ChannelMessage m;
  m.channel = c;
  m.datatype = ros::message_traits::DataType<Msg>::value();
  m.md5sum = ros::message_traits::MD5Sum<Msg>::value();
  auto sample_of = [c, value_of](const Msg& msg) {
    return core::ChannelSample{c, msg.header.stamp.toSec(), value_of(msg)};
  };
  m.subscribe = [sample_of](ros::NodeHandle& nh, const std::string& topic, std::uint32_t queue,
                            ChannelMessage::Sink sink) {
    return nh.subscribe<Msg>(
        topic, queue,
        boost::function<void(const typename Msg::ConstPtr&)>(
            [sample_of, sink](const typename Msg::ConstPtr& msg) { sink(sample_of(*msg)); }));
  };
  m.deserialize = [sample_of](std::uint8_t* data, std::uint32_t length) {
    Msg msg;
    ros::serialization::IStream stream(data, length);
    ros::serialization::deserialize(stream, msg);
    return sample_of(msg);
  };
  m.instantiate = [sample_of](const rosbag::MessageInstance& instance) {
    const auto msg = instance.instantiate<Msg>();
    return msg ? std::optional<core::ChannelSample>(sample_of(*msg)) : std::nullopt;
  };
  return m;
}

std::vector<ChannelMessage> make_bindings() {
  // In the order of core::kChannels.
  std::vector<ChannelMessage> bindings{
      bind<sensor_msgs::Temperature>(
          core::Channel::Temperature,
          [](const sensor_msgs::Temperature& m) { return m.temperature; }),
  };
  if (bindings.size() != core::kChannelCount)
    throw std::logic_error("channel_messages: one binding per core::kChannels row");
  for (std::size_t i = 0; i < bindings.size(); ++i) {
    const core::ChannelSpec& spec = core::kChannels[i];
    if (bindings[i].channel != spec.id || bindings[i].datatype != spec.message_type)
      throw std::logic_error(std::string("channel_messages: the binding of channel ") + spec.name +
                             " is not for " + spec.message_type);
  }
  return bindings;
}

}  // namespace

const std::vector<ChannelMessage>& channel_messages() {
  static const std::vector<ChannelMessage> bindings = make_bindings();
  return bindings;
}

core::PerChannel<std::string> default_channel_topics() {
  core::PerChannel<std::string> topics;
  for (const core::ChannelSpec& spec : core::kChannels)
    topics[core::channel_index(spec.id)] = spec.topic;
  return topics;
}

}  // namespace accel_intrinsics
