// Estimator scatter against the Cramer-Rao bound (issue 6, "bench/run"): Monte Carlo of one
// device on the default protocol (N = 24 per phase, default rate and noise), fitted with the joint
// model (and eq4 for comparison). For each intrinsic (|u|, |v|, |w|, theta_uv, theta_vw,
// theta_wu) it prints
//   scatter_over_crb_<q>            sample standard deviation of the estimates about the truth,
//                                   over the Cramer-Rao bound (Fisher information of the dwell
//                                   means with the true noise, propagated to the intrinsics)
//   reported_std_over_scatter_<q>   mean reported standard uncertainty over that scatter
//   eq4_scatter_over_crb_<q>        the same ratio for the eq4 fit (docs/design.md section 1) (>=
//   1: less efficient)
// as `name: value unit` lines. Ratios of 1 mean an efficient estimator and honest uncertainties;
// the Monte Carlo resolution of each ratio (1 / sqrt(2 (M - 1))) is printed too.
// Core library only (no ROS).
//   estimator_scatter_bench [--runs M]     (default 20000)
#include <Eigen/Dense>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/intrinsics.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace core = accel_intrinsics::core;

namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;

core::SimulationOptions setup() {
  core::SimulationOptions sim;
  sim.truth.S << 1.021, 0.013, -0.009,  //
      -0.017, 0.987, 0.021,             //
      0.008, -0.014, 1.012;
  sim.truth.O << 0.12, -0.31, 0.05;
  sim.protocol.steps_per_phase = 24;
  return sim;  // default noise density and rate
}

// Cramer-Rao bound of (S, O) from the dwell means (standard error sigma / sqrt(n)): the Fisher
// information of each accelerometer is sum_rows h h^T n / sigma^2 with h = (g f, 1); its inverse,
// propagated through the intrinsics Jacobian at the truth. Returns the 6 bound standard deviations.
Vector6d cramer_rao_std(const core::SimulationOptions& sim, const core::PositionTable& table) {
  const double sigma = core::sample_noise_std(sim);
  Eigen::Matrix4d F = Eigen::Matrix4d::Zero();  // the same for u, v, w (same noise)
  for (const core::DwellRecord& row : table.rows) {
    const Eigen::Vector3d f =
        core::in_plane_direction(row.phase, row.angle_rad) * sim.local_gravity;
    const Eigen::Vector4d h(f(0), f(1), f(2), 1.0);
    F += h * h.transpose() * (static_cast<double>(row.n) / (sigma * sigma));
  }
  const Eigen::Matrix4d C = F.inverse();
  Eigen::Matrix<double, 9, 9> cov_S = Eigen::Matrix<double, 9, 9>::Zero();
  for (int s = 0; s < 3; ++s) cov_S.block<3, 3>(3 * s, 3 * s) = C.topLeftCorner<3, 3>();
  const Eigen::Matrix<double, 6, 9> J = core::intrinsics_jacobian(sim.truth.S);
  return (J * cov_S * J.transpose()).diagonal().cwiseSqrt();
}

struct Scatter {
  Vector6d truth = Vector6d::Zero();
  Vector6d sum = Vector6d::Zero();
  Vector6d sum_sq = Vector6d::Zero();
  Vector6d reported = Vector6d::Zero();
  int n = 0;

  void add(const core::Intrinsics& in) {
    Vector6d x, sd;
    x << in.responsivity, in.angles_rad;
    sd << in.responsivity_std, in.angles_std_rad;
    const Vector6d d = x - truth;
    sum += d;
    sum_sq += d.cwiseProduct(d);
    reported += sd;
    ++n;
  }
  Vector6d std_dev() const {
    const Vector6d mean = sum / n;
    return ((sum_sq - n * mean.cwiseProduct(mean)) / (n - 1)).cwiseSqrt();
  }
  Vector6d mean_reported() const { return reported / n; }
};

const char* const kName[6] = {"responsivity_u", "responsivity_v", "responsivity_w",
                              "angle_uv",       "angle_vw",       "angle_wu"};

void line(const std::string& name, double value, const char* unit) {
  std::printf("%s: %.4g %s\n", name.c_str(), value, unit);
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 20000;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--runs" && i + 1 < argc) {
      runs = std::atoi(argv[++i]);
    } else {
      std::fprintf(stderr, "usage: estimator_scatter_bench [--runs M]\n");
      return 2;
    }
  }
  if (runs < 100) {
    std::fprintf(stderr, "estimator_scatter_bench: --runs must be >= 100\n");
    return 2;
  }
  const auto t0 = std::chrono::steady_clock::now();
  core::SimulationOptions sim = setup();
  const core::Intrinsics truth = core::intrinsics_from_vectors(sim.truth.S);
  Scatter joint, eq4;
  joint.truth << truth.responsivity, truth.angles_rad;
  eq4.truth = joint.truth;
  core::FitOptions eq4_options;
  eq4_options.model = core::FitModel::Eq4;
  Vector6d crb = Vector6d::Zero();
  for (int r = 0; r < runs; ++r) {
    sim.seed = 7000000 + static_cast<std::uint64_t>(r);
    const core::PositionTable table = core::simulate_position_table(sim);
    if (r == 0) crb = cramer_rao_std(sim, table);
    joint.add(core::fit(table).intrinsics);
    eq4.add(core::fit(table, eq4_options).intrinsics);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const Vector6d s_joint = joint.std_dev();
  const Vector6d s_eq4 = eq4.std_dev();
  const Vector6d rep = joint.mean_reported();
  constexpr double kDeg = 180.0 / M_PI;
  std::printf("estimator_scatter_runs: %d runs\n", runs);
  line("estimator_scatter_ratio_resolution", 1.0 / std::sqrt(2.0 * (runs - 1)), "1");
  for (int i = 0; i < 6; ++i) {
    const bool angle = i >= 3;
    line(std::string("crb_std_") + kName[i], angle ? crb(i) * kDeg : crb(i), angle ? "deg" : "1");
  }
  for (int i = 0; i < 6; ++i)
    line(std::string("scatter_over_crb_") + kName[i], s_joint(i) / crb(i), "1");
  for (int i = 0; i < 6; ++i)
    line(std::string("reported_std_over_scatter_") + kName[i], rep(i) / s_joint(i), "1");
  for (int i = 0; i < 6; ++i)
    line(std::string("eq4_scatter_over_crb_") + kName[i], s_eq4(i) / crb(i), "1");
  line("estimator_scatter_wall_time", seconds, "s");
  return 0;
}
