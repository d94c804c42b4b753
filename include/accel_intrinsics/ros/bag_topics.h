// Which topics of a bag hold the run: the bag's topic list and the rules that turn a requested
// name ("imu/data_raw", "/stand1/imu/data_raw") into a topic of the bag.
#pragma once

#include <rosbag/bag.h>

#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_record.h"
#include "accel_intrinsics/ros/bag_format.h"

namespace accel_intrinsics {

// The bag's topics, sorted by name.
std::vector<BagTopic> list_topics(rosbag::Bag& bag);
// "/a (type, N msgs), /b (...)" for messages.
std::string describe_topics(const std::vector<BagTopic>& topics);

// Finds the bag topic meant by `requested`. Rules, in order:
//   1. exact match, ignoring one leading '/' on either side;
//   2. unless `requested` starts with '/': topics ending in "/<requested>" (namespaced); one
//      candidate wins, several are narrowed to the one in `preferred_namespace` (e.g. the
//      namespace of the other topic, "/stand1/"), else the lookup is ambiguous.
// Throws BagInputError naming the topic and listing the bag's topics when none or several match,
// or when the match has a type other than `expected_datatype` (empty = any).
std::string resolve_topic(const std::string& requested, const std::vector<BagTopic>& topics,
                          const std::string& expected_datatype,
                          const std::string& preferred_namespace = "");

// The namespace prefix of a resolved topic given the requested relative name:
// ("/stand1/imu/data_raw", "imu/data_raw") -> "/stand1/"; "/" when not namespaced.
std::string topic_namespace(const std::string& resolved, const std::string& requested);

// An optional topic (a channel's, imu/temperature): "" when no topic of the bag has the requested
// name (exact or namespaced); otherwise resolve_topic(), which throws for an ambiguous name or
// another type.
std::string resolve_optional_topic(const std::string& requested,
                                   const std::vector<BagTopic>& topics,
                                   const std::string& expected_datatype,
                                   const std::string& preferred_namespace = "");

// The IMU (sensor_msgs/Imu) and gimbal command (accel_intrinsics/GimbalCommand) topics of a run.
struct RunTopics {
  std::string imu;
  std::string command;
  // Each per-dwell channel's topic (core::kChannels, of its message type); "" when the bag has
  // none (channels are optional).
  core::PerChannel<std::string> channels;
  std::string note;  // how a topic was found when not by its name, for the user
};

// Resolves both topics of a run with resolve_topic(); when one of them is ambiguous between
// namespaces, the namespace of the other decides (several stands recorded in one bag). With
// `imu_by_type` (the IMU topic was not named by the user), a bag without the default IMU topic
// but with exactly one sensor_msgs/Imu topic uses that one and says so in `note`.
// The channels' topics `channels_requested` are optional ("" skips one) and preferred in the
// IMU's namespace. With `command_optional`, a bag without any GimbalCommand topic (a hand tumble)
// resolves with `command` empty.
RunTopics resolve_run_topics(const std::string& imu_requested, const std::string& command_requested,
                             const std::vector<BagTopic>& topics, bool imu_by_type = false,
                             const core::PerChannel<std::string>& channels_requested = {},
                             bool command_optional = false);

}  // namespace accel_intrinsics
