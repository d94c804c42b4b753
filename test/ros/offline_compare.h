// Shared by the replay rostests (replay_equals_offline, replay_through_node): run offline_fit,
// wait for the calibration node's result, compare the two to the last digit, stop a node.
#pragma once

#include <gtest/gtest.h>
#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <xmlrpcpp/XmlRpc.h>
#include <yaml-cpp/yaml.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "accel_intrinsics/GetIntrinsics.h"
#include "accel_intrinsics/IntrinsicResult.h"

namespace offline_compare {

// offline_fit next to this test binary (catkin puts both in devel/lib/accel_intrinsics), or
// $ACCEL_OFFLINE_FIT.
inline std::string offline_fit_binary() {
  if (const char* env = std::getenv("ACCEL_OFFLINE_FIT")) return env;
  char self[4096];
  const ssize_t n = ::readlink("/proc/self/exe", self, sizeof(self) - 1);
  if (n <= 0) return "offline_fit";
  self[n] = '\0';
  std::string dir(self);
  return dir.substr(0, dir.rfind('/')) + "/offline_fit";
}

inline std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

inline bool file_exists(const std::string& path) {
  struct stat info;
  return ::stat(path.c_str(), &info) == 0;
}

inline std::string quote(const std::string& arg) {
  std::string out = "'";
  for (char c : arg) out += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

struct ToolRun {
  int status = -1;
  std::string err;
};

// offline_fit with `args`; stderr captured, stdout discarded.
inline ToolRun run_offline_fit(const std::vector<std::string>& args, const std::string& err_path) {
  std::string command = quote(offline_fit_binary());
  for (const std::string& a : args) command += " " + quote(a);
  command += " >/dev/null 2>" + quote(err_path);
  const int raw = std::system(command.c_str());
  ToolRun r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.err = read_file(err_path);
  return r;
}

// Polls `service` (GetIntrinsics) until success or timeout (wall time). Returns success.
inline bool wait_for_result(const std::string& service, double timeout_s,
                            accel_intrinsics::IntrinsicResult* result, std::string* last_message) {
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::ok() && ros::WallTime::now() < deadline) {
    accel_intrinsics::GetIntrinsics srv;
    if (ros::service::exists(service, false) && ros::service::call(service, srv)) {
      *last_message = srv.response.message;
      if (srv.response.success) {
        *result = srv.response.result;
        return true;
      }
    }
    ros::WallDuration(0.2).sleep();
  }
  return false;
}

// True when every topic in `topics` has `node` among its subscribers (master getSystemState).
inline bool subscribed(const std::string& node, const std::vector<std::string>& topics) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  if (!ros::master::execute("getSystemState", args, result, payload, true)) return false;
  const XmlRpc::XmlRpcValue& subscribers = payload[1];
  for (const std::string& topic : topics) {
    bool found = false;
    for (int i = 0; i < subscribers.size() && !found; ++i) {
      if (static_cast<std::string>(subscribers[i][0]) != topic) continue;
      for (int j = 0; j < subscribers[i][1].size(); ++j) {
        if (static_cast<std::string>(subscribers[i][1][j]) == node) found = true;
      }
    }
    if (!found) return false;
  }
  return true;
}

// Asks a node to shut down through its XML-RPC API (what `rosnode kill` does); rosbag record
// then closes its bag properly.
inline bool shutdown_node(const std::string& node) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, true)) return false;
  const std::string uri = payload;
  std::string host;
  std::uint32_t port = 0;
  if (!ros::network::splitURI(uri, host, port)) return false;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue call_args, call_result;
  call_args[0] = ros::this_node::getName();
  call_args[1] = "recording finished";
  return client.execute("shutdown", call_args, call_result);
}

// The online result against offline_fit's JSON, every contract field, to the last digit.
inline void expect_equal(const accel_intrinsics::IntrinsicResult& online, const nlohmann::json& j) {
  const char* accel[3] = {"u", "v", "w"};
  const char* angles[3] = {"uv", "vw", "wu"};
  const char* phases[3] = {"x", "y", "z"};
  EXPECT_EQ(online.model, j["model_label"].get<std::string>());
  EXPECT_EQ(online.local_gravity, j["local_gravity"].get<double>());
  const geometry_msgs::Vector3* vectors[3] = {&online.u, &online.v, &online.w};
  for (int s = 0; s < 3; ++s) {
    EXPECT_EQ(online.responsivity[s], j["responsivity"][accel[s]].get<double>()) << accel[s];
    EXPECT_EQ(online.responsivity_std[s], j["responsivity_std"][accel[s]].get<double>())
        << accel[s];
    EXPECT_EQ(online.angles_deg[s], j["angles_deg"][angles[s]].get<double>()) << angles[s];
    EXPECT_EQ(online.angles_std_deg[s], j["angles_std_deg"][angles[s]].get<double>()) << angles[s];
    EXPECT_EQ(online.offset[s], j["offset"][accel[s]].get<double>()) << accel[s];
    EXPECT_EQ(online.offset_std[s], j["offset_std"][accel[s]].get<double>()) << accel[s];
    EXPECT_EQ(vectors[s]->x, j["vectors"][accel[s]][0].get<double>()) << accel[s];
    EXPECT_EQ(vectors[s]->y, j["vectors"][accel[s]][1].get<double>()) << accel[s];
    EXPECT_EQ(vectors[s]->z, j["vectors"][accel[s]][2].get<double>()) << accel[s];
    EXPECT_EQ(online.positions[s], j["positions"][phases[s]].get<std::uint32_t>()) << phases[s];
    for (int p = 0; p < 3; ++p) {
      EXPECT_EQ(online.offset_per_phase[3 * s + p],
                j["offset_per_phase"][accel[s]][phases[p]].get<double>());
      EXPECT_EQ(online.cross_sensitivity[3 * s + p], j["cross_sensitivity"][s][p].get<double>());
    }
  }
  EXPECT_EQ(online.reduced_chi2, j["reduced_chi2"].get<double>());
  EXPECT_EQ(online.residual_rms, j["residual_rms"].get<double>());
}

// Keys only one side writes: the node's stamp and sample counters; offline_fit's input
// description. Every other key is shared and must mean the same (io/result_document.h).
// local_gravity_source is on both sides but says where each tool got g (a parameter, a flag).
inline bool node_only_key(const std::string& key) {
  // ... and what the node knows of its stand (docs/design.md section 15): the device's serial,
  // the IMU topic, the gimbal driver, the UTC time the file was written.
  return key == "stamp" || key == "samples" || key == "local_gravity_source" ||
         key == "device_serial" || key == "imu_topic" || key == "gimbal_driver" ||
         key == "time_utc";
}
inline bool offline_only_key(const std::string& key) {
  return key == "input" || key == "complete" || key == "warnings" || key == "local_gravity_source";
}

// offline_fit's JSON against the node's intrinsics.yaml: the same keys at every level and the same
// values (numbers to the last digit, null for null), except the keys one side alone writes.
inline void expect_same_document(const nlohmann::json& j, const YAML::Node& y,
                                 const std::string& where = "") {
  if (j.is_object()) {
    ASSERT_TRUE(y.IsMap()) << where;
    std::set<std::string> json_keys, yaml_keys;
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (!(where.empty() && offline_only_key(it.key()))) json_keys.insert(it.key());
    }
    for (auto it = y.begin(); it != y.end(); ++it) {
      const std::string key = it->first.as<std::string>();
      if (!(where.empty() && node_only_key(key))) yaml_keys.insert(key);
    }
    ASSERT_EQ(json_keys, yaml_keys) << "keys of '" << where << "'";
    for (const std::string& key : json_keys)
      expect_same_document(j[key], y[key], where + "/" + key);
  } else if (j.is_array()) {
    ASSERT_TRUE(y.IsSequence()) << where;
    ASSERT_EQ(j.size(), y.size()) << where;
    for (std::size_t i = 0; i < j.size(); ++i)
      expect_same_document(j[i], y[i], where + "/" + std::to_string(i));
  } else if (j.is_null()) {
    EXPECT_TRUE(y.IsNull()) << where;
  } else if (j.is_boolean()) {
    EXPECT_EQ(y.as<bool>(), j.get<bool>()) << where;
  } else if (j.is_number()) {
    EXPECT_EQ(y.as<double>(), j.get<double>()) << where;
  } else {
    EXPECT_EQ(y.as<std::string>(), j.get<std::string>()) << where;
  }
}

}  // namespace offline_compare
