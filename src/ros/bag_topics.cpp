// Topic resolution for bag reading (bag_topics.h).
#include "accel_intrinsics/ros/bag_topics.h"

#include <rosbag/view.h>

#include <algorithm>
#include <map>

#include "accel_intrinsics/ros/names.h"

namespace accel_intrinsics {

namespace {

constexpr char kImuType[] = "sensor_msgs/Imu";
constexpr char kCommandType[] = "accel_intrinsics/GimbalCommand";

std::string strip_slash(const std::string& name) {
  return (!name.empty() && name[0] == '/') ? name.substr(1) : name;
}

bool ends_with(const std::string& text, const std::string& suffix) {
  return text.size() >= suffix.size() &&
         text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Every channel's topic, preferred in `ns`.
core::PerChannel<std::string> resolve_channels(const core::PerChannel<std::string>& requested,
                                               const std::vector<BagTopic>& topics,
                                               const std::string& ns) {
  core::PerChannel<std::string> resolved;
  for (const core::ChannelSpec& spec : core::kChannels) {
    const std::size_t c = core::channel_index(spec.id);
    resolved[c] = resolve_optional_topic(requested[c], topics, spec.message_type, ns);
  }
  return resolved;
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

// The namespace around the default name when the resolved topic has it ("/stand2/imu/data_raw"
// -> "/stand2/", even when asked for as "stand2/imu/data_raw"), else around the request.
std::string namespace_of(const std::string& resolved, const std::string& default_name,
                         const std::string& requested) {
  return ends_with(resolved, "/" + default_name) ? topic_namespace(resolved, default_name)
                                                 : topic_namespace(resolved, requested);
}

}  // namespace

std::vector<BagTopic> list_topics(rosbag::Bag& bag) {
  std::map<std::string, BagTopic> by_name;
  rosbag::View view(bag);
  for (const rosbag::ConnectionInfo* connection : view.getConnections()) {
    BagTopic& topic = by_name[connection->topic];
    topic.name = connection->topic;
    if (topic.datatype.empty())
      topic.datatype = connection->datatype;
    else if (topic.datatype != connection->datatype)
      topic.datatype += "|" + connection->datatype;
  }
  for (auto& entry : by_name) {
    rosbag::View count(bag, rosbag::TopicQuery(entry.first));
    entry.second.messages = count.size();
  }
  std::vector<BagTopic> topics;
  for (auto& entry : by_name) topics.push_back(entry.second);
  return topics;
}

std::string describe_topics(const std::vector<BagTopic>& topics) {
  if (topics.empty()) return "(none: the bag has no messages)";
  std::vector<std::string> items;
  for (const BagTopic& t : topics) {
    items.push_back(t.name + " (" + t.datatype + ", " + std::to_string(t.messages) + " msgs)");
  }
  return join(items);
}

std::string resolve_topic(const std::string& requested, const std::vector<BagTopic>& topics,
                          const std::string& expected_datatype,
                          const std::string& preferred_namespace) {
  if (requested.empty() || requested == "/") throw BagInputError("empty topic name requested");
  const std::string wanted = strip_slash(requested);
  const bool absolute = requested[0] == '/';

  std::vector<const BagTopic*> candidates;
  for (const BagTopic& t : topics) {
    if (strip_slash(t.name) == wanted) candidates.push_back(&t);
  }
  if (candidates.empty() && !absolute) {
    for (const BagTopic& t : topics) {
      if (ends_with(t.name, "/" + wanted)) candidates.push_back(&t);
    }
    if (candidates.size() > 1 && !preferred_namespace.empty()) {
      std::vector<const BagTopic*> preferred;
      for (const BagTopic* t : candidates) {
        if (t->name == preferred_namespace + wanted) preferred.push_back(t);
      }
      if (preferred.size() == 1) candidates = preferred;
    }
  }
  if (candidates.empty()) {
    throw BagInputError("topic '" + requested +
                        "' not found in the bag; its topics are: " + describe_topics(topics));
  }
  if (candidates.size() > 1) {
    std::vector<std::string> names;
    for (const BagTopic* t : candidates) names.push_back(t->name);
    throw BagInputError("topic '" + requested + "' is ambiguous in the bag: " + join(names) +
                        "; pass the full name");
  }
  const BagTopic& found = *candidates.front();
  if (!expected_datatype.empty() && found.datatype != expected_datatype) {
    throw BagInputError("topic '" + found.name + "' has type " + found.datatype + ", expected " +
                        expected_datatype);
  }
  return found.name;
}

std::string resolve_optional_topic(const std::string& requested,
                                   const std::vector<BagTopic>& topics,
                                   const std::string& expected_datatype,
                                   const std::string& preferred_namespace) {
  if (requested.empty()) return "";
  const std::string wanted = strip_slash(requested);
  const bool absolute = requested[0] == '/';
  bool any = false;
  for (const BagTopic& t : topics) {
    any = any || strip_slash(t.name) == wanted || (!absolute && ends_with(t.name, "/" + wanted));
  }
  if (!any) return "";
  return resolve_topic(requested, topics, expected_datatype, preferred_namespace);
}

std::string topic_namespace(const std::string& resolved, const std::string& requested) {
  const std::string wanted = "/" + strip_slash(requested);
  const std::string full = resolved.empty() || resolved[0] == '/' ? resolved : "/" + resolved;
  if (ends_with(full, wanted)) return full.substr(0, full.size() - wanted.size()) + "/";
  return "/";
}

RunTopics resolve_run_topics(const std::string& imu_requested, const std::string& command_requested,
                             const std::vector<BagTopic>& topics, bool imu_by_type,
                             const core::PerChannel<std::string>& channels_requested,
                             bool command_optional) {
  RunTopics run;
  // Resolve the IMU first; its namespace disambiguates the command topic, and vice versa.
  try {
    run.imu = resolve_topic(imu_requested, topics, kImuType);
  } catch (const BagInputError& imu_error) {
    // Several namespaced IMU topics: retry in the namespace of the command topic when that one
    // is unambiguous; otherwise report the IMU topic's own problem.
    std::vector<std::string> imu_topics;
    for (const BagTopic& t : topics) {
      if (t.datatype == kImuType) imu_topics.push_back(t.name);
    }
    std::string command;
    try {
      command = resolve_topic(command_requested, topics, kCommandType);
    } catch (const BagInputError&) {
      throw imu_error;
    }
    try {
      run.imu = resolve_topic(imu_requested, topics, kImuType,
                              namespace_of(command, names::kGimbalCommandTopic, command_requested));
    } catch (const BagInputError&) {
      // The driver published under another name: the only IMU topic of the bag is the one.
      if (!imu_by_type || imu_topics.size() != 1) throw;
      run.imu = imu_topics.front();
      run.note = "no IMU topic '" + imu_requested + "'; using " + run.imu +
                 ", the only sensor_msgs/Imu topic of the bag (--imu-topic names another)";
      run.command = command;
      run.channels =
          resolve_channels(channels_requested, topics,
                           namespace_of(command, names::kGimbalCommandTopic, command_requested));
      return run;
    }
  }
  const std::string imu_ns = namespace_of(run.imu, names::kImuTopic, imu_requested);
  // A bag with no gimbal command topic at all is a hand tumble (docs/design.md section 11): the IMU
  // alone. A command topic that exists but does not resolve is still an error.
  const bool any_command_topic = std::any_of(
      topics.begin(), topics.end(), [](const BagTopic& t) { return t.datatype == kCommandType; });
  if (!any_command_topic && command_optional) {
    run.channels = resolve_channels(channels_requested, topics, imu_ns);
    return run;
  }
  run.command = resolve_topic(command_requested, topics, kCommandType, imu_ns);
  run.channels = resolve_channels(channels_requested, topics, imu_ns);
  return run;
}

}  // namespace accel_intrinsics
