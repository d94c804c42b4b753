// Fit time against the number of positions per phase N (docs/design.md / issue 2 "Performance").
//   BM_FitJoint         closed-form weighted least squares (normal equations, O(N))
//   BM_FitEq4           eq4's 9 three-parameter fits and their combination (O(N))
//   BM_FitJointEffect   joint + quadratic_nonlinearity[u] through Ceres (O(N) per iteration)
// Each runs at N = 24 (the default protocol) up to N = 3600, and Google Benchmark fits the
// complexity: "BigO" close to a constant times N and a small RMS confirm the linear cost.
// Run: devel/lib/accel_intrinsics/fit_bench [--benchmark_filter=Joint]
#include <benchmark/benchmark.h>

#include <cstdint>
#include <map>

#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace {

using accel_intrinsics::core::FitModel;
using accel_intrinsics::core::FitOptions;
using accel_intrinsics::core::PositionTable;
using accel_intrinsics::core::SimulationOptions;

// One simulated table per N, built outside the timed loop.
const PositionTable& table_for(std::uint32_t steps, bool with_effect) {
  static std::map<std::pair<std::uint32_t, bool>, PositionTable> cache;
  auto key = std::make_pair(steps, with_effect);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  SimulationOptions sim;
  sim.truth.S << 1.021, 0.013, -0.009, -0.017, 0.987, 0.021, 0.008, -0.014, 1.012;
  sim.truth.O << 0.12, -0.31, 0.05;
  if (with_effect)
    sim.truth.effects = {accel_intrinsics::core::make_effect("quadratic_nonlinearity", "u", 2e-4)};
  sim.protocol.steps_per_phase = steps;
  sim.seed = 42;
  return cache.emplace(key, accel_intrinsics::core::simulate_position_table(sim)).first->second;
}

void run(benchmark::State& state, const FitOptions& options, bool with_effect) {
  const auto steps = static_cast<std::uint32_t>(state.range(0));
  const PositionTable& table = table_for(steps, with_effect);
  for (auto _ : state) {
    auto result = accel_intrinsics::core::fit(table, options);
    benchmark::DoNotOptimize(result);
  }
  state.SetComplexityN(state.range(0));
  state.counters["dwells"] = static_cast<double>(table.rows.size());
}

void BM_FitJoint(benchmark::State& state) {
  run(state, FitOptions(), false);
}

void BM_FitEq4(benchmark::State& state) {
  FitOptions options;
  options.model = FitModel::Eq4;
  run(state, options, false);
}

void BM_FitJointEffect(benchmark::State& state) {
  FitOptions options;
  options.effects = {accel_intrinsics::core::make_effect("quadratic_nonlinearity", "u", 0.0)};
  run(state, options, true);
}

void positions(benchmark::internal::Benchmark* b) {
  for (int n : {24, 96, 360, 1200, 3600}) b->Arg(n);
}

BENCHMARK(BM_FitJoint)->Apply(positions)->Complexity(benchmark::oN)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FitEq4)->Apply(positions)->Complexity(benchmark::oN)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FitJointEffect)
    ->Apply(positions)
    ->Complexity(benchmark::oN)
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
