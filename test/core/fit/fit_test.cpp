// Tests of fit(): exact recovery on noise-free data (joint, eq4, joint + each effect term),
// derivative checks of every effect term, effect recovery within its uncertainty on noisy data,
// the weights, and bad input.
#include "accel_intrinsics/core/fit/fit.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "../../support/statistical_bounds.h"
#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/simulation/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

// A random non-orthogonal triad near the identity: scale errors of 1-3 %, misalignments of
// about 1 degree, offsets of a few tenths of m/s^2.
Device random_triad(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> scale(0.01, 0.03);
  std::uniform_real_distribution<double> sign(-1.0, 1.0);
  std::normal_distribution<double> misalign(0.0, deg_to_rad(1.0));
  std::uniform_real_distribution<double> offset(-0.4, 0.4);
  Device d;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      d.S(i, j) = i == j ? 1.0 + (sign(rng) < 0 ? -1.0 : 1.0) * scale(rng) : misalign(rng);
    }
    d.O(i) = offset(rng);
  }
  return d;
}

SimulationOptions noise_free(const Device& truth, std::uint32_t steps = 24) {
  SimulationOptions sim;
  sim.truth = truth;
  sim.protocol.steps_per_phase = steps;
  sim.noise_density = 0.0;
  return sim;
}

double max_rel(const Eigen::MatrixXd& est, const Eigen::MatrixXd& truth) {
  return (est - truth).cwiseAbs().maxCoeff() / truth.cwiseAbs().maxCoeff();
}

void expect_exact(const FitResult& r, const Device& truth, double tol) {
  EXPECT_LT(max_rel(r.S, truth.S), tol) << "S\n" << r.S << "\ntruth\n" << truth.S;
  for (int s = 0; s < 3; ++s) EXPECT_LT(std::abs(r.O(s) - truth.O(s)), tol * std::abs(truth.O(s)));
  const Intrinsics want = intrinsics_from_vectors(truth.S);
  for (int i = 0; i < 3; ++i) {
    EXPECT_LT(std::abs(r.intrinsics.responsivity(i) / want.responsivity(i) - 1.0), tol);
    EXPECT_LT(std::abs(r.intrinsics.angles_rad(i) / want.angles_rad(i) - 1.0), tol);
  }
  EXPECT_LT(max_rel(r.cross_sensitivity, truth.S.inverse()), tol);
  EXPECT_LT(r.residual_rms, 1e-10);
  // Exact data with unit weights: uncertainties at the round-off level, finite, never NaN.
  EXPECT_TRUE(r.covariance.allFinite());
  EXPECT_TRUE(r.intrinsics.covariance.allFinite());
  EXPECT_TRUE(r.cross_sensitivity_std.allFinite());
  EXPECT_LT(r.intrinsics.responsivity_std.maxCoeff(), tol);
  EXPECT_LT(r.intrinsics.angles_std_rad.maxCoeff(), tol);
  for (double sd : r.effects_std) EXPECT_LT(sd, tol * std::max(1.0, std::abs(r.effects[0].value)));
}

TEST(Fit, ParseAndNameModels) {
  EXPECT_EQ(parse_model("joint"), FitModel::Joint);
  EXPECT_EQ(parse_model("eq4"), FitModel::Eq4);
  EXPECT_STREQ(model_name(FitModel::Eq4), "eq4");
  EXPECT_THROW(parse_model("eq5"), std::invalid_argument);
}

TEST(Fit, NoiseFreeRandomTriadsBothModelsAreExact) {
  std::mt19937_64 rng(20261121);
  for (int trial = 0; trial < 12; ++trial) {
    const Device truth = random_triad(rng);
    for (std::uint32_t steps : {3u, 5u, 24u}) {
      const PositionTable table = simulate_position_table(noise_free(truth, steps));
      for (FitModel model : {FitModel::Joint, FitModel::Eq4}) {
        SCOPED_TRACE(std::string(model_name(model)) + " N=" + std::to_string(steps) + " trial " +
                     std::to_string(trial));
        FitOptions opt;
        opt.model = model;
        const FitResult r = fit(table, opt);
        expect_exact(r, truth, 1e-9);
        EXPECT_EQ(r.positions[0], static_cast<int>(steps));
        EXPECT_EQ(r.residuals.size(), table.rows.size());
        EXPECT_EQ(r.model_label(), model_name(model));
        // Per-phase offsets: all equal to O for joint, and for eq4 on an exact model too.
        for (int p = 0; p < 3; ++p)
          EXPECT_NEAR(r.offset_per_phase(0, p), truth.O(0), 1e-9 * std::abs(truth.O(0)));
      }
    }
  }
}

TEST(Fit, UsesTheGivenLocalGravity) {
  std::mt19937_64 rng(7);
  const Device truth = random_triad(rng);
  SimulationOptions sim = noise_free(truth);
  sim.local_gravity = 9.7803;
  const PositionTable table = simulate_position_table(sim);
  FitOptions opt;
  opt.local_gravity = 9.7803;
  const FitResult r = fit(table, opt);
  expect_exact(r, truth, 1e-9);
  EXPECT_EQ(r.local_gravity, 9.7803);
  // With the wrong g the responsivities scale by the ratio and nothing else changes.
  opt.local_gravity = kStandardGravity;
  const FitResult wrong = fit(table, opt);
  EXPECT_NEAR(wrong.intrinsics.responsivity(0) / r.intrinsics.responsivity(0),
              9.7803 / kStandardGravity, 1e-12);
  EXPECT_NEAR(wrong.intrinsics.angles_rad(1), r.intrinsics.angles_rad(1), 1e-12);
  EXPECT_LT(wrong.residual_rms, 1e-10);
}

TEST(Fit, NoisyJointIsConsistent) {
  std::mt19937_64 rng(11);
  SimulationOptions sim;
  sim.truth = random_triad(rng);
  sim.seed = 5;
  const PositionTable table = simulate_position_table(sim);
  for (FitModel model : {FitModel::Joint, FitModel::Eq4}) {
    FitOptions opt;
    opt.model = model;
    const FitResult r = fit(table, opt);
    SCOPED_TRACE(model_name(model));
    EXPECT_EQ(r.dof, model == FitModel::Joint ? 3 * 72 - 12 : 9 * (24 - 3));
    EXPECT_GT(r.reduced_chi2, 0.6);
    EXPECT_LT(r.reduced_chi2, 1.4);
    for (int k = 0; k < 9; ++k) {
      const double sd = std::sqrt(r.covariance(k, k));
      EXPECT_GT(sd, 0.0);
      EXPECT_LT(std::abs(r.S(k / 3, k % 3) - sim.truth.S(k / 3, k % 3)), 4.5 * sd);
    }
    for (int s = 0; s < 3; ++s) {
      EXPECT_LT(std::abs(r.O(s) - sim.truth.O(s)), 4.5 * r.O_std(s));
      EXPECT_GT(r.cross_sensitivity_std(s, s), 0.0);
    }
    // Residuals are measured minus model and their normalized sum of squares is chi2.
    double chi2 = 0.0;
    for (std::size_t i = 0; i < r.residuals.size(); ++i)
      chi2 += r.residuals[i].cwiseQuotient(r.standard_errors[i]).squaredNorm();
    EXPECT_NEAR(chi2, r.chi2, 1e-9 * r.chi2);
  }
}

// On an inexact (noisy) fit the residuals and their RMS are computed here from the fitted S and
// O and the specific force written out (docs/design.md section 1): RMS = sqrt(sum |r_i|^2 / 3N)
// over the 3N residual components (over N it would be sqrt(3) larger), chi2 with the dwell standard
// errors std / sqrt(n).
TEST(Fit, ResidualRmsIsOverTheThreeNComponentsOnAnInexactFit) {
  std::mt19937_64 rng(17);
  SimulationOptions sim;
  sim.truth = random_triad(rng);
  sim.seed = 9;
  const PositionTable table = simulate_position_table(sim);
  const FitResult r = fit(table);
  const double g = r.local_gravity;
  double sum_sq = 0.0, chi2 = 0.0;
  ASSERT_EQ(r.residuals.size(), table.rows.size());
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    const DwellRecord& row = table.rows[i];
    const double s = std::sin(row.angle_rad), c = std::cos(row.angle_rad);
    Eigen::Vector3d f(s, c, 0.0);
    if (row.phase == Phase::X) f << 0.0, s, c;
    if (row.phase == Phase::Y) f << s, 0.0, c;
    const Eigen::Vector3d residual = row.mean - (r.S * (g * f) + r.O);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(r.residuals[i](k), residual(k), 1e-10) << i;
    sum_sq += residual.squaredNorm();
    const Eigen::Vector3d se = row.std / std::sqrt(static_cast<double>(row.n));
    chi2 += residual.cwiseQuotient(se).squaredNorm();
  }
  const double rms = std::sqrt(sum_sq / (3.0 * static_cast<double>(table.rows.size())));
  EXPECT_GT(rms, 1e-5);  // inexact: the check can see the divisor
  EXPECT_NEAR(r.residual_rms, rms, 1e-9 * rms);
  EXPECT_NEAR(r.chi2, chi2, 1e-8 * chi2);
  EXPECT_EQ(r.dof, 3 * static_cast<int>(table.rows.size()) - 12);
  EXPECT_NEAR(r.reduced_chi2, chi2 / r.dof, 1e-8 * chi2 / r.dof);
}

// A tilted rotation axis adds a per-phase constant; eq4's per-phase offsets absorb it, joint's
// single offset cannot (docs/design.md section 1: "that is intended").
TEST(Fit, AxisTiltIsAbsorbedByEq4ButNotByJoint) {
  std::mt19937_64 rng(3);
  SimulationOptions sim;
  sim.truth = random_triad(rng);
  sim.truth.effects = {make_effect("axis_tilt", "y", deg_to_rad(0.5))};
  const PositionTable table = simulate_position_table(sim);
  FitOptions eq4;
  eq4.model = FitModel::Eq4;
  const FitResult a = fit(table, eq4);
  const FitResult j = fit(table);
  EXPECT_LT(a.reduced_chi2, 1.5);
  EXPECT_GT(j.reduced_chi2, 20.0);
}

TEST(Fit, StandardErrorsFollowTheFallbackRules) {
  PositionTable table;
  for (int i = 0; i < 4; ++i) {
    DwellRecord r;
    r.n = 100;
    r.std = Eigen::Vector3d(0.1 * (i + 1), 0.0, 0.5);
    table.rows.push_back(r);
  }
  table.rows[3].n = 1;  // too few samples for a std
  const std::vector<Eigen::Vector3d> se = dwell_standard_errors(table);
  ASSERT_EQ(se.size(), 4u);
  EXPECT_DOUBLE_EQ(se[0](0), 0.01);
  EXPECT_DOUBLE_EQ(se[2](0), 0.03);
  EXPECT_DOUBLE_EQ(se[3](0), 0.02);                      // median of 0.01, 0.02, 0.03
  for (int i = 0; i < 4; ++i) EXPECT_EQ(se[i](1), 1.0);  // all zero: unit weights
  EXPECT_DOUBLE_EQ(se[3](2), 0.05);
}

// ---- bad input ---------------------------------------------------------------------------

PositionTable good_table() {
  std::mt19937_64 rng(1);
  SimulationOptions sim;
  sim.truth = random_triad(rng);
  sim.protocol.steps_per_phase = 6;
  return simulate_position_table(sim);
}

std::string fit_error(const PositionTable& table, const FitOptions& options = {}) {
  try {
    fit(table, options);
  } catch (const FitError& e) {
    return e.what();
  }
  return "(no FitError)";
}

TEST(FitBadInput, TooFewPositionsNamesPhaseAndCount) {
  PositionTable table = good_table();
  std::vector<DwellRecord> rows;
  int kept_y = 0;
  for (const DwellRecord& r : table.rows)
    if (r.phase != Phase::Y || kept_y++ < 2) rows.push_back(r);
  table.rows = rows;
  for (FitModel model : {FitModel::Joint, FitModel::Eq4}) {
    FitOptions opt;
    opt.model = model;
    EXPECT_EQ(fit_error(table, opt), "phase y has 2 dwells, needs at least 3");
  }
}

TEST(FitBadInput, NonFiniteValueNamesRowAndField) {
  PositionTable table = good_table();
  table.rows[4].mean(1) = std::nan("");
  const std::string msg = fit_error(table);
  EXPECT_NE(msg.find("row 5"), std::string::npos) << msg;
  EXPECT_NE(msg.find("mean_v"), std::string::npos) << msg;
  table = good_table();
  table.rows[10].std(2) = INFINITY;
  const std::string msg2 = fit_error(table);
  EXPECT_NE(msg2.find("row 11"), std::string::npos) << msg2;
  EXPECT_NE(msg2.find("std_w"), std::string::npos) << msg2;
  table = good_table();
  table.rows[0].angle_rad = -INFINITY;
  EXPECT_NE(fit_error(table).find("row 1 (phase x, step 0): angle_rad"), std::string::npos);
}

TEST(FitBadInput, DegenerateGeometryNamesPhase) {
  PositionTable table = good_table();
  for (DwellRecord& r : table.rows)
    if (r.phase == Phase::Z) r.angle_rad = 0.3;
  for (FitModel model : {FitModel::Joint, FitModel::Eq4}) {
    FitOptions opt;
    opt.model = model;
    const std::string msg = fit_error(table, opt);
    EXPECT_NE(msg.find("phase z has a degenerate geometry"), std::string::npos) << msg;
    EXPECT_NE(msg.find("1 distinct angle"), std::string::npos) << msg;
  }
  // Two distinct angles (mod 360 degrees) are still degenerate.
  table = good_table();
  int k = 0;
  for (DwellRecord& r : table.rows)
    if (r.phase == Phase::X) r.angle_rad = (k++ % 2) ? 0.5 : 0.5 + 2.0 * kPi;
  EXPECT_NE(fit_error(table).find("phase x has a degenerate"), std::string::npos);
}

// A dead sensor (every dwell mean exactly 0) fits S = 0 exactly: the fit must refuse it with a
// FitError naming the singular S rather than hand back an infinite cross-sensitivity matrix.
TEST(FitBadInput, DeadSensorWithAllOutputsZeroIsRefused) {
  PositionTable table = good_table();
  for (DwellRecord& r : table.rows) r.mean.setZero();
  const std::string msg = fit_error(table);
  EXPECT_NE(msg.find("linearly dependent"), std::string::npos) << msg;
  EXPECT_NE(msg.find("S singular"), std::string::npos) << msg;
}

TEST(FitBadInput, EffectsNeedTheJointModel) {
  FitOptions opt;
  opt.model = FitModel::Eq4;
  opt.effects = {make_effect("quadratic_nonlinearity", "u")};
  const std::string msg = fit_error(good_table(), opt);
  EXPECT_NE(msg.find("effects need the joint model"), std::string::npos) << msg;
}

TEST(FitBadInput, UnfittableEffectsAreExplained) {
  FitOptions opt;
  opt.effects = {make_effect("timing_lag", "all")};
  EXPECT_NE(fit_error(good_table(), opt).find("timing_lag cannot be fitted from dwell means"),
            std::string::npos);
  opt.effects = {make_effect("backlash", "x")};  // one-way sweep
  EXPECT_NE(fit_error(good_table(), opt).find("backlash[x] needs a two-way sweep"),
            std::string::npos);
  opt.effects = {make_effect("angle_offset", "y"), make_effect("angle_offset", "y")};
  EXPECT_NE(fit_error(good_table(), opt).find("listed twice"), std::string::npos);
  PositionTable table = good_table();
  for (DwellRecord& r : table.rows) r.t_start_s = r.t_end_s = 0.0;
  opt.effects = {make_effect("offset_drift", "w")};
  EXPECT_NE(fit_error(table, opt).find("offset_drift[w] needs dwell times"), std::string::npos);
  Effect bad;
  bad.kind = EffectKind::AngleScale;
  bad.target = 5;
  opt.effects = {bad};
  EXPECT_NE(fit_error(good_table(), opt).find("target index 5"), std::string::npos);
}

// A drift whose time stamps happen to follow the x component of the specific force is a
// change of s_ux and O_u: the rank check must name the parameters instead of returning garbage.
TEST(FitBadInput, UnidentifiableCombinationNamesTheParameters) {
  PositionTable table = good_table();
  for (DwellRecord& r : table.rows) {
    const double t = 100.0 + 10.0 * in_plane_direction(r.phase, r.angle_rad)(0);
    r.t_start_s = r.t_end_s = t;
  }
  FitOptions opt;
  opt.effects = {make_effect("offset_drift", "u")};
  const std::string msg = fit_error(table, opt);
  EXPECT_NE(msg.find("not identifiable"), std::string::npos) << msg;
  EXPECT_NE(msg.find("offset_drift[u]"), std::string::npos) << msg;
  EXPECT_NE(msg.find("S[u_x]"), std::string::npos) << msg;
  EXPECT_NE(msg.find("O[u]"), std::string::npos) << msg;
}

TEST(FitBadInput, BadOptions) {
  FitOptions opt;
  opt.local_gravity = -1.0;
  EXPECT_NE(fit_error(good_table(), opt).find("local_gravity"), std::string::npos);
  opt = FitOptions();
  opt.min_positions_per_phase = 2;
  EXPECT_NE(fit_error(good_table(), opt).find("min_positions_per_phase"), std::string::npos);
  EXPECT_EQ(fit_error(PositionTable()), "the position table has no dwells");
  opt = FitOptions();
  opt.model = FitModel::Eq4;
  EXPECT_EQ(fit_error(PositionTable(), opt), "phase x has 0 dwells, needs at least 3");
}

// ---- effect terms ------------------------------------------------------------------------

struct EffectCase {
  const char* name;
  const char* target;
  double value;  // true value used in the simulations
  bool two_way;
};

// Values large enough to stand far above the noise of a 24-position run (dwell means of about
// 1.5e-3 m/s^2), small enough to be realistic.
const std::vector<EffectCase>& effect_cases() {
  static const std::vector<EffectCase> cases = {
      {"quadratic_nonlinearity", "u", 2e-4, false},
      {"quadratic_nonlinearity", "w", -1.5e-4, false},
      {"cubic_nonlinearity", "v", 4e-5, false},
      {"angle_offset", "x", 3e-3, false},
      {"angle_offset", "z", -2e-3, false},
      {"angle_scale", "y", 1e-3, false},
      {"axis_tilt", "x", 4e-3, false},
      {"axis_tilt", "z", -3e-3, false},
      {"offset_drift", "u", 1e-4, false},
      {"backlash", "y", 3e-3, true},
  };
  return cases;
}

// d predict_outputs / d(S, O, effect value) with ceres::Jet against central differences, at
// several geometries (all phases, both approaches, a non-zero time).
TEST(FitEffects, JetDerivativesMatchCentralDifferences) {
  using Jet = ceres::Jet<double, 13>;
  std::mt19937_64 rng(99);
  const Device base = random_triad(rng);
  const double g = kStandardGravity;
  std::vector<DwellGeometry> geoms;
  for (Phase p : kPhases)
    for (double a : {0.3, 2.0, 4.4})
      for (int approach : {+1, -1}) {
        DwellGeometry geo;
        geo.phase = p;
        geo.angle_rad = a;
        geo.time_s = 37.5;
        geo.approach = approach;
        geoms.push_back(geo);
      }
  for (const EffectCase& c : effect_cases()) {
    SCOPED_TRACE(std::string(c.name) + "[" + c.target + "]");
    const std::vector<Effect> terms = {make_effect(c.name, c.target)};
    Eigen::Matrix<double, 13, 1> x;
    for (int k = 0; k < 9; ++k) x(k) = base.S(k / 3, k % 3);
    x.segment<3>(9) = base.O;
    x(12) = c.value;
    auto eval = [&](const Eigen::Matrix<double, 13, 1>& p, const DwellGeometry& geo) {
      return predict_outputs<double>(p.data(), p.data() + 9, terms, p.data() + 12, geo, g);
    };
    for (const DwellGeometry& geo : geoms) {
      Jet xj[13];
      for (int k = 0; k < 13; ++k) xj[k] = Jet(x(k), k);
      const Eigen::Matrix<Jet, 3, 1> out = predict_outputs<Jet>(xj, xj + 9, terms, xj + 12, geo, g);
      const Eigen::Vector3d value = eval(x, geo);
      for (int s = 0; s < 3; ++s) EXPECT_DOUBLE_EQ(out(s).a, value(s));
      for (int k = 0; k < 13; ++k) {
        const double h = 1e-6 * std::max(1e-3, std::abs(x(k)));
        Eigen::Matrix<double, 13, 1> xp = x, xm = x;
        xp(k) += h;
        xm(k) -= h;
        const Eigen::Vector3d fd = (eval(xp, geo) - eval(xm, geo)) / (2.0 * h);
        for (int s = 0; s < 3; ++s) {
          EXPECT_NEAR(out(s).v(k), fd(s), 1e-6 * std::max(1.0, std::abs(fd(s))))
              << "output " << s << " parameter " << k << " phase " << phase_name(geo.phase)
              << " angle " << geo.angle_rad;
        }
      }
    }
  }
}

SimulationOptions effect_simulation(const EffectCase& c, std::uint64_t seed, double noise) {
  std::mt19937_64 rng(seed);
  SimulationOptions sim;
  sim.truth = random_triad(rng);
  sim.truth.effects = {make_effect(c.name, c.target, c.value)};
  sim.protocol.two_way = c.two_way;
  sim.noise_density = noise;
  sim.seed = seed;
  return sim;
}

TEST(FitEffects, NoiseFreeRecoveryIsExact) {
  for (const EffectCase& c : effect_cases()) {
    SCOPED_TRACE(std::string(c.name) + "[" + c.target + "]");
    const SimulationOptions sim = effect_simulation(c, 17, 0.0);
    const PositionTable table = simulate_position_table(sim);
    FitOptions opt;
    opt.effects = {make_effect(c.name, c.target, 0.0)};  // start from zero
    const FitResult r = fit(table, opt);
    ASSERT_EQ(r.effects.size(), 1u);
    EXPECT_NEAR(r.effects[0].value, c.value, 1e-9 * std::abs(c.value));
    expect_exact(r, sim.truth, 1e-9);
    EXPECT_EQ(r.model_label(), std::string("joint+") + c.name + "[" + c.target + "]");
    EXPECT_FALSE(r.solver_message.empty());
  }
}

// Over 20 seeds per effect case (200 noisy fits): the count of estimates beyond 2 of their
// reported standard uncertainties is binomial(200, 0.0455) for honest uncertainties, bounded on
// both sides at the 2.5e-4 quantiles; S within 5.3 of its standard uncertainties (1800 checks at
// P(|z| > 5.3) = 1.2e-7: < 2.5e-4 for all); the effect resolved and the plain fit worse in every
// fit. A correct fit fails this test in < 1e-3 of seed sets.
TEST(FitEffects, NoisyRecoveryRateWithinReportedUncertainty) {
  namespace sb = statistical_bounds;
  const int seeds = 20;
  int fits = 0, beyond_2 = 0;
  const double k_S = sb::normal_k(2.5e-4 / (9.0 * seeds * effect_cases().size()));
  for (const EffectCase& c : effect_cases()) {
    SCOPED_TRACE(std::string(c.name) + "[" + c.target + "]");
    for (int seed = 0; seed < seeds; ++seed) {
      const SimulationOptions sim = effect_simulation(c, 2300 + static_cast<std::uint64_t>(seed),
                                                      SimulationOptions().noise_density);
      const PositionTable table = simulate_position_table(sim);
      FitOptions opt;
      opt.effects = {make_effect(c.name, c.target, 0.0)};
      const FitResult r = fit(table, opt);
      ASSERT_EQ(r.effects_std.size(), 1u);
      const double est = r.effects[0].value;
      const double sd = r.effects_std[0];
      EXPECT_GT(sd, 0.0);
      ++fits;
      if (std::abs(est - c.value) > 2.0 * sd) ++beyond_2;
      EXPECT_GT(std::abs(c.value), 5.0 * sd) << "effect not clearly resolved: +- " << sd;
      EXPECT_LT(r.reduced_chi2, 1.5);
      // Without the term the same data do not fit: the test can tell the effect is there.
      const FitResult plain = fit(table);
      EXPECT_GT(plain.reduced_chi2, 2.0 * r.reduced_chi2);
      // And S is recovered with the effect fitted.
      for (int k = 0; k < 9; ++k)
        EXPECT_LT(std::abs(r.S(k / 3, k % 3) - sim.truth.S(k / 3, k % 3)),
                  k_S * std::sqrt(r.covariance(k, k)));
    }
  }
  const double p2 = std::erfc(2.0 / std::sqrt(2.0));
  const int lo = sb::binomial_lower(fits, p2, 2.5e-4), hi = sb::binomial_upper(fits, p2, 2.5e-4);
  std::printf("effect estimates beyond 2 std: %d of %d (bounds %d..%d)\n", beyond_2, fits, lo, hi);
  EXPECT_GE(beyond_2, lo);
  EXPECT_LE(beyond_2, hi);
}

TEST(FitEffects, SeveralEffectsTogether) {
  std::mt19937_64 rng(41);
  SimulationOptions sim;
  sim.truth = random_triad(rng);
  sim.truth.effects = {make_effect("quadratic_nonlinearity", "v", 2e-4),
                       make_effect("angle_offset", "x", 2e-3), make_effect("backlash", "x", 2e-3),
                       make_effect("offset_drift", "w", -1e-4)};
  sim.protocol.two_way = true;
  sim.noise_density = 0.0;
  FitOptions opt;
  for (Effect e : sim.truth.effects) {
    e.value = 0.0;
    opt.effects.push_back(e);
  }
  const FitResult r = fit(simulate_position_table(sim), opt);
  for (std::size_t i = 0; i < opt.effects.size(); ++i)
    EXPECT_NEAR(r.effects[i].value, sim.truth.effects[i].value,
                1e-9 * std::abs(sim.truth.effects[i].value));
  expect_exact(r, sim.truth, 1e-9);
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
