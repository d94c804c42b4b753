// Hand tumble throughput (issue 22 "Performance"): rest detection plus the tumble fit on a stream
// already in memory, in samples per second (goal: 10^7 or more), on a simulated 100 Hz session
// and on imu_tk's real Xsens session (test/data/imu_tk_xsens, read once outside the timed loop).
// imu_tk itself takes a median 0.50 s for its calibrateAcc() on that file on this kind of machine
// (built and run outside the repository: test/data/imu_tk_xsens/imu_tk_reference.json).
// Run: devel/lib/accel_intrinsics/tumble_bench
#include <benchmark/benchmark.h>

#include <string>

#include "accel_intrinsics/core/dwells/rest_detection.h"
#include "accel_intrinsics/core/dwells/samples_file.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/fit/tumble.h"
#include "accel_intrinsics/core/simulation/tumble_simulator.h"

namespace {

namespace core = accel_intrinsics::core;

void detect_and_fit(benchmark::State& state, const std::vector<core::ImuSample>& samples) {
  for (auto _ : state) {
    const core::RestDetection found = core::detect_rests(samples);
    core::PositionTable table;
    table.rows = found.rests;
    const core::FitResult r = core::fit(table);
    benchmark::DoNotOptimize(r.S);
  }
  state.counters["samples_per_s"] = benchmark::Counter(
      static_cast<double>(samples.size()) * state.iterations(), benchmark::Counter::kIsRate);
}

void BM_TumbleSimulated(benchmark::State& state) {
  static const std::vector<core::ImuSample> samples = [] {
    core::TumbleSimulationOptions o;
    o.truth = core::random_tumble_device(1);
    o.poses = 200;  // about 20 min at 100 Hz, 1.2 10^5 samples
    return core::simulate_hand_tumble(o).samples;
  }();
  detect_and_fit(state, samples);
}
BENCHMARK(BM_TumbleSimulated)->Unit(benchmark::kMillisecond);

void BM_TumbleImuTkXsens(benchmark::State& state) {
  static const std::vector<core::ImuSample> samples = core::read_samples_file(
      std::string(ACCEL_BENCH_SOURCE_DIR) + "/test/data/imu_tk_xsens/xsens_acc.mat");
  detect_and_fit(state, samples);
}
BENCHMARK(BM_TumbleImuTkXsens)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
