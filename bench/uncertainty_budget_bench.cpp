// Cost of the type-B budget (core/uncertainty_budget.h, issue 13 "Performance") and where Monte
// Carlo and linear propagation disagree.
//   BM_Budget/N/draws       the budget of a joint fit with all five Monte Carlo sources (and g),
//                           `draws` per source, N positions per phase. Target: under 2 s for
//                           N = 24, 2000 draws (what offline_fit --budget adds); cost linear in
//                           draws and in N (BigO over N at 2000 draws).
//   BM_BudgetEq4/N/draws    the same for the eq4 model.
//   BM_MonteCarloOverLinear/source/mdeg  one source at a standard uncertainty of mdeg
//                           millidegrees (angle_scale: mdeg * 1e-6), joint fit, N = 24: counters
//                           mc_over_linear_resp and _angle (Monte Carlo contribution divided by
//                           the linear propagation's, max over u, v, w) and mc_resp/linear_resp.
//                           1.0 where the output is linear in the error; >> 1 where the first
//                           derivative vanishes at the nominal rig (angle offsets, axis tilt on
//                           the angles: second order) -- there linear propagation reports ~0.
// Run: devel/lib/accel_intrinsics/uncertainty_budget_bench [--benchmark_filter=Budget]
#include <benchmark/benchmark.h>

#include <cstdint>
#include <map>

#include "accel_intrinsics/core/analysis/uncertainty_budget.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace {

namespace core = accel_intrinsics::core;

struct Run {
  core::PositionTable table;
  core::FitResult joint, eq4;
};

const Run& run_for(std::uint32_t steps) {
  static std::map<std::uint32_t, Run> cache;
  auto it = cache.find(steps);
  if (it != cache.end()) return it->second;
  core::SimulationOptions sim;
  sim.truth.S << 1.021, 0.013, -0.009, -0.017, 0.987, 0.021, 0.008, -0.014, 1.012;
  sim.truth.O << 0.12, -0.31, 0.05;
  sim.protocol.steps_per_phase = steps;
  sim.seed = 42;
  Run r;
  r.table = core::simulate_position_table(sim);
  r.joint = core::fit(r.table);
  core::FitOptions eq4;
  eq4.model = core::FitModel::Eq4;
  r.eq4 = core::fit(r.table, eq4);
  return cache.emplace(steps, r).first->second;
}

core::BudgetSpec lab_gimbal(int draws) {
  core::BudgetSpec spec;  // config/uncertainty_budget.yaml's values
  spec.gravity_std_rel = 2e-5;
  spec.angle_random_std_deg = 0.005;
  spec.angle_offset_std_deg = 0.01;
  spec.angle_scale_std = 2e-5;
  spec.axis_tilt_std_deg = 0.01;
  spec.mount_misalignment_std_deg = 0.02;
  spec.samples = draws;
  return spec;
}

void budget(benchmark::State& state, bool eq4) {
  const auto steps = static_cast<std::uint32_t>(state.range(0));
  const int draws = static_cast<int>(state.range(1));
  const Run& r = run_for(steps);
  for (auto _ : state) {
    auto b = core::uncertainty_budget(r.table, eq4 ? r.eq4 : r.joint, lab_gimbal(draws));
    benchmark::DoNotOptimize(b);
  }
  state.SetComplexityN(state.range(0));
  state.counters["draws_total"] = 5.0 * draws;
}

void BM_Budget(benchmark::State& state) {
  budget(state, false);
}
void BM_BudgetEq4(benchmark::State& state) {
  budget(state, true);
}

BENCHMARK(BM_Budget)
    ->ArgsProduct({{24}, {250, 500, 1000, 2000, 4000}})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Budget)
    ->ArgsProduct({{12, 24, 48, 96, 192, 384}, {2000}})
    ->Complexity(benchmark::oN)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BudgetEq4)->Args({24, 2000})->Unit(benchmark::kMillisecond);

// source: 0 random, 1 offset, 2 scale, 3 tilt, 4 mount.
void BM_MonteCarloOverLinear(benchmark::State& state) {
  const Run& r = run_for(24);
  const double mdeg = static_cast<double>(state.range(1));
  core::BudgetSpec spec;
  spec.samples = 2000;
  switch (state.range(0)) {
    case 0: spec.angle_random_std_deg = 1e-3 * mdeg; break;
    case 1: spec.angle_offset_std_deg = 1e-3 * mdeg; break;
    case 2: spec.angle_scale_std = 1e-6 * mdeg; break;
    case 3: spec.axis_tilt_std_deg = 1e-3 * mdeg; break;
    default: spec.mount_misalignment_std_deg = 1e-3 * mdeg; break;
  }
  core::UncertaintyBudget mc, lin;
  for (auto _ : state) {
    mc = core::uncertainty_budget(r.table, r.joint, spec);
    lin = core::linear_propagation_budget(r.table, r.joint, spec);
  }
  const core::BudgetSource& m = mc.sources.back();
  const core::BudgetSource& l = lin.sources.back();
  double resp = 0.0, angle = 0.0;
  for (int i = 0; i < 3; ++i) {
    resp = std::max(resp, m.std.responsivity(i) / l.std.responsivity(i));
    angle = std::max(angle, m.std.angles_rad(i) / l.std.angles_rad(i));
  }
  state.counters["mc_over_linear_resp"] = resp;
  state.counters["mc_over_linear_angle"] = angle;
  state.counters["mc_resp"] = m.std.responsivity.maxCoeff();
  state.counters["linear_resp"] = l.std.responsivity.maxCoeff();
}
BENCHMARK(BM_MonteCarloOverLinear)
    ->ArgsProduct({{0, 1, 2, 3, 4}, {10, 1000, 10000}})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
