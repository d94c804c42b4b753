// Every run keeps its own directory (docs/design.md section 15): a second run of the same device
// gets a new directory (also within the same second) and `latest` follows it, the first run's
// files stay; devices are kept apart; the UTC names are checked against dates worked by hand.
#include "accel_intrinsics/io/run_directory.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "../support/test_files.h"

namespace accel_intrinsics {
namespace io {
namespace {

namespace fs = std::filesystem;
using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

TEST(RunDirectory, UtcNamesOfKnownInstants) {
  // 2026-11-27 14:15:02 UTC: 20784 days after 1970-01-01 (worked by hand: 56 years of which
  // 14 leap years, 1970..2025 = 20454 days, plus 330 days to 27 November 2026), + 51302 s.
  const double t = 20784.0 * 86400.0 + 14 * 3600 + 15 * 60 + 2 + 0.75;
  EXPECT_EQ(utc_basic_time(t), "20261127T141502Z");
  EXPECT_EQ(utc_iso_time(t), "2026-11-27T14:15:02Z");
  EXPECT_EQ(utc_basic_time(0.0), "19700101T000000Z");
}

TEST(RunDirectory, DeviceNamesAreOneSafeDirectory) {
  EXPECT_EQ(device_directory_name("SN-0042_a.b+c"), "SN-0042_a.b+c");
  EXPECT_EQ(device_directory_name("lab/../SN 1"), "lab_.._SN_1");
  EXPECT_EQ(device_directory_name(""), kUnnamedDevice);
  EXPECT_EQ(device_directory_name(".."), kUnnamedDevice);
}

TEST(RunDirectory, ASecondRunNeverReusesTheFirstAndLatestFollows) {
  TempDir dir;
  const RunDirectories runs(dir.path());
  EXPECT_EQ(runs.latest_run("A"), "");
  const double t = 1.8e9;
  const std::string first = runs.start_run("A", t);
  EXPECT_EQ(fs::path(first).parent_path(), fs::path(dir.path()) / "A");
  EXPECT_EQ(fs::path(first).filename(), utc_basic_time(t));
  { std::ofstream(fs::path(first) / "result.json") << "{\"run\": 1}\n"; }
  EXPECT_EQ(fs::canonical(runs.latest_run("A")), fs::canonical(first));

  const std::string second = runs.start_run("A", t + 0.5);  // the same second
  EXPECT_NE(second, first);
  EXPECT_EQ(fs::path(second).filename(), utc_basic_time(t) + "-2");
  EXPECT_EQ(fs::canonical(runs.latest_run("A")), fs::canonical(second));
  EXPECT_EQ(read_file((fs::path(first) / "result.json").string()), "{\"run\": 1}\n");
  // `latest` is a relative link: the tree can be moved or archived whole.
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(runs.latest_link("A"))));
  EXPECT_FALSE(fs::read_symlink(runs.latest_link("A")).is_absolute());

  const std::string other = runs.start_run("B", t + 60.0);
  EXPECT_EQ(fs::canonical(runs.latest_run("A")), fs::canonical(second));
  EXPECT_EQ(fs::canonical(runs.latest_run("B")), fs::canonical(other));
  // No temporary link left behind.
  std::size_t entries = 0;
  for (const auto& e : fs::directory_iterator(fs::path(dir.path()) / "A")) {
    (void)e;
    ++entries;
  }
  EXPECT_EQ(entries, 3u);  // two runs and latest
}

TEST(RunDirectory, LatestPointingNowhereIsNoRun) {
  TempDir dir;
  const RunDirectories runs(dir.path());
  const std::string run = runs.start_run("A", 1.8e9);
  fs::remove_all(run);
  EXPECT_EQ(runs.latest_run("A"), "");
  EXPECT_EQ(RunDirectories("").start_run("A", 1.8e9), "");
}

}  // namespace
}  // namespace io
}  // namespace accel_intrinsics
