// Waiting for an event in the rostests instead of sleeping a fixed time (issue 24): a condition
// polled until it holds or a generous wall-time bound has passed; the failure names the event.
//   ASSERT_TRUE(test_wait::wait_for([&] { return ...; }, 30.0, "the node's status after reset"));
#pragma once

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <gtest/gtest.h>
#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <xmlrpcpp/XmlRpcClient.h>

#include <cstdint>
#include <map>
#include <mutex>
#include <set>
#include <string>

namespace test_wait {

// The latest value of each key of a DiagnosticStatus topic (calibration/status, the controller's
// progress), its latest message text and how many messages came: filled in roscpp's callback
// thread, read by the test's conditions; "" for a key not seen yet. Subscribe with
// nh.subscribe(topic, 10, &LatestValues::on_message, &values).
class LatestValues {
 public:
  void on_message(const diagnostic_msgs::DiagnosticStatus::ConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& kv : msg->values) values_[kv.key] = kv.value;
    message_ = msg->message;
    ++messages_;
  }
  std::string operator()(const std::string& key) const {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = values_.find(key);
    return it == values_.end() ? "" : it->second;
  }
  std::string message() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return message_;
  }
  std::uint64_t messages() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return messages_;
  }

 private:
  mutable std::mutex mutex_;
  std::map<std::string, std::string> values_;
  std::string message_;
  std::uint64_t messages_ = 0;
};

// Polls `done()` every period_s until it returns true, or fails after timeout_s of wall time.
template <class Condition>
::testing::AssertionResult wait_for(Condition done, double timeout_s, const std::string& what,
                                    double period_s = 0.05) {
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (!done()) {
    if (ros::WallTime::now() >= deadline) {
      return ::testing::AssertionFailure()
             << "waited " << timeout_s << " s (wall time) for " << what << ", in vain";
    }
    ros::WallDuration(period_s).sleep();
  }
  return ::testing::AssertionSuccess();
}

// A call of `node`'s own XML-RPC API (ROS slave API: getPid, getBusInfo, ...) with the caller
// id as its only argument, as rosnode makes it; false when the node cannot be found or asked.
// *response: [code, status message, value].
inline bool call_node_api(const std::string& node, const std::string& method,
                          XmlRpc::XmlRpcValue* response) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false)) return false;
  std::string host;
  std::uint32_t port = 0;
  if (!ros::network::splitURI(static_cast<std::string>(payload), host, port)) return false;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue request;
  request[0] = ros::this_node::getName();
  return client.execute(method.c_str(), request, *response) &&
         response->getType() == XmlRpc::XmlRpcValue::TypeArray && response->size() >= 3 &&
         static_cast<int>((*response)[0]) == 1;
}

// The pid of a node (getPid); -1 when it cannot be asked.
inline int node_pid(const std::string& node) {
  XmlRpc::XmlRpcValue response;
  return call_node_api(node, "getPid", &response) ? static_cast<int>(response[2]) : -1;
}

// The topics on which `node` has a connected subscription (inbound connection), from its own
// XML-RPC API (getBusInfo, as rosnode info shows them); empty when the node cannot be asked.
inline std::set<std::string> connected_inbound_topics(const std::string& node) {
  std::set<std::string> topics;
  XmlRpc::XmlRpcValue response;
  if (!call_node_api(node, "getBusInfo", &response)) return topics;
  // Each connection: [id, peer, direction "i"/"o", transport, topic, connected, ...].
  XmlRpc::XmlRpcValue& connections = response[2];
  for (int i = 0; i < connections.size(); ++i) {
    XmlRpc::XmlRpcValue& c = connections[i];
    if (c.getType() != XmlRpc::XmlRpcValue::TypeArray || c.size() < 6) continue;
    if (static_cast<std::string>(c[2]) != "i") continue;
    if (c[5].getType() == XmlRpc::XmlRpcValue::TypeBoolean && !static_cast<bool>(c[5])) continue;
    topics.insert(static_cast<std::string>(c[4]));
  }
  return topics;
}

}  // namespace test_wait
