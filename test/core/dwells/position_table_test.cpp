#include "accel_intrinsics/core/dwells/position_table.h"

#include <gtest/gtest.h>

#include <random>
#include <sstream>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/protocol.h"

namespace core = accel_intrinsics::core;

namespace {
core::PositionTable random_table(int rows, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-20, 20);
  core::PositionTable table;
  for (int i = 0; i < rows; ++i) {
    core::DwellRecord r;
    r.phase = static_cast<core::Phase>(i % 3);
    r.step = static_cast<std::uint32_t>(i);
    r.angle_rad = u(rng) / 7.0;
    r.t_start_s = 1e9 + i * 3.3;  // ROS-like absolute stamps must survive the round trip
    r.t_end_s = r.t_start_s + 2.0 + u(rng) * 1e-3;
    r.n = 100 + i;
    r.mean = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 1.000000001;
    r.std = Eigen::Vector3d(u(rng), u(rng), u(rng)).cwiseAbs() * 1e-3;
    table.rows.push_back(r);
  }
  return table;
}

std::string expect_error(const std::string& csv) {
  std::istringstream in(csv);
  try {
    core::read_position_table(in, "table.csv");
  } catch (const core::PositionTableError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for:\n" << csv;
  return "";
}

const std::string kHeader = std::string(core::kPositionTableHeader) + "\n";
const std::string kGoodRow = "x,0,0,1,3,200,0.1,0.2,9.8,0.01,0.01,0.01\n";
}  // namespace

TEST(DwellAccumulator, MatchesTwoPassStatisticsOnLargeOffsets) {
  // Welford must stay exact where the naive sum-of-squares formula loses every digit.
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0, 1e-3);
  std::vector<Eigen::Vector3d> xs;
  core::DwellAccumulator acc;
  for (int i = 0; i < 10000; ++i) {
    xs.emplace_back(1e6 + n(rng), 9.8 + n(rng), -3 + n(rng));
    acc.add(xs.back());
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& x : xs) mean += x;
  mean /= xs.size();
  Eigen::Vector3d var = Eigen::Vector3d::Zero();
  for (const auto& x : xs) var += (x - mean).cwiseAbs2();
  var /= (xs.size() - 1);
  EXPECT_EQ(acc.count(), 10000u);
  EXPECT_TRUE(acc.mean().isApprox(mean, 1e-14));
  // At an offset of 1e6 the data carry only ~9 digits of the 1e-3 spread: 1e-6 relative is the
  // best any method can do (a naive sum of squares would have no correct digit at all).
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(acc.sample_std()(k), std::sqrt(var(k)), 1e-6 * std::sqrt(var(k)));
  acc.reset();
  acc.add(Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(acc.sample_std(), Eigen::Vector3d::Zero());
}

TEST(PositionTableCsv, RoundTripIsExact) {
  const core::PositionTable table = random_table(30, 7);
  std::stringstream buffer;
  core::write_position_table(buffer, table);
  const core::PositionTable back = core::read_position_table(buffer);
  ASSERT_EQ(back.rows.size(), table.rows.size());
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    const auto& a = table.rows[i];
    const auto& b = back.rows[i];
    EXPECT_EQ(a.phase, b.phase);
    EXPECT_EQ(a.step, b.step);
    EXPECT_EQ(a.angle_rad, b.angle_rad);
    EXPECT_EQ(a.t_start_s, b.t_start_s);
    EXPECT_EQ(a.t_end_s, b.t_end_s);
    EXPECT_EQ(a.n, b.n);
    EXPECT_EQ(a.mean, b.mean);
    EXPECT_EQ(a.std, b.std);
  }
}

TEST(PositionTableCsv, MalformedRowsAreRejectedWithLineAndField) {
  EXPECT_NE(expect_error("").find("header"), std::string::npos);
  EXPECT_NE(expect_error("phase,step\n").find("line 1"), std::string::npos);
  std::string msg = expect_error(kHeader + kGoodRow + "x,1,0.5,1,3,200,0.1,0.2\n");
  EXPECT_NE(msg.find("table.csv line 3"), std::string::npos) << msg;
  EXPECT_NE(msg.find("expected 12 fields"), std::string::npos) << msg;
  msg =
      expect_error(kHeader + kGoodRow + kGoodRow + "q,1,0.5,1,3,200,0.1,0.2,9.8,0.01,0.01,0.01\n");
  EXPECT_NE(msg.find("line 4"), std::string::npos) << msg;
  EXPECT_NE(msg.find("phase"), std::string::npos) << msg;
  msg = expect_error(kHeader + "y,1,0.5,1,3,200,0.1,abc,9.8,0.01,0.01,0.01\n");
  EXPECT_NE(msg.find("line 2"), std::string::npos) << msg;
  EXPECT_NE(msg.find("mean_v"), std::string::npos) << msg;
  msg = expect_error(kHeader + "y,1,0.5,1,3,200,0.1,nan,9.8,0.01,0.01,0.01\n");
  EXPECT_NE(msg.find("mean_v is not finite"), std::string::npos) << msg;
  msg = expect_error(kHeader + "y,1,0.5,1,3,0,0.1,0.2,9.8,0.01,0.01,0.01\n");
  EXPECT_NE(msg.find("field n is 0"), std::string::npos) << msg;
  msg = expect_error(kHeader + "y,-1,0.5,1,3,10,0.1,0.2,9.8,0.01,0.01,0.01\n");
  EXPECT_NE(msg.find("field step"), std::string::npos) << msg;
  msg = expect_error(kHeader + "y,1,0.5,1,3,10,0.1,0.2,9.8,0.01,-0.01,0.01\n");
  EXPECT_NE(msg.find("std_v is negative"), std::string::npos) << msg;
  msg = expect_error(kHeader + "y,1,0.5,5,3,10,0.1,0.2,9.8,0.01,0.01,0.01\n");
  EXPECT_NE(msg.find("t_end is before t_start"), std::string::npos) << msg;
}

TEST(PositionTableCsv, ToleratesCrLfCommentsAndBlankLines) {
  std::istringstream in("# exported by a rig without ROS\r\n" +
                        std::string(core::kPositionTableHeader) +
                        "\r\n\r\nx,0,0,1,3,200,0.1,0.2,9.8,0.01,0.01,0.01\r\n");
  const auto table = core::read_position_table(in);
  ASSERT_EQ(table.rows.size(), 1u);
  EXPECT_EQ(table.rows[0].n, 200u);
}

TEST(PositionTableGeometry, ApproachFollowsTheSweepDirection) {
  core::PositionTable table;
  const double angles[] = {0.0, 1.0, 2.0, 2.0, 1.0, 0.0};
  for (double a : angles) {
    core::DwellRecord r;
    r.phase = core::Phase::Z;
    r.angle_rad = a;
    r.t_start_s = 10 + a;
    r.t_end_s = 12 + a;
    r.n = 5;
    table.rows.push_back(r);
  }
  const auto geoms = core::dwell_geometries(table);
  const int expected[] = {+1, +1, +1, -1, -1, -1};
  for (int i = 0; i < 6; ++i) EXPECT_EQ(geoms[i].approach, expected[i]) << i;
  // Without a known t0 the first dwell start is the origin; times are mid-dwell.
  EXPECT_DOUBLE_EQ(geoms[0].time_s, 1.0);
  table.time_origin_s = 5.0;
  EXPECT_DOUBLE_EQ(core::dwell_geometries(table)[1].time_s, 7.0);  // mid 12 - t0 5
}

TEST(PositionTableCsv, ClosingPositionRowReadsBackAndIsApproachedFromBelow) {
  // Step N = 4 at 2 pi after step 3 at 3/4 turn: the closing position of a phase.
  const double two_pi = 2.0 * core::kPi;
  std::ostringstream csv;
  csv.precision(17);
  csv << kHeader;
  for (std::uint32_t k = 0; k <= 4; ++k) {
    csv << "y," << k << ',' << core::step_angle(k, 4) << ',' << 10.0 + 3 * k << ',' << 12.0 + 3 * k
        << ",200,0.1,0.2,9.8,0.01,0.01,0.01\n";
  }
  std::istringstream in(csv.str());
  const core::PositionTable table = core::read_position_table(in, "closing.csv");
  ASSERT_EQ(table.rows.size(), 5u);
  EXPECT_EQ(table.rows[4].step, 4u);
  EXPECT_EQ(table.rows[4].angle_rad, two_pi);
  EXPECT_EQ(core::positions_per_phase(table)[1], 5);
  const auto geoms = core::dwell_geometries(table);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(geoms[i].approach, +1) << i;
  EXPECT_EQ(geoms[4].angle_rad, two_pi);  // not wrapped to 0
  // The round trip keeps it exactly.
  std::ostringstream out;
  core::write_position_table(out, table);
  std::istringstream again(out.str());
  EXPECT_EQ(core::read_position_table(again).rows[4].angle_rad, two_pi);
}

TEST(PositionTableGeometry, ApproachesMatchTheScheduleWithClosingPositionAndTwoWay) {
  // The directions inferred from the rows must be the ones the schedule (and so the simulator and
  // the backlash term) used: up with the closing position at 2 pi, then down from above.
  for (bool two_way : {false, true}) {
    core::ProtocolOptions options;
    options.steps_per_phase = 5;
    options.closing_position = true;
    options.two_way = two_way;
    const auto schedule = core::build_schedule(options);
    core::PositionTable table;
    for (const auto& p : schedule) {
      core::DwellRecord r;
      r.phase = p.phase;
      r.step = p.step;
      r.angle_rad = p.angle_rad;
      r.t_start_s = p.settled_s;
      r.t_end_s = p.dwell_end_s;
      r.n = 10;
      table.rows.push_back(r);
    }
    const auto geoms = core::dwell_geometries(table);
    ASSERT_EQ(geoms.size(), schedule.size());
    for (std::size_t i = 0; i < geoms.size(); ++i) {
      EXPECT_EQ(geoms[i].approach, schedule[i].approach) << (two_way ? "two-way " : "") << i;
    }
  }
}

// The channel columns (core::kChannels) follow f_x,f_y,f_z in any order; an unknown column or one
// given twice is an error naming it; the writer adds a channel's column when a row has a value.
TEST(PositionTableCsv, ChannelColumnsAreReadByNameAndWrittenWhenARowHasAValue) {
  const std::string base = core::kPositionTableHeader;
  std::istringstream in(base + ",temperature_c\nx,0,0,1,2,10,0,0,9.8,0.1,0.1,0.1,\n" +
                        "x,1,0.5,3,4,10,0,0,9.8,0.1,0.1,0.1,23.5\n");
  const core::PositionTable table = core::read_position_table(in);
  ASSERT_EQ(table.rows.size(), 2u);
  EXPECT_FALSE(table.rows[0].has_temperature());
  EXPECT_EQ(table.rows[1].temperature_c, 23.5);
  EXPECT_TRUE(
      core::columns_needed(table).channels[core::channel_index(core::Channel::Temperature)]);
  EXPECT_FALSE(core::columns_needed(table.rows[0]).channels[0]);

  std::ostringstream out;
  core::write_position_table(out, table);
  EXPECT_EQ(out.str().substr(0, out.str().find('\n')), base + ",temperature_c");
  std::istringstream back(out.str());
  EXPECT_EQ(core::read_position_table(back).rows[1].temperature_c, 23.5);

  EXPECT_NE(expect_error(base + ",humidity\n").find("unknown column 'humidity'"),
            std::string::npos);
  EXPECT_NE(expect_error(base + ",temperature_c,temperature_c\n").find("twice"), std::string::npos);
  EXPECT_NE(expect_error(base + ",temperature_c,f_x,f_y,f_z\n").find("unknown column 'f_x'"),
            std::string::npos);
}

namespace {
core::DwellRecord visit(core::Phase phase, std::uint32_t step, std::uint64_t n = 100) {
  core::DwellRecord r;
  r.phase = phase;
  r.step = step;
  r.angle_rad = 2.0 * core::kPi * step / 4.0;
  r.n = n;
  return r;
}
std::vector<std::size_t> superseded(const std::vector<core::DwellRecord>& rows) {
  core::PositionTable table;
  table.rows = rows;
  return core::find_remeasured_rows(table).rows;
}
}  // namespace

// A retried position (the same (phase, step) twice in a row) keeps the dwell measured again; the
// turn of a two-way sweep (up to step 3, down from step 3) is not a retry; a retry there leaves
// the visits with the most samples.
TEST(PositionTableGeometry, RemeasuredDwellsOfARetriedPositionAreFound) {
  using core::Phase;
  // One-way sweep, step 2 of phase x cut short and measured again.
  EXPECT_EQ(superseded({visit(Phase::X, 0), visit(Phase::X, 1), visit(Phase::X, 2, 7),
                        visit(Phase::X, 2), visit(Phase::X, 3), visit(Phase::Y, 0)}),
            (std::vector<std::size_t>{2}));
  // Retried twice: both earlier visits.
  EXPECT_EQ(superseded({visit(Phase::Y, 0, 3), visit(Phase::Y, 0, 5), visit(Phase::Y, 0),
                        visit(Phase::Y, 1)}),
            (std::vector<std::size_t>{0, 1}));
  // The last step of one phase and the first of the next are different positions.
  EXPECT_TRUE(superseded({visit(Phase::X, 3), visit(Phase::Y, 3), visit(Phase::Y, 2)}).empty());
  // Two-way sweep: 0 1 2 3 | 3 2 1 0, nothing superseded.
  std::vector<core::DwellRecord> two_way;
  for (std::uint32_t s : {0u, 1u, 2u, 3u, 3u, 2u, 1u, 0u}) two_way.push_back(visit(Phase::Z, s));
  EXPECT_TRUE(superseded(two_way).empty());
  // ... with a retry on the way down (step 1) and one at the turn (the up visit cut short).
  std::vector<core::DwellRecord> retried = two_way;
  retried.insert(retried.begin() + 6, visit(Phase::Z, 1, 9));  // before the last 1
  retried.insert(retried.begin() + 3, visit(Phase::Z, 3, 4));  // before the first 3
  // rows: 0 1 2 3(4) 3 3 2 1(9) 1 0
  EXPECT_EQ(superseded(retried), (std::vector<std::size_t>{3, 7}));
  // With a closing position (step 4) the return sweep's first visit of step 3 follows step 4: a
  // repeat there is a retry, not the turn.
  EXPECT_EQ(superseded({visit(Phase::X, 3), visit(Phase::X, 4), visit(Phase::X, 3, 2),
                        visit(Phase::X, 3), visit(Phase::X, 2)}),
            (std::vector<std::size_t>{2}));
  // Rows of a known direction are never taken for a repeat.
  core::DwellRecord known = visit(Phase::X, 0);
  known.has_direction = true;
  EXPECT_TRUE(superseded({known, known}).empty());
}

// A table without the superseded rows gives ApproachTracker the sweep as the schedule has it.
TEST(PositionTableGeometry, ApproachesOfARetriedTwoWayRunMatchTheSweepOnceTheRepeatIsDropped) {
  using core::Phase;
  core::PositionTable table;
  for (std::uint32_t s : {0u, 1u, 1u, 2u, 3u, 3u, 2u, 1u, 0u})
    table.rows.push_back(visit(Phase::Y, s));
  const core::SupersededRows found = core::find_remeasured_rows(table);
  ASSERT_EQ(found.rows, (std::vector<std::size_t>{1}));
  const core::PositionTable kept = core::without_rows(table, found.rows);
  ASSERT_EQ(kept.rows.size(), 8u);
  std::vector<int> approaches;
  for (const core::DwellGeometry& g : core::dwell_geometries(kept))
    approaches.push_back(g.approach);
  EXPECT_EQ(approaches, (std::vector<int>{+1, +1, +1, +1, -1, -1, -1, -1}));
  // Kept as it was, the repeat would have been taken as a turn of the sweep.
  std::vector<int> naive;
  for (const core::DwellGeometry& g : core::dwell_geometries(table)) naive.push_back(g.approach);
  EXPECT_EQ(naive[2], -1);
}
