// Two rigs in two namespaces at once (test/ros/two_rigs.test).
#include <fstream>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "run_dirs.h"
#include "stand_checks.h"

namespace {

// Rows of a position table at angle 2 pi (the closing position).
std::size_t count_closing_rows(const std::string& path) {
  std::ifstream in(path);
  const accel_intrinsics::core::PositionTable table =
      accel_intrinsics::core::read_position_table(in, path);
  std::size_t n = 0;
  for (const auto& row : table.rows) {
    if (row.step > 0 && std::abs(row.angle_rad - 2.0 * M_PI) < 1e-9) ++n;
  }
  return n;
}

}  // namespace

TEST(TwoRigs, BothMatchTheirOwnTruth) {
  ros::NodeHandle pnh("~");
  const stand_checks::Limits limits = stand_checks::load_limits(pnh);
  std::vector<std::string> namespaces;
  double timeout_s = 300.0;
  std::string output_dir;
  std::vector<int> positions_per_phase;
  ASSERT_TRUE(pnh.getParam("namespaces", namespaces));
  ASSERT_EQ(namespaces.size(), 2u);
  ASSERT_TRUE(pnh.getParam("positions_per_phase", positions_per_phase));
  ASSERT_EQ(positions_per_phase.size(), namespaces.size());
  std::vector<bool> closing_position;
  ASSERT_TRUE(pnh.getParam("closing_position", closing_position));
  ASSERT_EQ(closing_position.size(), namespaces.size());
  pnh.getParam("timeout_s", timeout_s);
  ASSERT_TRUE(pnh.getParam("output_dir", output_dir));
  for (const std::string& ns : namespaces) {
    ASSERT_TRUE(ros::service::waitForService(
        stand_checks::join_ns(ns, "calibration/get_intrinsics"), ros::Duration(60.0)));
  }
  // Both at once, one supervisor.
  stand_checks::supervise_and_check(namespaces, limits, timeout_s, output_dir + "/supervise.json");

  std::vector<stand_checks::Truth> truths(2);
  for (std::size_t i = 0; i < namespaces.size(); ++i) {
    ASSERT_TRUE(stand_checks::load_truth(namespaces[i], &truths[i]));
    const accel_intrinsics::GetIntrinsics::Response res =
        stand_checks::get_intrinsics(namespaces[i]);
    ASSERT_TRUE(res.success) << namespaces[i] << ": " << res.message;
    stand_checks::expect_matches_truth(res.result, truths[i], limits, namespaces[i]);
    for (int p = 0; p < 3; ++p) {
      EXPECT_EQ(res.result.positions[p], static_cast<unsigned>(positions_per_phase[i]))
          << namespaces[i] << " phase " << p;
    }
    const std::string table =
        run_dirs::latest(output_dir + "/" + namespaces[i]) + "/position_table.csv";
    EXPECT_EQ(stand_checks::count_csv_rows(table), 3u * res.result.positions[0]);
    // The closing position is a row step = N at 2 pi, once per phase, only where it was run.
    const std::size_t closing_rows = count_closing_rows(table);
    EXPECT_EQ(closing_rows, closing_position[i] ? 3u : 0u) << table;
  }
  // The truths differ by far more than the uncertainty, so a mix-up could not pass.
  EXPECT_GT(std::abs(truths[0].responsivity[0] - truths[1].responsivity[0]), 0.01);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "two_rigs_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
