// Replays every input under fuzz/corpus/position_table (seeds and any crash the fuzzer found,
// committed there) through the CSV reader: each must be rejected cleanly or round-trip exactly.
#include <dirent.h>
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../../support/source_dir.h"
#include "accel_intrinsics/core/dwells/position_table.h"

namespace core = accel_intrinsics::core;

TEST(FuzzRegression, PositionTableCorpusIsRejectedCleanlyOrRoundTrips) {
  const std::string dir =
      accel_intrinsics::test_support::source_dir() + "/fuzz/corpus/position_table";
  DIR* handle = opendir(dir.c_str());
  ASSERT_NE(handle, nullptr) << dir;
  std::vector<std::string> files;
  while (dirent* entry = readdir(handle)) {
    if (entry->d_name[0] != '.') files.push_back(dir + "/" + entry->d_name);
  }
  closedir(handle);
  ASSERT_GE(files.size(), 3u);
  int parsed = 0;
  for (const std::string& path : files) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream content;
    content << in.rdbuf();
    std::istringstream input(content.str());
    core::PositionTable table;
    try {
      table = core::read_position_table(input, path);
    } catch (const core::PositionTableError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos);
      continue;
    }
    ++parsed;
    std::stringstream buffer;
    core::write_position_table(buffer, table);
    const core::PositionTable back = core::read_position_table(buffer);
    ASSERT_EQ(back.rows.size(), table.rows.size()) << path;
    for (std::size_t i = 0; i < back.rows.size(); ++i) {
      EXPECT_EQ(back.rows[i].mean, table.rows[i].mean) << path;
      EXPECT_EQ(back.rows[i].angle_rad, table.rows[i].angle_rad) << path;
    }
  }
  EXPECT_GE(parsed, 1);
}
