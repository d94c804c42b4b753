// Scaffolding shared by the tests that write files: a temporary directory removed when the test
// ends (kept when KEEP_TEST_FILES is set, to look at what a failing test wrote) and a reader.
#pragma once

#include <stdlib.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>

namespace accel_intrinsics {
namespace test_support {

class TempDir {
 public:
  explicit TempDir(const std::string& prefix = "accel_intrinsics_test") {
    std::string templ = "/tmp/" + prefix + "_XXXXXX";
    if (::mkdtemp(templ.data()) == nullptr) throw std::runtime_error("mkdtemp failed for " + templ);
    path_ = templ;
  }
  ~TempDir() {
    if (std::getenv("KEEP_TEST_FILES") == nullptr) {
      std::error_code ignored;
      std::filesystem::remove_all(path_, ignored);
    }
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::string& path() const { return path_; }
  std::string file(const std::string& name) const { return path_ + "/" + name; }
  // The names of the files in the directory (to check that a tool wrote all or nothing).
  std::set<std::string> entries() const {
    std::set<std::string> names;
    for (const auto& entry : std::filesystem::directory_iterator(path_)) {
      names.insert(entry.path().filename().string());
    }
    return names;
  }

 private:
  std::string path_;
};

// The whole file as bytes; empty when it cannot be opened (the test's assertions then fail).
inline std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace test_support
}  // namespace accel_intrinsics
