// Detection power of the discrepancy analysis (issue 5, "Performance"): the smallest quadratic
// non-linearity and the smallest angle offset that analyze() names in 90 % of runs, beside the
// theoretical threshold for the same device, noise and protocol (non-central chi-square),
// computed independently of the analysis (test/support/detection_theory.h: known noise, its own
// projection and its own max-T draws; nothing of what analyze() reports).
//
// Prints `name: value unit` lines. The theoretical threshold of a candidate with linearized
// standard uncertainty sigma_c (1 / |b_perp|, after projecting out S and O) is
//   value_90 = sqrt(lambda_90) * sigma_c,  P(chi2_1(lambda_90) > c) = 0.9
// with c either the family-wise critical value of max-T across all candidates at the analysis'
// alpha (2.5 %), from the theory's own draws: the best any test with the same false-alarm
// guarantee can do) or the single-test value 3.84 (an oracle that knows in advance which effect to
// look for).
//
// Usage: detection_bench [--runs R] [--example DIR]
//   --runs R       Monte Carlo runs per amplitude (default 200)
//   --example DIR  instead, write a worked example to DIR (position table CSV, analysis JSON,
//                  residual CSV) with two hidden effects, for docs/finding_the_missing_effect.md
#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include "../test/support/detection_theory.h"
#include "accel_intrinsics/core/analysis/discrepancy.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/io/analysis_report.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/residuals_csv.h"

using namespace accel_intrinsics::core;

namespace {

SimulationOptions bench_simulation() {
  // A fixed, realistic device: responsivities within 3 %, mrad misalignments, a tilted mounting.
  SimulationOptions so;
  Eigen::Matrix3d M;
  M << 1.021, 0.004, -0.007, -0.006, 0.987, 0.011, 0.003, -0.009, 1.008;
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  so.truth.S = M * R;
  so.truth.O = Eigen::Vector3d(0.05, -0.12, 0.08);
  so.noise_density = 300e-6 * kStandardGravity;
  so.protocol.steps_per_phase = 24;
  return so;
}

struct Theory {
  double sigma_c = 0;       // linearized standard uncertainty of the candidate
  double critical_fw = 0;   // family-wise critical chi2 of the analysis
  double value_fw = 0;      // theoretical 90 % threshold at the family-wise level
  double value_single = 0;  // theoretical 90 % threshold of a single 5 % test
};

Theory theory_for(const SimulationOptions& base, const Effect& e) {
  // Independent of analyze() (test/support/detection_theory.h, shared with
  // test/core/analysis/detection_theory_test.cpp): the Fisher information of the effect term with S
  // and O projected out and the simulator's known noise, the family-wise max-T critical value of
  // the analysis' candidate family from the theory's own Monte Carlo draws at the analysis' alpha.
  namespace dt = accel_intrinsics::detection_theory;
  SimulationOptions clean = base;
  clean.noise_density = 0.0;  // the timeline and sample counts only
  dt::Problem pr;
  pr.S = base.truth.S;
  pr.sigma = sample_noise_stds(base);
  pr.g = base.local_gravity;
  pr.dwells = dt::dwells_of(simulate_position_table(clean));
  const dt::Theory th =
      dt::theory_for(pr, e, dt::candidate_family(base.protocol.two_way), AnalysisOptions{}.alpha);
  Theory t;
  t.sigma_c = th.sigma_value;
  t.critical_fw = th.critical_chi2;
  t.value_fw = dt::threshold(th, 0.9);
  dt::Theory single = th;
  single.critical_chi2 = 3.841458820694124;  // chi2_1 95 % quantile: one test, no family
  t.value_single = dt::threshold(single, 0.9);
  return t;
}

double named_rate(const SimulationOptions& base, Effect e, double value, int runs,
                  std::uint64_t seed0) {
  int named = 0;
  for (int r = 0; r < runs; ++r) {
    SimulationOptions so = base;
    e.value = value;
    so.truth.effects = {e};
    so.seed = seed0 + static_cast<std::uint64_t>(r);
    const AnalysisResult a = analyze(simulate_position_table(so));
    for (const NamedEffect& ne : a.effects) {
      if (ne.effect.kind == e.kind && ne.effect.target == e.target) {
        ++named;
        break;
      }
    }
  }
  return static_cast<double>(named) / runs;
}

std::string key_of(const Effect& e) {
  return e.name() + "_" + e.target_name();
}

void bench_effect(const SimulationOptions& base, const Effect& e, int runs) {
  const Theory t = theory_for(base, e);
  const std::string key = key_of(e);
  const std::string unit = effect_info(e.kind).unit;
  std::cout << key << "_sigma_linearized: " << t.sigma_c << " " << unit << "\n";
  std::cout << key << "_critical_chi2_familywise: " << t.critical_fw << " 1\n";
  std::cout << key << "_threshold_theory_familywise: " << t.value_fw << " " << unit << "\n";
  std::cout << key << "_threshold_theory_single_test: " << t.value_single << " " << unit << "\n";
  const std::vector<double> multiples = {0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.5, 1.8};
  double previous_m = 0.0, previous_rate = 0.0, empirical = std::nan("");
  // Common random numbers: the same noise seeds at every amplitude, so the rate curve is smooth.
  const std::uint64_t seed0 = 1;
  for (double m : multiples) {
    const double rate = named_rate(base, e, m * t.value_fw, runs, seed0);
    std::cout << key << "_named_rate_at_" << m << "x_familywise_threshold: " << rate << " 1\n";
    if (std::isnan(empirical) && rate >= 0.9) {
      // Linear interpolation of the rate between the two bracketing amplitudes.
      const double f = previous_rate < 0.9 && rate > previous_rate
                           ? (0.9 - previous_rate) / (rate - previous_rate)
                           : 1.0;
      empirical = (previous_m + f * (m - previous_m)) * t.value_fw;
      if (previous_m == 0.0) empirical = m * t.value_fw;  // already >= 90 % at the first amplitude
    }
    previous_m = m;
    previous_rate = rate;
  }
  std::cout << key << "_threshold_empirical_90pct: " << empirical << " " << unit << "\n";
  std::cout << key << "_ratio_to_theory_familywise: " << empirical / t.value_fw << " 1\n";
  std::cout << key << "_ratio_to_theory_single_test: " << empirical / t.value_single << " 1\n";
}

int write_example(const std::string& dir) {
  SimulationOptions so = bench_simulation();
  so.seed = 17;
  // Two hidden effects: a quadratic non-linearity of v and an angle offset of the y phase.
  so.truth.effects = {Effect{EffectKind::QuadraticNonlinearity, 1, 6.0e-5},
                      Effect{EffectKind::AngleOffset, 1, deg_to_rad(0.03)}};
  const PositionTable table = simulate_position_table(so);
  write_position_table_file(dir + "/example_table.csv", table);
  const AnalysisResult a = analyze(table);
  accel_intrinsics::io::write_file_atomically(dir + "/example_analysis.json",
                                              accel_intrinsics::io::analysis_json_text(a) + "\n");
  accel_intrinsics::io::write_residuals_csv(dir + "/example_residuals.csv", table, a.before_fit,
                                            a.after_fit);
  std::cout << "hidden: ";
  for (const Effect& e : so.truth.effects) std::cout << e.label() << " = " << e.value << "  ";
  std::cout << "\n";
  accel_intrinsics::io::write_analysis_report(std::cout, a);
  std::cout << "wrote " << dir
            << "/example_table.csv, example_analysis.json, example_residuals.csv\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 200;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--runs" && i + 1 < argc) {
      runs = std::atoi(argv[++i]);
    } else if (arg == "--example" && i + 1 < argc) {
      return write_example(argv[++i]);
    } else {
      std::cerr << "usage: detection_bench [--runs R] [--example DIR]\n";
      return 2;
    }
  }
  if (runs < 10) {
    std::cerr << "detection_bench: --runs must be >= 10\n";
    return 2;
  }
  const auto start = std::chrono::steady_clock::now();
  const SimulationOptions base = bench_simulation();
  std::cout << "noise_density: " << base.noise_density << " (m/s^2)/sqrt(Hz)\n";
  std::cout << "positions_per_phase: " << base.protocol.steps_per_phase << " 1\n";
  std::cout << "runs_per_amplitude: " << runs << " 1\n";
  bench_effect(base, Effect{EffectKind::QuadraticNonlinearity, 0, 0.0}, runs);
  bench_effect(base, Effect{EffectKind::AngleOffset, 0, 0.0}, runs);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << "wall_time: " << seconds << " s\n";
  return 0;
}
