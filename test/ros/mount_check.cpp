// supervise --check-mount on the simulated stand: see test/ros/mount_check.test. The IMU on
// /imu_test is this test's own: it follows the commanded pose on gimbal/command and publishes
// g * eq. (4) of docs/design.md section 1 (written here) through its own device, with one setup
// mistake at a time.
#include <accel_intrinsics/GimbalCommand.h>
#include <dirent.h>
#include <ros/ros.h>
#include <sensor_msgs/Imu.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <mutex>
#include <random>
#include <set>
#include <string>

#include "stand_checks.h"

namespace {

constexpr double kG = 9.80665;

enum class Mode { Silent, FlipY, SwapXY, InG, Constant };

class TestImu {
 public:
  TestImu() {
    ros::NodeHandle nh;
    pub_ = nh.advertise<sensor_msgs::Imu>("/imu_test", 1000);
    sub_ = nh.subscribe("/gimbal/command", 100, &TestImu::on_command, this);
    timer_ = nh.createTimer(ros::Duration(0.01), &TestImu::on_timer, this);
  }
  void set_mode(Mode m) { mode_ = m; }

 private:
  void on_command(const accel_intrinsics::GimbalCommand& c) {
    std::lock_guard<std::mutex> lock(mutex_);
    phase_ = c.phase;
    angle_ = c.angle;
  }
  void on_timer(const ros::TimerEvent&) {
    const Mode mode = mode_;
    if (mode == Mode::Silent) return;
    int phase = 0;
    double a = 0.0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      phase = phase_;
      a = angle_;
    }
    if (mode == Mode::FlipY && phase == 1) a = -a;
    if (mode == Mode::SwapXY && phase < 2) phase = 1 - phase;
    // eq. (4): x: (0, sin, cos), y: (sin, 0, cos), z: (sin, cos, 0).
    double f[3] = {0.0, 0.0, 0.0};
    if (phase == 0) f[1] = std::sin(a), f[2] = std::cos(a);
    if (phase == 1) f[0] = std::sin(a), f[2] = std::cos(a);
    if (phase == 2) f[0] = std::sin(a), f[1] = std::cos(a);
    if (mode == Mode::Constant) f[0] = 0.0, f[1] = 0.0, f[2] = 1.0;
    // This test's device: responsivities 1.01, 0.99, 1.0, offsets 0.1, -0.2, 0.15 m/s^2, noise
    // 0.02 m/s^2.
    const double scale = mode == Mode::InG ? 1.0 / kG : 1.0;
    sensor_msgs::Imu msg;
    msg.header.stamp = ros::Time::now();
    msg.header.frame_id = "imu_test";
    msg.orientation_covariance[0] = -1;
    msg.angular_velocity_covariance[0] = -1;
    msg.linear_acceleration.x = scale * (1.01 * kG * f[0] + 0.1 + 0.02 * noise_(rng_));
    msg.linear_acceleration.y = scale * (0.99 * kG * f[1] - 0.2 + 0.02 * noise_(rng_));
    msg.linear_acceleration.z = scale * (1.00 * kG * f[2] + 0.15 + 0.02 * noise_(rng_));
    pub_.publish(msg);
  }

  ros::Publisher pub_;
  ros::Subscriber sub_;
  ros::Timer timer_;
  std::atomic<Mode> mode_{Mode::Silent};
  std::mutex mutex_;
  int phase_ = 0;
  double angle_ = 0.0;
  std::mt19937_64 rng_{7};
  std::normal_distribution<double> noise_{0.0, 1.0};
};

TestImu* imu = nullptr;

// The calibration node's runs of the device: the entries of output_dir/unnamed and where its
// `latest` points.
struct Runs {
  std::set<std::string> entries;
  std::string latest;
};

Runs runs() {
  ros::NodeHandle pnh("~");
  std::string output_dir;
  pnh.getParam("output_dir", output_dir);
  Runs r;
  const std::string device = output_dir + "/unnamed";
  if (DIR* d = opendir(device.c_str())) {
    while (const dirent* e = readdir(d)) r.entries.insert(e->d_name);
    closedir(d);
  }
  char target[4096];
  const ssize_t n = readlink((device + "/latest").c_str(), target, sizeof target - 1);
  if (n > 0) r.latest.assign(target, static_cast<std::size_t>(n));
  return r;
}

stand_checks::CommandResult check(const std::string& extra) {
  ros::NodeHandle pnh("~");
  double timeout_s = 60.0;
  pnh.getParam("timeout_s", timeout_s);
  const Runs before = runs();
  stand_checks::CommandResult r =
      stand_checks::run("rosrun accel_intrinsics supervise --check-mount --timeout " +
                        std::to_string(timeout_s) + " " + extra);
  ros::WallDuration(1.0).sleep();  // the calibration node hears the last dwell and the abort
  const Runs after = runs();
  EXPECT_EQ(after.entries, before.entries) << "the mount check left a run directory";
  EXPECT_EQ(after.latest, before.latest) << "the mount check moved latest";
  EXPECT_FALSE(ros::param::has("/calibration/mount_check")) << "supervise left ~mount_check";
  return r;
}

void wait_for_stand() {
  ASSERT_TRUE(ros::service::waitForService("/gimbal_controller/resume", ros::Duration(90.0)));
  ASSERT_TRUE(ros::service::waitForService("/calibration/get_intrinsics", ros::Duration(90.0)));
}

TEST(MountCheck, SimulatedStandIsCorrect) {
  wait_for_stand();
  // The IMU topic the calibration node listens to: the simulated accelerometer's.
  const stand_checks::CommandResult r = check("");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("mount correct"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("/imu/data_raw"), std::string::npos) << r.output;
}

TEST(MountCheck, EachMistakeNamed) {
  wait_for_stand();
  struct Case {
    Mode mode;
    const char* names[2];
  };
  const Case cases[] = {
      {Mode::FlipY, {"axis_sign[y]", nullptr}},
      {Mode::SwapXY, {"axes_swapped[x]", "axes_swapped[y]"}},
      {Mode::InG, {"output_unit", "in g"}},
      {Mode::Constant, {"imu_motionless", nullptr}},
      {Mode::Silent, {"imu_silent", nullptr}},
  };
  for (const Case& c : cases) {
    imu->set_mode(c.mode);
    const stand_checks::CommandResult r = check("--imu-topic /imu_test");
    EXPECT_EQ(r.exit_code, 4) << r.output;
    for (const char* name : c.names) {
      if (name) {
        EXPECT_NE(r.output.find(name), std::string::npos) << name << " not in:\n" << r.output;
      }
    }
    EXPECT_NE(r.output.find("fix:"), std::string::npos) << r.output;
  }
}

TEST(MountCheck, ImuTopicWithoutPublisherIsNamed) {
  wait_for_stand();
  // Nobody publishes /imu_nobody: supervise waits for a connection (bounded), says so and
  // goes on; the check then names the IMU silent.
  const stand_checks::CommandResult r = check("--imu-topic /imu_nobody");
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_NE(r.output.find("no publisher of /imu_nobody connected"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("imu_silent"), std::string::npos) << r.output;
}

TEST(MountCheck, NoGimbalCouldNotRun) {
  const stand_checks::CommandResult r = stand_checks::run(
      "rosrun accel_intrinsics supervise --check-mount --service-timeout 1 "
      "nowhere");
  EXPECT_EQ(r.exit_code, 1) << r.output;
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "mount_check_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  TestImu test_imu;
  imu = &test_imu;
  return RUN_ALL_TESTS();
}
