// Any known orientations (DESIGN.md section 6): position tables whose rows give the specific
// force direction (6-position flip, 24-position tumble), gimbal runs missing a phase, and sets
// that do not determine S and O (the error names the unobservable combination). The data are
// made here from R = S g f + O with Gaussian noise, not by the simulator.
#include <gtest/gtest.h>

#include <random>
#include <sstream>

#include "accel_intrinsics/core/fit.h"
#include "accel_intrinsics/core/simulator.h"

namespace accel_intrinsics {
namespace core {
namespace {

Eigen::Matrix3d device_S() {
  Eigen::Matrix3d S;
  S << 1.012, 0.004, -0.009, -0.003, 0.991, 0.011, 0.006, -0.007, 1.004;
  return S;
}
const Eigen::Vector3d kO(0.12, -0.05, 0.2);
constexpr double kNoise = 0.004;  // m/s^2, std of a dwell mean's samples
constexpr std::uint64_t kSamples = 400;

PositionTable table_of(const std::vector<Eigen::Vector3d>& directions, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, kNoise / std::sqrt(static_cast<double>(kSamples)));
  PositionTable t;
  double time = 0.0;
  for (std::size_t i = 0; i < directions.size(); ++i) {
    DwellRecord r;
    r.has_direction = true;
    r.direction = directions[i].normalized();
    r.step = static_cast<std::uint32_t>(i);
    r.t_start_s = time;
    r.t_end_s = time += 10.0;
    r.n = kSamples;
    r.mean = device_S() * (kStandardGravity * r.direction) + kO + Eigen::Vector3d(n(rng), n(rng), n(rng));
    r.std = Eigen::Vector3d::Constant(kNoise);
    t.rows.push_back(r);
  }
  return t;
}

std::vector<Eigen::Vector3d> six_positions() {
  return {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
}

// 12 edge, 8 corner and 4 face directions of a cube.
std::vector<Eigen::Vector3d> tumble24() {
  std::vector<Eigen::Vector3d> d;
  for (int a = 0; a < 3; ++a)
    for (int s1 : {-1, 1})
      for (int s2 : {-1, 1}) {
        Eigen::Vector3d v = Eigen::Vector3d::Zero();
        v((a + 1) % 3) = s1;
        v((a + 2) % 3) = s2;
        d.push_back(v);
      }
  for (int x : {-1, 1})
    for (int y : {-1, 1})
      for (int z : {-1, 1}) d.emplace_back(x, y, z);
  d.emplace_back(1, 0, 0);
  d.emplace_back(-1, 0, 0);
  d.emplace_back(0, 0, 1);
  d.emplace_back(0, 0, -1);
  return d;
}

void expect_recovered(const FitResult& r, double sigmas) {
  for (int s = 0; s < 3; ++s) {
    for (int c = 0; c < 3; ++c) {
      const double sd = std::sqrt(r.covariance(3 * s + c, 3 * s + c));
      EXPECT_GT(sd, 0.0);
      EXPECT_NEAR(r.S(s, c), device_S()(s, c), sigmas * sd) << s << c;
    }
    EXPECT_NEAR(r.O(s), kO(s), sigmas * r.O_std(s)) << s;
  }
}

TEST(Orientations, SixPositionFlipDeterminesSAndO) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const FitResult r = fit(table_of(six_positions(), seed));
    expect_recovered(r, 4.5);
    EXPECT_EQ(r.dof, 18 - 12);
    EXPECT_EQ(r.positions[0] + r.positions[1] + r.positions[2], 0);
  }
}

TEST(Orientations, TumbleOf24RecoversTheDeviceWithHonestUncertainty) {
  // The spread of the estimates over many tables matches the reported standard deviation.
  const int draws = 300;
  double sum_sq = 0.0, reported = 0.0;
  for (int k = 0; k < draws; ++k) {
    const FitResult r = fit(table_of(tumble24(), 100 + k));
    sum_sq += std::pow(r.S(1, 2) - device_S()(1, 2), 2);
    reported += std::sqrt(r.covariance(5, 5));
  }
  const double observed = std::sqrt(sum_sq / draws);
  reported /= draws;
  EXPECT_NEAR(observed / reported, 1.0, 0.15) << observed << " vs " << reported;
}

TEST(Orientations, Eq4RefusesDirectionRows) {
  FitOptions o;
  o.model = FitModel::Eq4;
  try {
    fit(table_of(six_positions(), 1), o);
    FAIL() << "eq4 took direction rows";
  } catch (const FitError& e) {
    EXPECT_NE(std::string(e.what()).find("use the joint model"), std::string::npos) << e.what();
  }
}

TEST(Orientations, UnobservableSetNamesTheCombination) {
  // Gravity never has a z component: the z column of S is unobservable.
  try {
    fit(table_of({{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {1, 1, 0}, {1, -1, 0}}, 1));
    FAIL() << "fitted an unobservable set";
  } catch (const FitError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("do not determine S and O"), std::string::npos) << m;
    EXPECT_NE(m.find("0 f_x + 0 f_y + 1 f_z + 0 = 0"), std::string::npos) << m;
  }
  // Four orientations on one circle of the sphere (f_x + f_y + f_z = 1): the offsets cannot be
  // told from the sum of the vector components.
  try {
    fit(table_of({{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {2, 2, -1}}, 1));
    FAIL() << "fitted an unobservable set";
  } catch (const FitError& e) {
    EXPECT_NE(std::string(e.what()).find("1 f_x + 1 f_y + 1 f_z + -1 = 0"), std::string::npos)
        << e.what();
  }
}

TEST(Orientations, GimbalRunMissingAPhaseIsFittedByJoint) {
  SimulationOptions sim;
  sim.truth.S = device_S();
  sim.truth.O = kO;
  sim.protocol.steps_per_phase = 12;
  PositionTable full = simulate_position_table(sim);
  PositionTable xy;
  for (const DwellRecord& r : full.rows)
    if (r.phase != Phase::Z) xy.rows.push_back(r);
  const FitResult r = fit(xy);
  expect_recovered(r, 4.5);
  EXPECT_EQ(r.positions[2], 0);
  FitOptions eq4;
  eq4.model = FitModel::Eq4;
  EXPECT_THROW(fit(xy, eq4), FitError);
  // Phase z alone leaves the z column unobservable.
  PositionTable z_only;
  for (const DwellRecord& row : full.rows)
    if (row.phase == Phase::Z) z_only.rows.push_back(row);
  EXPECT_THROW(fit(z_only), FitError);
}

TEST(Orientations, CsvRoundTripWithDirections) {
  PositionTable t = table_of(six_positions(), 3);
  DwellRecord gimbal;  // a gimbal row beside them
  gimbal.phase = Phase::Y;
  gimbal.step = 2;
  gimbal.angle_rad = 0.5;
  gimbal.n = 10;
  gimbal.mean = Eigen::Vector3d(1, 2, 3);
  t.rows.push_back(gimbal);
  std::stringstream csv;
  write_position_table(csv, t);
  EXPECT_NE(csv.str().find(std::string(kPositionTableHeader) + kDirectionColumns),
            std::string::npos);
  const PositionTable back = read_position_table(csv);
  ASSERT_EQ(back.rows.size(), t.rows.size());
  for (std::size_t i = 0; i < t.rows.size(); ++i) {
    EXPECT_EQ(back.rows[i].has_direction, t.rows[i].has_direction);
    EXPECT_EQ(back.rows[i].mean, t.rows[i].mean);
    if (t.rows[i].has_direction) {
      EXPECT_TRUE(back.rows[i].direction.isApprox(t.rows[i].direction, 1e-15));
    }
  }
  EXPECT_EQ(back.rows.back().phase, Phase::Y);

  auto error_of = [](const std::string& text) {
    std::istringstream in(text);
    try {
      read_position_table(in);
    } catch (const PositionTableError& e) {
      return std::string(e.what());
    }
    return std::string("(none)");
  };
  const std::string header = std::string(kPositionTableHeader) + kDirectionColumns + "\n";
  EXPECT_NE(error_of(header + "-,0,0,0,1,10,1,2,3,0.1,0.1,0.1,0.5,0.5,0\n").find("unit vector"),
            std::string::npos);
  EXPECT_NE(error_of(header + "-,0,0,0,1,10,1,2,3,0.1,0.1,0.1,,,\n").find("needs the direction"),
            std::string::npos);
  // A direction row needs no angle.
  EXPECT_EQ(error_of(header + "-,0,,0,1,10,1,2,3,0.1,0.1,0.1,0,0,1\n"), "(none)");
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
