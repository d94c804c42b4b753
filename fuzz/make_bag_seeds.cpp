// Writes the seed bags of fuzz/corpus/bag_input/ with rosbag::Bag: one short run (3 positions of
// phase X, a few IMU samples each, DONE) uncompressed, lz4, bz2, with a namespaced topic layout,
// and cut short (no index). Each stays under 20 kB. Usage: make_bag_seeds OUTPUT_DIR
// (tools/fuzz.sh builds and runs it when the directory has no bags yet).
#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "accel_intrinsics/GimbalCommand.h"

namespace ai = accel_intrinsics;

namespace {

void write_run(const std::string& path, rosbag::compression::CompressionType compression,
               const std::string& ns, int samples_per_dwell) {
  rosbag::Bag bag;
  bag.open(path, rosbag::bagmode::Write);
  bag.setCompression(compression);
  bag.setChunkThreshold(3000);  // two chunks or more even in a small bag
  const std::uint32_t steps = 3;
  double t = 1.0;
  auto command = [&](std::uint32_t step, std::uint8_t state) {
    ai::GimbalCommand c;
    c.header.stamp.fromSec(t);
    c.phase = ai::GimbalCommand::PHASE_X;
    c.step = step;
    c.steps = steps;
    c.angle = 2.0 * M_PI * step / steps;
    c.state = state;
    bag.write(ns + "/gimbal/command", ros::Time(t + 0.001), c);
  };
  for (std::uint32_t step = 0; step < steps; ++step) {
    command(step, ai::GimbalCommand::MOVING);
    t += 0.1;
    command(step, ai::GimbalCommand::SETTLED);
    const double a = 2.0 * M_PI * step / steps;
    for (int i = 0; i < samples_per_dwell; ++i) {
      t += 0.01;
      sensor_msgs::Imu m;
      m.header.stamp.fromSec(t);
      m.header.frame_id = "dut";
      m.orientation.w = 1.0;
      m.linear_acceleration.x = 0.01 * i;
      m.linear_acceleration.y = 9.81 * std::sin(a);
      m.linear_acceleration.z = 9.81 * std::cos(a);
      bag.write(ns + "/imu/data_raw", ros::Time(t + 0.001), m);
    }
    t += 0.01;
  }
  command(steps - 1, ai::GimbalCommand::DONE);
  bag.close();
}

std::vector<char> slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_bag_seeds OUTPUT_DIR\n");
    return 2;
  }
  const std::string dir = argv[1];
  write_run(dir + "/run_uncompressed.bag", rosbag::compression::Uncompressed, "", 4);
  write_run(dir + "/run_lz4.bag", rosbag::compression::LZ4, "", 4);
  write_run(dir + "/run_bz2.bag", rosbag::compression::BZ2, "", 4);
  write_run(dir + "/run_namespaced.bag", rosbag::compression::Uncompressed, "/stand1", 2);
  // Cut short: the first 60 % of the uncompressed run (header says the index is past the end).
  const std::vector<char> whole = slurp(dir + "/run_uncompressed.bag");
  std::ofstream cut(dir + "/run_truncated.bag", std::ios::binary);
  cut.write(whole.data(), static_cast<std::streamsize>(whole.size() * 6 / 10));
  return 0;
}
