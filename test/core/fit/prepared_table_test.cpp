// Tests of the prepared view of a position table (prepared_table.h): its contents against the
// table's own accessors and the equations, on tables written here; and that a fit prepares its
// table once, whatever the model, and gives the same result from a view prepared by the caller.
#include "accel_intrinsics/core/fit/prepared_table.h"

#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/constants.h"

namespace accel_intrinsics {
namespace core {
namespace {

constexpr double kG = 9.81;

// Phase x sweeps up 0, 90, 180 degrees and returns to 90 (approach -1); y and z go up; the last
// row is a known orientation with a single sample (its standard error is the median fallback).
const char* const kTableCsv =
    "phase,step,angle_rad,t_start,t_end,n,mean_u,mean_v,mean_w,std_u,std_v,std_w,f_x,f_y,f_z,"
    "temperature_c\n"
    "x,0,0,10,12,100,0.1,0.2,9.8,0.01,0.02,0.03,,,,25.0\n"
    "x,1,1.5707963267948966,14,16,400,0.1,9.8,0.3,0.02,0.02,0.02,,,,25.5\n"
    "x,2,3.141592653589793,18,20,100,0.1,0.2,-9.8,0.03,0.01,0.01,,,,26.0\n"
    "x,1,1.5707963267948966,22,24,100,0.1,9.8,0.3,0.04,0.02,0.05,,,,26.5\n"
    "y,0,0,30,32,100,0.1,0.2,9.8,0.01,0.01,0.01,,,,\n"
    "y,1,1.5707963267948966,34,36,100,9.8,0.2,0.3,0.01,0.01,0.01,,,,27.5\n"
    "y,2,3.141592653589793,38,40,100,0.1,0.2,-9.8,0.01,0.01,0.01,,,,28.0\n"
    "z,0,0,42,44,100,0.1,9.8,0.3,0.01,0.01,0.01,,,,28.5\n"
    "z,1,1.5707963267948966,46,48,100,9.8,0.2,0.3,0.01,0.01,0.01,,,,29.0\n"
    "z,2,3.141592653589793,50,52,100,0.1,-9.8,0.3,0.01,0.01,0.01,,,,29.5\n"
    "-,0,,54,56,1,5.9,0.2,7.9,0,0,0,0.6,0,0.8,30.0\n";

PositionTable table_written_here() {
  std::istringstream in(kTableCsv);
  return read_position_table(in, "test");
}

void expect_same_geometry(const DwellGeometry& a, const DwellGeometry& b, std::size_t row) {
  SCOPED_TRACE("row " + std::to_string(row));
  EXPECT_EQ(a.phase, b.phase);
  EXPECT_EQ(a.angle_rad, b.angle_rad);
  EXPECT_EQ(a.time_s, b.time_s);
  EXPECT_EQ(a.approach, b.approach);
  EXPECT_EQ(a.has_temperature, b.has_temperature);
  EXPECT_EQ(a.temperature_offset_k, b.temperature_offset_k);
  EXPECT_EQ(a.has_direction, b.has_direction);
  EXPECT_EQ(a.direction, b.direction);
}

TEST(PreparedTable, HoldsWhatTheTablesOwnAccessorsGive) {
  const PositionTable table = table_written_here();
  ASSERT_EQ(table.rows.size(), 11u);
  const PreparedTable prepared(table);
  EXPECT_EQ(&prepared.table(), &table);
  ASSERT_EQ(prepared.size(), table.rows.size());
  for (std::size_t i = 0; i < table.rows.size(); ++i) EXPECT_EQ(&prepared.row(i), &table.rows[i]);

  // Per-row geometry: the direction of gravity in the DUT frame, and the model's inputs.
  for (std::size_t i = 0; i < table.rows.size(); ++i)
    EXPECT_EQ(prepared.direction(i), specific_force_direction(table.rows[i])) << "row " << i;
  const std::vector<DwellGeometry> geometries = dwell_geometries(table);
  ASSERT_EQ(prepared.geometries().size(), geometries.size());
  for (std::size_t i = 0; i < geometries.size(); ++i)
    expect_same_geometry(prepared.geometries()[i], geometries[i], i);
  // The same from the equations: x at 0 is (0, sin 0, cos 0), z at 90 degrees (sin, cos, 0).
  EXPECT_NEAR((prepared.direction(0) - Eigen::Vector3d(0, 0, 1)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((prepared.direction(8) - Eigen::Vector3d(1, 0, 0)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((prepared.direction(10) - Eigen::Vector3d(0.6, 0.0, 0.8)).norm(), 0.0, 1e-15);
  EXPECT_EQ(prepared.geometries()[1].approach, +1);
  EXPECT_EQ(prepared.geometries()[3].approach, -1);  // back down to 90 degrees
  EXPECT_FALSE(prepared.geometries()[4].has_temperature);
  EXPECT_TRUE(prepared.geometries()[5].has_temperature);
  // t0 = the earliest t_start (10 s): row 0's mid-dwell time is 1 s.
  EXPECT_DOUBLE_EQ(prepared.geometries()[0].time_s, 1.0);

  // Weights: std / sqrt(n), the single-sample row the median of the others.
  const std::vector<Eigen::Vector3d> se = dwell_standard_errors(table);
  ASSERT_EQ(prepared.standard_errors().size(), se.size());
  for (std::size_t i = 0; i < se.size(); ++i)
    EXPECT_EQ(prepared.standard_errors()[i], se[i]) << "row " << i;
  EXPECT_DOUBLE_EQ(prepared.standard_errors()[1](0), 0.02 / 20.0);
  // se_u of the ten others: 0.001 (eight rows), 0.003, 0.004: the median of ten is 0.001.
  EXPECT_DOUBLE_EQ(prepared.standard_errors()[10](0), 0.001);
  EXPECT_FALSE(prepared.unit_weights());

  // Per-phase counts and rows.
  EXPECT_EQ(prepared.positions_per_phase(), positions_per_phase(table));
  EXPECT_EQ(prepared.positions_per_phase(), (std::array<int, 3>{{4, 3, 3}}));
  EXPECT_EQ(prepared.phase_rows(Phase::X), (std::vector<std::size_t>{0, 1, 2, 3}));
  EXPECT_EQ(prepared.phase_rows(Phase::Y), (std::vector<std::size_t>{4, 5, 6}));
  EXPECT_EQ(prepared.phase_rows(Phase::Z), (std::vector<std::size_t>{7, 8, 9}));
  EXPECT_EQ(prepared.rows_with_direction(), rows_with_direction(table));
  EXPECT_EQ(prepared.rows_with_direction(), 1u);
  EXPECT_EQ(prepared.rows_with_unknown_orientation(), 0u);
}

TEST(PreparedTable, RestsOfUnknownOrientationAndUnitWeights) {
  const PositionTable tumble = forget_orientations(table_written_here());
  const PreparedTable prepared(tumble);
  EXPECT_EQ(prepared.rows_with_unknown_orientation(), rows_with_unknown_orientation(tumble));
  EXPECT_EQ(prepared.rows_with_unknown_orientation(), tumble.rows.size());
  EXPECT_EQ(prepared.rows_with_direction(), 0u);
  EXPECT_EQ(prepared.positions_per_phase(), (std::array<int, 3>{{0, 0, 0}}));
  for (Phase p : kPhases) EXPECT_TRUE(prepared.phase_rows(p).empty());
  // No orientation is known: no direction.
  for (std::size_t i = 0; i < prepared.size(); ++i)
    EXPECT_EQ(prepared.direction(i), Eigen::Vector3d(Eigen::Vector3d::Zero())) << "row " << i;

  // No row with a usable std_w: w falls back to unit weights, and the view says so.
  PositionTable no_std_w = table_written_here();
  for (DwellRecord& row : no_std_w.rows) row.std(2) = 0.0;
  const PreparedTable unit(no_std_w);
  EXPECT_TRUE(unit.unit_weights());
  for (std::size_t i = 0; i < unit.size(); ++i) EXPECT_EQ(unit.standard_errors()[i](2), 1.0);
}

// A gimbal run written from the equations R = S g f(phase, angle) + O, each mean nudged by a
// fixed pattern of a few standard errors so that chi-square is not zero.
PositionTable gimbal_run_from_equations(std::uint32_t steps) {
  Eigen::Matrix3d S;
  S << 1.02, 0.01, -0.005, 0.004, 0.98, 0.012, -0.008, 0.006, 1.01;
  const Eigen::Vector3d O(0.12, -0.07, 0.2);
  const double sd = 0.003, n = 400.0;
  PositionTable table;
  table.time_origin_s = 0.0;
  double t = 5.0;
  int k = 0;
  for (Phase p : kPhases) {
    for (std::uint32_t j = 0; j < steps; ++j, ++k) {
      const double a = 2.0 * kPi * j / steps;
      const double s = std::sin(a), c = std::cos(a);
      const Eigen::Vector3d f = p == Phase::X   ? Eigen::Vector3d(0, s, c)
                                : p == Phase::Y ? Eigen::Vector3d(s, 0, c)
                                                : Eigen::Vector3d(s, c, 0);
      DwellRecord row;
      row.phase = p;
      row.step = j;
      row.angle_rad = a;
      row.t_start_s = t;
      row.t_end_s = t + 4.0;
      t += 6.0;
      row.n = static_cast<std::uint64_t>(n);
      row.std = Eigen::Vector3d::Constant(sd);
      const Eigen::Vector3d nudge(std::sin(1.3 * k), std::cos(2.1 * k), std::sin(0.7 * k + 1.0));
      row.mean = S * (kG * f) + O + 2.0 * sd / std::sqrt(n) * nudge;
      table.rows.push_back(row);
    }
  }
  return table;
}

void expect_identical(const FitResult& a, const FitResult& b) {
  EXPECT_EQ(a.S, b.S);
  EXPECT_EQ(a.O, b.O);
  EXPECT_EQ(a.covariance, b.covariance);
  EXPECT_EQ(a.chi2, b.chi2);
  EXPECT_EQ(a.dof, b.dof);
  EXPECT_EQ(a.positions, b.positions);
  ASSERT_EQ(a.effects.size(), b.effects.size());
  for (std::size_t i = 0; i < a.effects.size(); ++i)
    EXPECT_EQ(a.effects[i].value, b.effects[i].value);
}

TEST(PreparedTable, AFitPreparesItsTableOnceWhateverTheModel) {
  const PositionTable gimbal = gimbal_run_from_equations(8);
  PositionTable positions = gimbal;  // half of the rows as known directions
  for (std::size_t i = 0; i < positions.rows.size(); i += 2) {
    positions.rows[i].direction = specific_force_direction(positions.rows[i]);
    positions.rows[i].has_direction = true;
  }
  const PositionTable tumble = forget_orientations(gimbal);

  FitOptions joint;
  joint.local_gravity = kG;
  FitOptions eq4 = joint;
  eq4.model = FitModel::Eq4;
  FitOptions effects = joint;
  effects.effects = {Effect{EffectKind::AngleOffset, 0, 0.0}};
  FitOptions gls = joint;  // a slow part: generalized least squares
  gls.noise_model = white_noise_model(Eigen::Vector3d::Constant(0.003), 100.0);
  for (AxisNoiseModel& axis : gls.noise_model.axes) {
    axis.gm_sigma = 2e-4;
    axis.gm_tau_s = 30.0;
  }
  FitOptions gls_eq4 = gls;
  gls_eq4.model = FitModel::Eq4;

  struct Case {
    const char* name;
    const PositionTable* table;
    const FitOptions* options;
    FitModel model;
  };
  const Case cases[] = {{"joint", &gimbal, &joint, FitModel::Joint},
                        {"eq4", &gimbal, &eq4, FitModel::Eq4},
                        {"joint+angle_offset", &gimbal, &effects, FitModel::Joint},
                        {"joint, slow part", &gimbal, &gls, FitModel::Joint},
                        {"eq4, slow part", &gimbal, &gls_eq4, FitModel::Eq4},
                        {"known directions", &positions, &joint, FitModel::Joint},
                        {"tumble", &tumble, &joint, FitModel::Tumble}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::uint64_t before = prepared_table_builds();
    const FitResult from_table = fit(*c.table, *c.options);
    EXPECT_EQ(prepared_table_builds() - before, 1u);
    EXPECT_EQ(from_table.model, c.model);
    EXPECT_GT(from_table.chi2, 0.0);

    // A view prepared by the caller: no further preparation, the same result to the bit.
    const PreparedTable prepared(*c.table);
    const std::uint64_t after_prepare = prepared_table_builds();
    const FitResult from_view = fit(prepared, *c.options);
    EXPECT_EQ(prepared_table_builds(), after_prepare);
    expect_identical(from_view, from_table);
  }
}

TEST(PreparedTable, OneViewServesFitsWithDifferentOptions) {
  const PositionTable gimbal = gimbal_run_from_equations(6);
  const PreparedTable prepared(gimbal);
  FitOptions joint;
  joint.local_gravity = kG;
  FitOptions eq4 = joint;
  eq4.model = FitModel::Eq4;
  const std::uint64_t before = prepared_table_builds();
  const FitResult a = fit(prepared, joint);
  const FitResult b = fit(prepared, eq4);
  const FitResult a_again = fit(prepared, joint);
  EXPECT_EQ(prepared_table_builds(), before);
  EXPECT_EQ(a.model, FitModel::Joint);
  EXPECT_EQ(b.model, FitModel::Eq4);
  expect_identical(a_again, a);
  // The validators read the view too: too few positions per phase for what the options ask.
  FitOptions strict = joint;
  strict.min_positions_per_phase = 7;
  try {
    fit(prepared, strict);
    ADD_FAILURE() << "fit with 6 positions per phase and min 7 did not throw";
  } catch (const FitError& e) {
    EXPECT_NE(std::string(e.what()).find("has 6 dwells, needs at least 7"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace core
}  // namespace accel_intrinsics
