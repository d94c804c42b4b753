// tumble_live.test: imu_tk's real Xsens session (raw counts, turned by hand) replayed into the
// calibration node in mode tumble. The node finds the rests as the stream goes (its quiet level
// learned as it goes), publishes progress with the next pose after each, and fits on
// get_intrinsics: the same device as the batch fit of the same file within their uncertainties,
// both weighed with the noise model of the session's 51 s first rest (the live one kept from the
// stream), written to output_dir.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <std_msgs/String.h>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>

#include "accel_intrinsics/Dwell.h"
#include "accel_intrinsics/GetIntrinsics.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/dwells/rest_detection.h"
#include "accel_intrinsics/core/dwells/samples_file.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "run_dirs.h"

namespace accel_intrinsics {
namespace {

struct ProgressLog {
  std::mutex mutex;
  std::vector<nlohmann::json> messages;
  void on(const std_msgs::String& msg) {
    std::lock_guard<std::mutex> lock(mutex);
    messages.push_back(nlohmann::json::parse(msg.data));
  }
  nlohmann::json last() {
    std::lock_guard<std::mutex> lock(mutex);
    return messages.empty() ? nlohmann::json() : messages.back();
  }
};

TEST(TumbleLive, ReplayedSessionGivesRestsProgressAndTheFit) {
  ros::NodeHandle nh, pnh("~");
  std::string file;
  double rate_hz = 4000.0;
  ASSERT_TRUE(pnh.getParam("samples_file", file));
  pnh.getParam("replay_rate_hz", rate_hz);
  const std::vector<core::ImuSample> samples = core::read_samples_file(file);

  ProgressLog log;
  ros::Subscriber sub = nh.subscribe("calibration/tumble_progress", 100, &ProgressLog::on, &log);
  // calibration/dwell: one message per rest found (docs/design.md section 17).
  std::mutex dwell_mutex;
  std::vector<Dwell> dwells;
  ros::Subscriber dwell_sub =
      nh.subscribe<Dwell>("calibration/dwell", 1000, [&](const Dwell::ConstPtr& m) {
        std::lock_guard<std::mutex> lock(dwell_mutex);
        dwells.push_back(*m);
      });
  ros::Publisher pub = nh.advertise<sensor_msgs::Imu>("imu/data_raw", 20000);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  ASSERT_TRUE(ros::service::waitForService("calibration/get_intrinsics", ros::Duration(30.0)));
  const ros::WallTime wait_until = ros::WallTime::now() + ros::WallDuration(20.0);
  while (pub.getNumSubscribers() == 0 && ros::WallTime::now() < wait_until)
    ros::WallDuration(0.05).sleep();
  ASSERT_GT(pub.getNumSubscribers(), 0u);

  // Replay: stamps on a clock far from zero, paced in small bursts.
  const int burst = 20;
  ros::WallRate pace(rate_hz / burst);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    sensor_msgs::Imu msg;
    msg.header.stamp = ros::Time(1.6e9 + samples[i].stamp_s);
    msg.linear_acceleration.x = samples[i].outputs.x();
    msg.linear_acceleration.y = samples[i].outputs.y();
    msg.linear_acceleration.z = samples[i].outputs.z();
    msg.orientation_covariance[0] = -1;
    msg.angular_velocity_covariance[0] = -1;
    pub.publish(msg);
    if (i % burst == burst - 1) pace.sleep();
  }
  // Wait on the event: the node has seen every sample (its periodic progress says how many).
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(60.0);
  while (ros::WallTime::now() < deadline) {
    const nlohmann::json p = log.last();
    if (!p.is_null() && p["samples"].get<std::size_t>() == samples.size()) break;
    ros::WallDuration(0.05).sleep();
  }
  const nlohmann::json last = log.last();
  ASSERT_FALSE(last.is_null());
  ASSERT_EQ(last["samples"].get<std::size_t>(), samples.size()) << last.dump();

  // The batch fit of the same file (offline_fit's path): the noise model of its first rest of at
  // least 30 s (51 s here), fitted again to the whole tumble by calibrate().
  const core::RestDetection batch = core::detect_rests(samples);
  core::PositionTable table;
  table.rows = batch.rests;
  std::vector<double> stamps;
  std::vector<Eigen::Vector3d> outputs;
  for (const core::ImuSample& sample : samples) {
    stamps.push_back(sample.stamp_s);
    outputs.push_back(sample.outputs);
  }
  const std::optional<core::NoiseModel> rest_model =
      core::noise_model_of_run(table, stamps, outputs);
  ASSERT_TRUE(rest_model.has_value());
  const core::FitResult offline =
      core::calibrate(table, nullptr, core::with_noise_model(core::CalibrateOptions(), rest_model))
          .certificate;
  ASSERT_FALSE(offline.noise_model.white());

  // Live: the rests as they ended (the stream's last rest is still open: it never ended).
  const std::size_t live_rests = last["rests"].get<std::size_t>();
  EXPECT_GE(live_rests + 2, batch.rests.size());
  EXPECT_LE(live_rests, batch.rests.size() + 2);
  EXPECT_TRUE(last["fitted"].get<bool>()) << last.dump();
  EXPECT_FALSE(last["next_pose"]["words"].get<std::string>().empty());
  EXPECT_TRUE(last["coverage"]["complete"].get<bool>()) << last.dump();
  // Progress came after each rest: the rest counts seen rise one by one.
  std::size_t previous = 0, distinct = 0;
  {
    std::lock_guard<std::mutex> lock(log.mutex);
    for (const nlohmann::json& m : log.messages) {
      const std::size_t r = m["rests"].get<std::size_t>();
      EXPECT_GE(r, previous);
      if (r != previous) ++distinct;
      previous = r;
    }
  }
  EXPECT_GE(distinct + 2, live_rests);

  GetIntrinsics srv;
  ASSERT_TRUE(ros::service::call("calibration/get_intrinsics", srv));
  EXPECT_TRUE(srv.response.success) << srv.response.message;
  const IntrinsicResult& r = srv.response.result;
  EXPECT_EQ(r.model, "tumble");
  for (int s = 0; s < 3; ++s) {
    // Two fits of nearly the same rests: far closer than one standard uncertainty apart.
    EXPECT_NEAR(r.responsivity[s], offline.intrinsics.responsivity(s),
                r.responsivity_std[s] + offline.intrinsics.responsivity_std(s))
        << s;
    EXPECT_NEAR(r.angles_deg[s], offline.intrinsics.angles_rad(s) * 180.0 / M_PI,
                r.angles_std_deg[s] + offline.intrinsics.angles_std_rad(s) * 180.0 / M_PI)
        << s;
  }
  EXPECT_LT(r.reduced_chi2, 2.0);  // white weights: 16.6 (docs/finding_the_missing_effect.md)
  std::string output_dir;
  ASSERT_TRUE(nh.getParam("calibration/output_dir", output_dir));
  EXPECT_TRUE(std::filesystem::exists(run_dirs::latest(output_dir) + "/intrinsics.yaml"))
      << output_dir;
  {
    // Each rest of the table the node wrote beside the result came as a calibration/dwell.
    const core::PositionTable rests =
        core::read_position_table_file(run_dirs::latest(output_dir) + "/position_table.csv");
    std::lock_guard<std::mutex> lock(dwell_mutex);
    ASSERT_EQ(dwells.size(), rests.rows.size());
    EXPECT_EQ(dwells.size(), live_rests);
    for (std::size_t i = 0; i < dwells.size(); ++i) {
      EXPECT_EQ(dwells[i].index, i);
      EXPECT_EQ(dwells[i].phase, Dwell::PHASE_UNKNOWN);
      EXPECT_EQ(dwells[i].n, rests.rows[i].n) << i;
      for (int k = 0; k < 3; ++k) EXPECT_DOUBLE_EQ(dwells[i].mean[k], rests.rows[i].mean(k)) << i;
    }
  }
  // The live session kept its first rest's raw samples and weighed the fit with their noise
  // model as offline_fit does: the rest the same (live and batch rests start alike to a sample),
  // the model not white, fitted again to the tumble.
  const YAML::Node result = YAML::LoadFile(run_dirs::latest(output_dir) + "/intrinsics.yaml");
  ASSERT_TRUE(result["noise_model"].IsMap()) << output_dir;
  EXPECT_NE(result["noise_model"]["kind"].as<std::string>(), "white");
  EXPECT_NEAR(result["noise_model"]["rest"]["samples"].as<double>(),
              static_cast<double>(rest_model->rest_samples), 2.0);
  EXPECT_NE(result["noise_model"]["source"].as<std::string>().find("long rest's blocks"),
            std::string::npos);
}

}  // namespace
}  // namespace accel_intrinsics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "tumble_live_test");
  return RUN_ALL_TESTS();
}
