// noise_report_bench: the Allan analysis of noise_report (core::analyze_static_record: the
// overlapping Allan deviation of three outputs from cumulative sums, and N, B, K) on static
// records of 10^5 .. 10^7 samples, to show the cost is linear in the samples (target: 10^7
// samples in under 2 s). Reading the CSV or bag is not included (it is I/O).
//
//   noise_report_bench [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "accel_intrinsics/core/noise/noise.h"

namespace core = accel_intrinsics::core;

namespace {

struct Record {
  std::vector<double> stamps;
  std::vector<Eigen::Vector3d> outputs;
};

// White noise plus a random walk at 1 kHz.
const Record& record(std::size_t n) {
  static std::size_t made = 0;
  static Record r;
  if (made != n) {
    std::mt19937_64 rng(1);
    std::normal_distribution<double> normal(0.0, 1.0);
    r.stamps.resize(n);
    r.outputs.resize(n);
    Eigen::Vector3d walk = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < n; ++i) {
      r.stamps[i] = i * 1e-3;
      for (int a = 0; a < 3; ++a) {
        walk(a) += 1e-4 * std::sqrt(1e-3) * normal(rng);
        r.outputs[i](a) = walk(a) + 0.002 * std::sqrt(1000.0) * normal(rng);
      }
    }
    made = n;
  }
  return r;
}

void BM_AnalyzeStaticRecord(benchmark::State& state) {
  const Record& r = record(static_cast<std::size_t>(state.range(0)));
  for (auto _ : state) {
    const core::StaticRecordNoise noise = core::analyze_static_record(r.stamps, r.outputs);
    benchmark::DoNotOptimize(noise.axes[0].white_density);
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
  state.counters["ns_per_sample"] = benchmark::Counter(
      static_cast<double>(state.range(0)),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_AnalyzeStaticRecord)
    ->Arg(100000)
    ->Arg(1000000)
    ->Arg(10000000)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
