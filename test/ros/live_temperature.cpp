// live_temperature.test: imu/temperature on the live stand reaches the position table (one mean
// per dwell) and the result file.
#include <sensor_msgs/Temperature.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <mutex>
#include <sstream>
#include <utility>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "run_dirs.h"
#include "stand_checks.h"

namespace {
std::mutex readings_mutex;
std::vector<std::pair<double, double>> readings;  // (stamp s, temperature C) as received
void on_temperature(const sensor_msgs::Temperature::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(readings_mutex);
  readings.emplace_back(msg->header.stamp.toSec(), msg->temperature);
}

// Mean of the readings inside [t0, t1], each end included or not as asked (a reading stamped
// exactly on a gimbal command may fall on either side of it).
bool mean_between(double t0, double t1, bool with_t0, bool with_t1, double* mean) {
  double sum = 0.0;
  int n = 0;
  for (const auto& r : readings) {
    const bool after = with_t0 ? r.first >= t0 : r.first > t0;
    const bool before = with_t1 ? r.first <= t1 : r.first < t1;
    if (after && before) {
      sum += r.second;
      ++n;
    }
  }
  if (n == 0) return false;
  *mean = sum / n;
  return true;
}
}  // namespace

TEST(LiveTemperature, EachDwellRecordsTheMeanOfItsReadings) {
  ros::NodeHandle pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  double timeout_s = 200.0;
  int steps = 6;
  std::string output_dir;
  pnh.getParam("timeout_s", timeout_s);
  pnh.getParam("steps", steps);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  ros::NodeHandle nh;
  ros::Subscriber sub = nh.subscribe("/imu/temperature", 10000, on_temperature);
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(60.0)));
  // Both subscriptions in place before the run starts.
  ros::WallTime wait_end = ros::WallTime::now() + ros::WallDuration(20.0);
  while (sub.getNumPublishers() == 0 && ros::WallTime::now() < wait_end) {
    ros::WallDuration(0.05).sleep();
  }
  ASSERT_GT(sub.getNumPublishers(), 0u) << "nobody publishes /imu/temperature";

  // A temperature that changes does not disturb the fit of a device without temperature effects.
  stand_checks::supervise_and_check({""}, limits, timeout_s, output_dir + "/supervise.json");

  const accel_intrinsics::core::PositionTable table =
      accel_intrinsics::core::read_position_table_file(run_dirs::latest(output_dir) +
                                                       "/position_table.csv");
  ASSERT_EQ(table.rows.size(), static_cast<std::size_t>(3 * steps));
  std::lock_guard<std::mutex> lock(readings_mutex);
  ASSERT_GT(readings.size(), 20u);
  double lowest = 1e9, highest = -1e9;
  for (std::size_t r = 0; r < table.rows.size(); ++r) {
    const auto& row = table.rows[r];
    ASSERT_TRUE(std::isfinite(row.temperature_c)) << "row " << r << " has no temperature";
    lowest = std::min(lowest, row.temperature_c);
    highest = std::max(highest, row.temperature_c);
    // The node's mean equals the test's own mean of the readings in the dwell (noise 0.05 K per
    // reading: a reading more or fewer changes the mean by far more than 1e-9).
    bool matched = false;
    std::ostringstream tried;
    for (int ends = 0; ends < 4 && !matched; ++ends) {
      double mean = 0.0;
      if (!mean_between(row.t_start_s, row.t_end_s, ends & 1, ends & 2, &mean)) continue;
      matched = std::abs(mean - row.temperature_c) < 1e-9;
      tried << " " << mean;
    }
    EXPECT_TRUE(matched) << "row " << r << " [" << row.t_start_s << ", " << row.t_end_s
                         << "]: node " << row.temperature_c << ", test's means" << tried.str();
  }
  // The profile spans more than a kelvin over the run (the sine and the ramp are visible).
  EXPECT_GT(highest - lowest, 1.0);

  // The result file states the run's temperatures.
  std::ifstream yaml(run_dirs::latest(output_dir) + "/intrinsics.yaml");
  std::stringstream text;
  text << yaml.rdbuf();
  EXPECT_NE(text.str().find("dwells_with_temperature: " + std::to_string(3 * steps)),
            std::string::npos)
      << text.str();
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "live_temperature_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
