// Replays every input under fuzz/corpus/bag_input (the seed bags and every input the bag fuzzer
// found crashing, committed there) through read_bag, with the chunk scan allowed and with rosbag
// forced: each must give a result or a BagInputError with a one-line message, never a crash, a
// hang or another exception. The seed bags must still read, to the same table both ways; the
// crafted_* corruptions must be refused on the rosbag path.
#include <dirent.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "../support/source_dir.h"
#include "accel_intrinsics/ros/bag_input.h"

namespace ai = accel_intrinsics;

namespace {

std::vector<std::string> corpus_files() {
  const std::string dir = accel_intrinsics::test_support::source_dir() + "/fuzz/corpus/bag_input";
  std::vector<std::string> files;
  DIR* handle = opendir(dir.c_str());
  if (handle == nullptr) return files;
  while (dirent* entry = readdir(handle)) {
    if (entry->d_name[0] != '.') files.push_back(dir + "/" + entry->d_name);
  }
  closedir(handle);
  std::sort(files.begin(), files.end());
  return files;
}

// Hand-made corruptions of a seed that rosbag itself mishandled before the structure check
// (an index offset past its chunk: a read outside rosbag's buffer, SIGSEGV; header or chunk
// lengths of gigabytes: allocations of that size). Through rosbag they must be refused.
bool is_crafted(const std::string& path) {
  return path.substr(path.rfind('/') + 1).rfind("crafted_", 0) == 0;
}

bool is_seed(const std::string& path) {
  const std::string name = path.substr(path.rfind('/') + 1);
  return name.rfind("run_", 0) == 0 && name != "run_truncated.bag";
}

}  // namespace

TEST(BagFuzzRegression, CorpusReadsCleanlyOrFailsWithOneLine) {
  const std::vector<std::string> files = corpus_files();
  ASSERT_GE(files.size(), 5u) << accel_intrinsics::test_support::source_dir()
                              << "/fuzz/corpus/bag_input";
  int results = 0, errors = 0;
  for (const std::string& path : files) {
    std::vector<std::size_t> rows;
    for (bool allow_chunk_scan : {true, false}) {
      ai::BagInputOptions options;
      options.allow_chunk_scan = allow_chunk_scan;
      try {
        const ai::BagRun run = ai::read_bag(path, options);
        rows.push_back(run.table.rows.size());
        for (const auto& row : run.table.rows) EXPECT_GT(row.n, 0u) << path;
        ++results;
      } catch (const ai::BagInputError& e) {
        const std::string message = e.what();
        EXPECT_FALSE(message.empty()) << path;
        EXPECT_EQ(message.find('\n'), std::string::npos) << path << ": " << message;
        EXPECT_NE(message.find(path), std::string::npos)
            << "the message names the file: " << message;
        EXPECT_FALSE(is_seed(path)) << path << ": " << message;
        ++errors;
      } catch (const std::exception& e) {
        ADD_FAILURE() << path << ": escaped " << typeid(e).name() << ": " << e.what();
      }
    }
    if (is_crafted(path)) {
      ai::BagInputOptions options;
      options.allow_chunk_scan = false;
      try {
        ai::read_bag(path, options);
        ADD_FAILURE() << path << ": read through rosbag";
      } catch (const ai::BagInputError& e) {
        EXPECT_NE(std::string(e.what()).find("corrupt bag"), std::string::npos) << e.what();
      }
    }
    if (is_seed(path)) {
      ASSERT_EQ(rows.size(), 2u) << path;
      EXPECT_EQ(rows[0], 3u) << path;
      EXPECT_EQ(rows[0], rows[1]) << path;
    }
  }
  EXPECT_GE(results, 8);  // the four readable seeds, both ways
  EXPECT_GE(errors, 2);   // at least the truncated seed, both ways
}
