// Shared by the rostests of the simulated stand: run scripts/supervise, compare a result with
// the simulated truth on the parameter server.
#pragma once

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "accel_intrinsics/GetIntrinsics.h"

namespace stand_checks {

inline std::string join_ns(const std::string& ns, const std::string& name) {
  std::string n = ns;
  while (!n.empty() && n.front() == '/') n.erase(n.begin());
  while (!n.empty() && n.back() == '/') n.pop_back();
  return n.empty() ? "/" + name : "/" + n + "/" + name;
}

struct CommandResult {
  int exit_code = -1;
  std::string output;
};

inline CommandResult run(const std::string& command) {
  CommandResult r;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  char buffer[1024];
  while (fgets(buffer, sizeof(buffer), pipe)) r.output += buffer;
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// The simulated truth of a rig: S (rows u, v, w) from <ns>/accelerometer/device/S.
struct Truth {
  double S[3][3];
  double O[3];
  double responsivity[3];
  double angles_deg[3];
};

inline bool load_truth(const std::string& ns, Truth* t) {
  std::vector<double> S, O;
  if (!ros::param::get(join_ns(ns, "accelerometer/device/S"), S) || S.size() != 9) return false;
  if (!ros::param::get(join_ns(ns, "accelerometer/device/O"), O) || O.size() != 3) return false;
  for (int i = 0; i < 9; ++i) t->S[i / 3][i % 3] = S[i];
  for (int i = 0; i < 3; ++i) t->O[i] = O[i];
  for (int s = 0; s < 3; ++s) {
    t->responsivity[s] =
        std::sqrt(t->S[s][0] * t->S[s][0] + t->S[s][1] * t->S[s][1] + t->S[s][2] * t->S[s][2]);
  }
  const int pairs[3][2] = {{0, 1}, {1, 2}, {2, 0}};
  for (int k = 0; k < 3; ++k) {
    const int a = pairs[k][0], b = pairs[k][1];
    const double dot = t->S[a][0] * t->S[b][0] + t->S[a][1] * t->S[b][1] + t->S[a][2] * t->S[b][2];
    t->angles_deg[k] = std::acos(dot / (t->responsivity[a] * t->responsivity[b])) * 180.0 / M_PI;
  }
  return true;
}

struct Limits {
  double max_sigma = 4.0;
  double max_responsivity_std = 1e-3;
  double max_angle_std_deg = 0.05;
  double max_offset_std = 1e-2;
};

inline Limits load_limits(const ros::NodeHandle& pnh) {
  Limits l;
  pnh.getParam("max_sigma", l.max_sigma);
  pnh.getParam("max_responsivity_std", l.max_responsivity_std);
  pnh.getParam("max_angle_std_deg", l.max_angle_std_deg);
  pnh.getParam("max_offset_std", l.max_offset_std);
  return l;
}

// Every intrinsic within max_sigma standard uncertainties of the truth, with small sigmas.
inline void expect_matches_truth(const accel_intrinsics::IntrinsicResult& r, const Truth& t,
                                 const Limits& l, const std::string& label) {
  for (int s = 0; s < 3; ++s) {
    EXPECT_GT(r.responsivity_std[s], 0.0) << label;
    EXPECT_LT(r.responsivity_std[s], l.max_responsivity_std) << label << " responsivity " << s;
    EXPECT_LE(std::abs(r.responsivity[s] - t.responsivity[s]), l.max_sigma * r.responsivity_std[s])
        << label << " |"
        << "uvw"[s] << "| fitted " << r.responsivity[s] << " +- " << r.responsivity_std[s]
        << " truth " << t.responsivity[s];
    EXPECT_GT(r.angles_std_deg[s], 0.0) << label;
    EXPECT_LT(r.angles_std_deg[s], l.max_angle_std_deg) << label << " angle " << s;
    EXPECT_LE(std::abs(r.angles_deg[s] - t.angles_deg[s]), l.max_sigma * r.angles_std_deg[s])
        << label << " angle " << s << " fitted " << r.angles_deg[s] << " +- " << r.angles_std_deg[s]
        << " truth " << t.angles_deg[s];
    EXPECT_LT(r.offset_std[s], l.max_offset_std) << label;
    EXPECT_LE(std::abs(r.offset[s] - t.O[s]), l.max_sigma * r.offset_std[s])
        << label << " O_"
        << "uvw"[s] << " fitted " << r.offset[s] << " +- " << r.offset_std[s] << " truth "
        << t.O[s];
  }
}

inline std::size_t count_csv_rows(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::size_t rows = 0;
  if (!std::getline(in, line)) return 0;
  while (std::getline(in, line)) rows += !line.empty();
  return rows;
}

// Runs supervise on the namespaces and checks the exit code and the JSON it writes.
inline void supervise_and_check(const std::vector<std::string>& namespaces, const Limits& limits,
                                double timeout_s, const std::string& json_path) {
  std::string command = "rosrun accel_intrinsics supervise --quiet --timeout " +
                        std::to_string(timeout_s) + " --max-sigma " +
                        std::to_string(limits.max_sigma) + " --json " + json_path;
  for (const std::string& ns : namespaces)
    command += " '" + (ns.empty() ? std::string("/") : ns) + "'";
  std::remove(json_path.c_str());
  const CommandResult r = run(command);
  ASSERT_EQ(r.exit_code, 0) << command << "\n" << r.output;
  std::ifstream in(json_path);
  ASSERT_TRUE(in.good()) << json_path;
  const nlohmann::json report = nlohmann::json::parse(in);
  ASSERT_EQ(report["rigs"].size(), namespaces.size()) << report.dump(2);
  for (const auto& item : report["rigs"].items()) {
    const nlohmann::json& rig = item.value();
    EXPECT_TRUE(rig["success"].get<bool>()) << item.key();
    EXPECT_LE(rig["max_abs_z"].get<double>(), limits.max_sigma) << item.key();
    EXPECT_EQ(rig["result"]["positions"]["x"].get<int>(),
              rig["result"]["positions"]["z"].get<int>());
  }
  std::printf("%s\n", r.output.c_str());
}

// Waits for the stand's services, then starts a new run: calibration/reset (the next run gets a
// directory of its own; earlier runs are kept) and gimbal_controller/start. `must_hear`: the
// test's subscribers that must get the run's first messages; each is waited for (up to 30 s)
// until it is connected to a publisher (a fixed pause is not enough on a loaded machine).
inline void reset_and_start(std::initializer_list<const ros::Subscriber*> must_hear = {}) {
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(60.0)));
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/start", ros::Duration(60.0)));
  for (const ros::Subscriber* sub : must_hear) {
    const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(30.0);
    while (sub->getNumPublishers() == 0 && ros::WallTime::now() < deadline)
      ros::WallDuration(0.05).sleep();
    ASSERT_GT(sub->getNumPublishers(), 0u) << "no publisher of " << sub->getTopic();
  }
  ros::WallDuration(1.0).sleep();  // the other subscriptions connected
  std_srvs::Trigger reset, start;
  ASSERT_TRUE(ros::service::call("/calibration/reset", reset));
  ASSERT_TRUE(ros::service::call("/gimbal_controller/start", start));
  ASSERT_TRUE(start.response.success) << start.response.message;
}

inline accel_intrinsics::GetIntrinsics::Response get_intrinsics(const std::string& ns) {
  accel_intrinsics::GetIntrinsics srv;
  EXPECT_TRUE(ros::service::call(join_ns(ns, "calibration/get_intrinsics"), srv));
  return srv.response;
}

}  // namespace stand_checks
