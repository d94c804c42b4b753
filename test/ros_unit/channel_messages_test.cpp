// The ROS side of the per-dwell channels (ros/channel_messages.h): one binding per row of
// core::kChannels, of the row's message type, and a message read back as the sample it was.
#include "accel_intrinsics/ros/channel_messages.h"

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Temperature.h>

#include <vector>

#include "../support/bag_writer.h"
#include "../support/test_files.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

TEST(ChannelMessages, OneBindingPerChannelOfItsMessageType) {
  const std::vector<ai::ChannelMessage>& bindings = ai::channel_messages();
  ASSERT_EQ(bindings.size(), core::kChannelCount);
  for (std::size_t c = 0; c < core::kChannelCount; ++c) {
    EXPECT_EQ(bindings[c].channel, core::kChannels[c].id);
    EXPECT_EQ(bindings[c].datatype, core::kChannels[c].message_type);
    EXPECT_FALSE(bindings[c].md5sum.empty());
    EXPECT_EQ(ai::default_channel_topics()[c], core::kChannels[c].topic);
  }
}

TEST(ChannelMessages, ATemperatureMessageIsReadBackAsItsSample) {
  ai::test_support::TempDir dir;
  {
    ai::test_support::BagWriter writer(dir.file("t.bag"));
    writer.temperature(12.25, 31.5);
  }
  const ai::ChannelMessage& binding =
      ai::channel_messages()[core::channel_index(core::Channel::Temperature)];
  rosbag::Bag bag(dir.file("t.bag"));
  rosbag::View view(bag);
  std::vector<core::ChannelSample> read;
  for (const rosbag::MessageInstance& m : view) {
    const auto sample = binding.instantiate(m);
    ASSERT_TRUE(sample.has_value());
    read.push_back(*sample);
    // The same message serialized, as the chunk scan reads it.
    const auto msg = m.instantiate<sensor_msgs::Temperature>();
    std::vector<std::uint8_t> buffer(ros::serialization::serializationLength(*msg));
    ros::serialization::OStream out(buffer.data(), static_cast<std::uint32_t>(buffer.size()));
    ros::serialization::serialize(out, *msg);
    const core::ChannelSample again =
        binding.deserialize(buffer.data(), static_cast<std::uint32_t>(buffer.size()));
    EXPECT_EQ(again.value, sample->value);
    EXPECT_EQ(again.stamp_s, sample->stamp_s);
  }
  ASSERT_EQ(read.size(), 1u);
  EXPECT_EQ(read[0].channel, core::Channel::Temperature);
  EXPECT_EQ(read[0].value, 31.5);
  EXPECT_DOUBLE_EQ(read[0].stamp_s, 12.25);
}
