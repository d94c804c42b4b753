// Runs written in a test from the equations, not by the simulator (so the simulator and the fit
// cannot agree on a shared mistake): eq. (4)'s unit specific force, written out here, and the
// skeleton of a three-phase table whose means the test then writes itself.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <cstdint>

#include "accel_intrinsics/core/dwells/position_table.h"

namespace accel_intrinsics {
namespace written_runs {

// Eq. (4): the unit specific force in the DUT frame at gimbal angle `a` of phase `p`.
inline Eigen::Vector3d unit_force(core::Phase p, double a) {
  switch (p) {
    case core::Phase::X: return Eigen::Vector3d(0.0, std::sin(a), std::cos(a));
    case core::Phase::Y: return Eigen::Vector3d(std::sin(a), 0.0, std::cos(a));
    default: return Eigen::Vector3d(std::sin(a), std::cos(a), 0.0);
  }
}

// Phases x, y, z of `steps` positions each at 360/steps degrees, in protocol order; every dwell
// 2 s long after a 1 s move (dwell k from 3k + 1 to 3k + 3 s, its middle at 3k + 2 s), `n`
// samples of standard deviation `sample_std`. The means are zero: the test writes them.
inline core::PositionTable three_phase_table(std::uint32_t steps, std::uint64_t n,
                                             double sample_std) {
  core::PositionTable table;
  double t = 0.0;
  for (core::Phase phase : {core::Phase::X, core::Phase::Y, core::Phase::Z}) {
    for (std::uint32_t step = 0; step < steps; ++step) {
      core::DwellRecord r;
      r.phase = phase;
      r.step = step;
      r.angle_rad = 2.0 * M_PI * step / steps;
      r.t_start_s = t + 1.0;
      r.t_end_s = t + 3.0;
      r.n = n;
      r.std = Eigen::Vector3d::Constant(sample_std);
      r.mean = Eigen::Vector3d::Zero();
      table.rows.push_back(r);
      t += 3.0;
    }
  }
  return table;
}

// The middle of a dwell (the time its mean stands for under a linear drift).
inline double mid_time(const core::DwellRecord& r) {
  return 0.5 * (r.t_start_s + r.t_end_s);
}

}  // namespace written_runs
}  // namespace accel_intrinsics
