// offline_bench: throughput of offline_fit on a bag of one million IMU messages, against a plain
// Python rosbag loop over the same bag and against real-time replay, measured in the same run.
//
//   offline_bench [--bag PATH] [--messages N] [--rate-hz F] [--runs R] [--no-python]
//                 [--benchmark_filter=...]
//
// 1. Writes PATH (default /tmp/accel_intrinsics_bench_1M.bag, reused when it already holds N IMU
//    messages at that rate): core::simulate_recording of a 24-position protocol at F Hz (default
//    1 kHz, a common MEMS output rate) with dwells long enough for N samples, plus the gimbal
//    commands. Real-time replay of it takes N / F seconds. N must hold the full protocol with
//    0.5 s dwells (156 001 at 1 kHz); fewer is refused with a message naming the minimum.
// 2. Runs the built offline_fit binary on it R times (wall time; best and median).
// 3. Times `/usr/bin/python3`: `for _ in rosbag.Bag(PATH).read_messages(): pass`, once.
// 4. Prints `name: value unit` lines: times, messages per second, the ratio to the Python loop and
//    to real-time replay (bag duration / fit time).
// 5. Google Benchmark, in process, bag reading + dwell assembly three ways: bag_input's chunk
//    scan (what offline_fit does), bag_input through rosbag::View (compressed bags), and the
//    plain rosbag::View + instantiate<sensor_msgs::Imu> loop.
#include <benchmark/benchmark.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/ros/bag_input.h"
#include "accel_intrinsics/ros/conversions.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

namespace {

using Clock = std::chrono::steady_clock;

std::string g_bag = "/tmp/accel_intrinsics_bench_1M.bag";

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string sibling(const std::string& name) {
  char self[4096];
  const ssize_t n = ::readlink("/proc/self/exe", self, sizeof(self) - 1);
  if (n <= 0) return name;
  self[n] = '\0';
  std::string dir(self);
  return dir.substr(0, dir.rfind('/')) + "/" + name;
}

// Runs argv with stdout/stderr to /dev/null; returns the exit status, or -1.
int run(const std::vector<std::string>& args) {
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    std::FILE* null = std::fopen("/dev/null", "w");
    if (null) {
      ::dup2(::fileno(null), 1);
      ::dup2(::fileno(null), 2);
    }
    std::vector<char*> argv;
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

struct BagInfo {
  std::uint64_t imu = 0;
  std::uint64_t commands = 0;
  double duration_s = 0.0;
};

BagInfo inspect(const std::string& path) {
  BagInfo info;
  try {
    rosbag::Bag bag(path, rosbag::bagmode::Read);
    rosbag::View imu(bag, rosbag::TopicQuery("/imu/data_raw"));
    rosbag::View cmd(bag, rosbag::TopicQuery("/gimbal/command"));
    rosbag::View all(bag);
    info.imu = imu.size();
    info.commands = cmd.size();
    info.duration_s = (all.getEndTime() - all.getBeginTime()).toSec();
  } catch (const std::exception&) {
  }
  return info;
}

// The benchmark's simulated stand: the default 24-position protocol at `rate_hz`.
core::SimulationOptions bench_simulation(double rate_hz) {
  core::SimulationOptions sim;
  sim.truth.S << 1.02, 0.01, -0.005, 0.003, 0.98, 0.02, -0.01, 0.015, 1.005;
  sim.truth.O = Eigen::Vector3d(0.05, -0.03, 0.12);
  sim.rate_hz = rate_hz;
  return sim;
}

// Seconds from the start of the run to the end of its last dwell with dwells of `dwell_s`.
double run_length(const core::SimulationOptions& sim, double dwell_s) {
  core::ProtocolOptions p = sim.protocol;
  p.dwell_s = dwell_s;
  return core::build_schedule(p).back().dwell_end_s;
}

// The shortest dwell write_bag uses, and the fewest IMU messages a full protocol with it needs
// at `rate_hz` (fewer would cut the run short of DONE: not a run offline_fit can fit).
constexpr double kMinDwellS = 0.5;
std::uint64_t min_messages(double rate_hz) {
  return static_cast<std::uint64_t>(
             std::ceil(run_length(bench_simulation(rate_hz), kMinDwellS) * rate_hz)) +
         1;
}

// The 24-position protocol at an IMU rate of `rate_hz`, with the dwell time that makes the run
// `messages` samples long (1 M at 1 kHz: 12.2 s dwells, 16.7 min), stamps from t = 1000 s, bag
// time = stamp. `messages` >= min_messages(rate_hz) (main refuses fewer).
void write_bag(const std::string& path, std::uint64_t messages, double rate_hz) {
  core::SimulationOptions sim = bench_simulation(rate_hz);
  const double target_s = static_cast<double>(messages - 1) / rate_hz;
  const double per_second_of_dwell = run_length(sim, 2.0) - run_length(sim, 1.0);
  sim.protocol.dwell_s =
      std::max(kMinDwellS, 1.0 + (target_s - run_length(sim, 1.0)) / per_second_of_dwell);
  core::Recording rec = core::simulate_recording(sim);
  if (rec.samples.size() > messages && !rec.commands.empty() &&
      rec.samples[messages - 1].stamp_s < rec.commands.back().stamp_s) {
    std::fprintf(stderr, "offline_bench: %llu messages end before the protocol's DONE\n",
                 static_cast<unsigned long long>(messages));
    std::exit(2);
  }
  rec.samples.resize(std::min<std::size_t>(rec.samples.size(), messages));
  while (rec.samples.size() < messages) {  // pad after DONE, as a recorder would
    core::ImuSample s = rec.samples.back();
    s.stamp_s += 1.0 / rate_hz;
    rec.samples.push_back(s);
  }
  rosbag::Bag bag(path, rosbag::bagmode::Write);
  std::size_t c = 0;
  for (const core::ImuSample& sample : rec.samples) {
    while (c < rec.commands.size() && rec.commands[c].stamp_s <= sample.stamp_s) {
      core::GimbalEvent e = rec.commands[c++];
      e.stamp_s += 1000.0;
      bag.write("/gimbal/command", ros::Time(e.stamp_s), ai::to_msg(e));
    }
    core::ImuSample s = sample;
    s.stamp_s += 1000.0;
    bag.write("/imu/data_raw", ros::Time(s.stamp_s), ai::to_msg(s, "dut"));
  }
  for (; c < rec.commands.size(); ++c) {
    core::GimbalEvent e = rec.commands[c];
    e.stamp_s += 1000.0;
    bag.write("/gimbal/command", ros::Time(e.stamp_s), ai::to_msg(e));
  }
  bag.close();
}

void line(const std::string& name, double value, const std::string& unit) {
  std::printf("%s: %.6g %s\n", name.c_str(), value, unit.c_str());
  std::fflush(stdout);
}

// ---- in process (Google Benchmark) ---------------------------------------------------------

// bag_input as offline_fit uses it: memory-mapped chunk scan (or View when allow_chunk_scan is
// off).
void read_bag_benchmark(benchmark::State& state, bool allow_chunk_scan) {
  ai::BagInputOptions options;
  options.allow_chunk_scan = allow_chunk_scan;
  std::uint64_t messages = 0;
  for (auto _ : state) {
    const ai::BagRun run = ai::read_bag(g_bag, options);
    messages = run.stats.imu_messages + run.stats.command_messages;
    benchmark::DoNotOptimize(run.table.rows.data());
  }
  state.counters["msgs_per_s"] = benchmark::Counter(static_cast<double>(messages),
                                                    benchmark::Counter::kIsIterationInvariantRate);
}
void BM_ReadBag_ChunkScan(benchmark::State& state) {
  read_bag_benchmark(state, true);
}
void BM_ReadBag_RosbagView(benchmark::State& state) {
  read_bag_benchmark(state, false);
}

// The plain way: rosbag::View and instantiate<sensor_msgs::Imu>, same dwell assembly.
void BM_ReadBag_RosbagViewFullImuMessage(benchmark::State& state) {
  std::uint64_t messages = 0;
  for (auto _ : state) {
    rosbag::Bag bag(g_bag, rosbag::bagmode::Read);
    rosbag::View view(
        bag, rosbag::TopicQuery(std::vector<std::string>{"/imu/data_raw", "/gimbal/command"}));
    core::DwellAssembler assembler(ai::BagInputOptions::default_assembler_options());
    messages = 0;
    for (const rosbag::MessageInstance& m : view) {
      if (m.getTopic() == "/imu/data_raw") {
        assembler.add_sample(ai::to_core(*m.instantiate<sensor_msgs::Imu>()));
      } else {
        assembler.add_command(ai::to_core(*m.instantiate<ai::GimbalCommand>()));
      }
      ++messages;
    }
    assembler.flush();
    benchmark::DoNotOptimize(assembler.table().rows.data());
  }
  state.counters["msgs_per_s"] = benchmark::Counter(static_cast<double>(messages),
                                                    benchmark::Counter::kIsIterationInvariantRate);
}

BENCHMARK(BM_ReadBag_ChunkScan)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);
BENCHMARK(BM_ReadBag_RosbagView)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);
BENCHMARK(BM_ReadBag_RosbagViewFullImuMessage)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(3);

}  // namespace

int main(int argc, char** argv) {
  std::uint64_t messages = 1000000;
  double rate_hz = 1000.0;
  int runs = 3;
  bool python = true;
  std::vector<char*> rest{argv[0]};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--bag" && i + 1 < argc)
      g_bag = argv[++i];
    else if (a == "--messages" && i + 1 < argc)
      messages = std::strtoull(argv[++i], nullptr, 10);
    else if (a == "--rate-hz" && i + 1 < argc)
      rate_hz = std::atof(argv[++i]);
    else if (a == "--runs" && i + 1 < argc)
      runs = std::max(1, std::atoi(argv[++i]));
    else if (a == "--no-python")
      python = false;
    else
      rest.push_back(argv[i]);
  }

  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz)) {
    std::fprintf(stderr, "offline_bench: --rate-hz must be a positive number\n");
    return 2;
  }
  // Too few messages cannot hold the full protocol (24 positions, dwells >= 0.5 s): refuse rather
  // than write a run cut short of DONE and time something that is not a calibration.
  const std::uint64_t fewest = min_messages(rate_hz);
  if (messages < fewest) {
    std::fprintf(stderr,
                 "offline_bench: --messages %llu is too small for a full protocol at %g Hz (24 "
                 "positions with "
                 "%.1f s dwells need at least %llu IMU messages); use --messages %llu or more\n",
                 static_cast<unsigned long long>(messages), rate_hz, kMinDwellS,
                 static_cast<unsigned long long>(fewest), static_cast<unsigned long long>(fewest));
    return 2;
  }

  BagInfo info = inspect(g_bag);
  const double expected_duration = static_cast<double>(messages - 1) / rate_hz;
  if (info.imu != messages ||
      std::abs(info.duration_s - expected_duration) > 0.01 * expected_duration) {
    std::fprintf(stderr, "offline_bench: writing %s (%llu IMU messages)...\n", g_bag.c_str(),
                 static_cast<unsigned long long>(messages));
    const auto t0 = Clock::now();
    write_bag(g_bag, messages, rate_hz);
    line("bag_write_time", seconds_since(t0), "s");
    info = inspect(g_bag);
  }
  const double total = static_cast<double>(info.imu + info.commands);
  line("bag_imu_messages", static_cast<double>(info.imu), "msgs");
  line("bag_command_messages", static_cast<double>(info.commands), "msgs");
  line("bag_duration", info.duration_s, "s");
  line("bag_imu_rate", static_cast<double>(info.imu - 1) / info.duration_s, "Hz");

  // offline_fit, the shipped binary, end to end (read, assemble, fit, write JSON).
  const std::string tool = sibling("offline_fit");
  const std::string json = g_bag + ".bench.json";
  std::vector<double> times;
  for (int r = 0; r < runs; ++r) {
    const auto t0 = Clock::now();
    const int status = run({tool, "--bag", g_bag, "--json", json});
    times.push_back(seconds_since(t0));
    if (status != 0) {
      std::fprintf(stderr, "offline_bench: %s failed with status %d\n", tool.c_str(), status);
      return 1;
    }
  }
  std::sort(times.begin(), times.end());
  const double best = times.front();
  const double median = times[times.size() / 2];
  line("offline_fit_time_best", best, "s");
  line("offline_fit_time_median", median, "s");
  line("offline_fit_throughput", total / median, "msgs/s");
  line("offline_fit_vs_realtime_replay", info.duration_s / median, "x");

  if (python) {
    const auto t0 = Clock::now();
    const int status = run({"/usr/bin/python3", "-c",
                            "import sys, rosbag\n"
                            "bag = rosbag.Bag(sys.argv[1])\n"
                            "for _ in bag.read_messages():\n"
                            "    pass\n",
                            g_bag});
    const double t = seconds_since(t0);
    if (status != 0) {
      std::fprintf(stderr, "offline_bench: the python rosbag loop failed with status %d\n", status);
      return 1;
    }
    line("python_rosbag_loop_time", t, "s");
    line("python_rosbag_loop_throughput", total / t, "msgs/s");
    line("offline_fit_vs_python_loop", t / median, "x");
  }

  int bench_argc = static_cast<int>(rest.size());
  benchmark::Initialize(&bench_argc, rest.data());
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::remove(json.c_str());
  return 0;
}
