// The checkpoint files: a kill in the middle of writing a row leaves a torn last line, which
// load() drops (from the file too) so the restored table holds the complete rows only and the
// run continues appending after them; a broken state file is an error naming it, never a fresh
// run in disguise.
#include "accel_intrinsics/io/checkpoint.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "../support/test_files.h"
#include "accel_intrinsics/io/atomic_file.h"

namespace accel_intrinsics {
namespace io {
namespace {

using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

core::DwellRecord row(core::Phase phase, std::uint32_t step) {
  core::DwellRecord r;
  r.phase = phase;
  r.step = step;
  r.angle_rad = 0.5 * step;
  r.t_start_s = 10.0 * step;
  r.t_end_s = 10.0 * step + 5.0;
  r.n = 100 + step;
  r.mean = Eigen::Vector3d(0.1 * step, 0.2, 9.8);
  r.std = Eigen::Vector3d(0.01, 0.02, 0.03);
  return r;
}

TEST(Checkpoint, TornLastLineIsDroppedAndTheRunContinuesAfterTheCompleteRows) {
  TempDir dir;
  {
    CheckpointFiles files(dir.path(), "rig1_");
    for (std::uint32_t k = 0; k < 3; ++k) files.append_row(row(core::Phase::X, k));
    core::CheckpointState state;
    state.time_origin_s = 123.5;
    state.steps = 6;
    files.write_state(state);
  }
  const std::string table_path = dir.path() + "/rig1_position_table.csv";
  {
    // The kill: half of the fourth row reached the disk.
    std::ofstream out(table_path, std::ios::app);
    out << "x,3,1.5,30,35,10";
  }
  CheckpointFiles files(dir.path(), "rig1_");
  const std::optional<CheckpointFiles::Restored> restored = files.load();
  ASSERT_TRUE(restored.has_value());
  EXPECT_TRUE(restored->dropped_torn_line);
  ASSERT_EQ(restored->table.rows.size(), 3u);
  EXPECT_EQ(restored->state.rows, 3u);
  EXPECT_EQ(restored->state.steps, 6u);
  EXPECT_EQ(restored->table.time_origin_s, 123.5);
  for (std::uint32_t k = 0; k < 3; ++k) {
    EXPECT_EQ(restored->table.rows[k].step, k);
    EXPECT_EQ(restored->table.rows[k].mean, row(core::Phase::X, k).mean);
  }
  const std::string text = read_file(table_path);
  EXPECT_EQ(text.back(), '\n');
  EXPECT_EQ(text.find("x,3,1.5,30,35,10"), std::string::npos) << text;

  // The dwell is measured again and appended after the complete rows.
  files.append_row(row(core::Phase::X, 3));
  CheckpointFiles again(dir.path(), "rig1_");
  const auto reloaded = again.load();
  ASSERT_TRUE(reloaded.has_value());
  EXPECT_FALSE(reloaded->dropped_torn_line);
  ASSERT_EQ(reloaded->table.rows.size(), 4u);
  EXPECT_EQ(reloaded->table.rows[3].step, 3u);
  EXPECT_EQ(reloaded->table.rows[3].n, 103u);
}

// A run with temperatures checkpoints the temperature_c column and restores it; a checkpoint
// without the column continued by a row with a temperature gains the column (the file stays one
// table, the earlier rows without a value).
TEST(Checkpoint, TemperaturesAreKeptAndAnOldTableIsContinuedInItsOwnColumns) {
  TempDir dir;
  core::CheckpointState state;
  state.steps = 6;
  {
    CheckpointFiles files(dir.path(), "t_");
    for (std::uint32_t k = 0; k < 3; ++k) {
      core::DwellRecord r = row(core::Phase::Y, k);
      r.temperature_c = 21.5 + 0.25 * k;
      if (k == 1) r.temperature_c = std::numeric_limits<double>::quiet_NaN();  // no reading
      files.append_row(r);
    }
    files.write_state(state);
  }
  {
    CheckpointFiles files(dir.path(), "t_");
    const auto restored = files.load();
    ASSERT_TRUE(restored.has_value());
    ASSERT_EQ(restored->table.rows.size(), 3u);
    EXPECT_EQ(restored->table.rows[0].temperature_c, 21.5);
    EXPECT_FALSE(restored->table.rows[1].has_temperature());
    EXPECT_EQ(restored->table.rows[2].temperature_c, 22.0);
    core::DwellRecord r = row(core::Phase::Y, 3);
    r.temperature_c = 23.0;
    files.append_row(r);
    const auto again = CheckpointFiles(dir.path(), "t_").load();
    ASSERT_TRUE(again.has_value());
    ASSERT_EQ(again->table.rows.size(), 4u);
    EXPECT_EQ(again->table.rows[3].temperature_c, 23.0);
  }

  // An older checkpoint (no temperature column) continued by a run that now has temperatures.
  TempDir old_dir;
  {
    CheckpointFiles files(old_dir.path(), "o_");
    files.append_row(row(core::Phase::X, 0));  // no temperature: no column
    files.write_state(state);
  }
  CheckpointFiles files(old_dir.path(), "o_");
  ASSERT_TRUE(files.load().has_value());
  core::DwellRecord r = row(core::Phase::X, 1);
  r.temperature_c = 30.0;
  files.append_row(r);
  const auto restored = CheckpointFiles(old_dir.path(), "o_").load();
  ASSERT_TRUE(restored.has_value());  // still one readable table
  ASSERT_EQ(restored->table.rows.size(), 2u);
  EXPECT_FALSE(restored->table.rows[0].has_temperature());
  EXPECT_EQ(restored->table.rows[1].temperature_c, 30.0);
}

// A channel that starts late (the first dwell had no temperature reading, the later ones do)
// is kept: the table gains its column when the first value comes, in the same run and in a run
// continued from the checkpoint.
TEST(Checkpoint, AChannelThatStartsLateIsKept) {
  TempDir dir;
  core::CheckpointState state;
  state.steps = 6;
  {
    CheckpointFiles files(dir.path(), "late_");
    files.append_row(row(core::Phase::Z, 0));  // no reading yet
    core::DwellRecord r = row(core::Phase::Z, 1);
    r.temperature_c = 24.25;
    files.append_row(r);
    files.write_state(state);
  }
  CheckpointFiles files(dir.path(), "late_");
  const auto restored = files.load();
  ASSERT_TRUE(restored.has_value());
  ASSERT_EQ(restored->table.rows.size(), 2u);
  EXPECT_FALSE(restored->table.rows[0].has_temperature());
  EXPECT_EQ(restored->table.rows[1].temperature_c, 24.25);
  EXPECT_EQ(restored->table.rows[1].mean, row(core::Phase::Z, 1).mean);
  core::DwellRecord r = row(core::Phase::Z, 2);
  r.temperature_c = 24.5;
  files.append_row(r);
  const auto again = CheckpointFiles(dir.path(), "late_").load();
  ASSERT_TRUE(again.has_value());
  ASSERT_EQ(again->table.rows.size(), 3u);
  EXPECT_FALSE(again->table.rows[0].has_temperature());
  EXPECT_EQ(again->table.rows[1].temperature_c, 24.25);
  EXPECT_EQ(again->table.rows[2].temperature_c, 24.5);
}

// Every field of the state file survives the round trip, each with a value of its own (done and
// a fault of a finished run, as the node writes them at DONE and on an abort).
TEST(Checkpoint, StateRoundTripsEveryField) {
  TempDir dir;
  {
    CheckpointFiles files(dir.path(), "");
    files.append_row(row(core::Phase::Y, 2));
    core::CheckpointState state;
    state.time_origin_s = 1700000000.25;
    state.steps = 9;
    state.done = true;
    state.fault = "dwell phase y step 2 has 5 samples";
    files.write_state(state);
  }
  CheckpointFiles files(dir.path(), "");
  const auto restored = files.load();
  ASSERT_TRUE(restored.has_value());
  EXPECT_EQ(restored->state.time_origin_s, 1700000000.25);
  EXPECT_EQ(restored->state.steps, 9u);
  EXPECT_TRUE(restored->state.done);
  EXPECT_EQ(restored->state.fault, "dwell phase y step 2 has 5 samples");
}

TEST(Checkpoint, NoStateFileMeansNoCheckpoint) {
  TempDir dir;
  CheckpointFiles files(dir.path(), "");
  EXPECT_FALSE(files.load().has_value());
  CheckpointFiles disabled("", "");
  EXPECT_FALSE(disabled.enabled());
  EXPECT_FALSE(disabled.load().has_value());
}

TEST(Checkpoint, BrokenStateFileIsAnErrorNamingIt) {
  TempDir dir;
  CheckpointFiles files(dir.path(), "");
  files.append_row(row(core::Phase::Y, 0));
  {
    std::ofstream out(files.state_path());
    out << "time_origin_s: [not, a, number\n";
  }
  try {
    files.load();
    FAIL() << "a broken state file was accepted";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(files.state_path()), std::string::npos) << e.what();
  }
}

TEST(Checkpoint, ClearRemovesBothFiles) {
  TempDir dir;
  CheckpointFiles files(dir.path(), "");
  files.append_row(row(core::Phase::Z, 1));
  files.write_state(core::CheckpointState());
  ASSERT_TRUE(std::filesystem::exists(files.table_path()));
  files.clear();
  EXPECT_FALSE(std::filesystem::exists(files.table_path()));
  EXPECT_FALSE(std::filesystem::exists(files.state_path()));
}

}  // namespace
}  // namespace io
}  // namespace accel_intrinsics
