// libFuzzer target for bag input (src/ros/bag_format.cpp, bag_topics.cpp, bag_input.cpp):
// arbitrary bytes, written to a temporary file, go through read_bag() twice: once with the
// memory-mapped chunk scan allowed (so the scanner's index parse, its "does this bag qualify"
// decision and, when it does not, the fallback to rosbag::Bag/View all run) and once forced through
// rosbag. The contract: either a result or a BagInputError with a one-line, non-empty message. Any
// other exception, a crash, a sanitizer report or a hang (libFuzzer -timeout) is a finding. Built
// and run by tools/fuzz.sh; crashing inputs go, minimized, into fuzz/corpus/bag_input/, which
// test/ros_unit/bag_fuzz_regression_test replays.
#include <fcntl.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "accel_intrinsics/ros/bag_input.h"

namespace ai = accel_intrinsics;

namespace {

// One temporary file per fuzzing process, rewritten for every input.
const std::string& input_path() {
  static const std::string path = [] {
    const char* dir = std::getenv("TMPDIR");
    std::string pattern = std::string(dir && *dir ? dir : "/tmp") + "/bag_input_fuzz_XXXXXX";
    const int fd = ::mkstemp(&pattern[0]);
    if (fd < 0) std::abort();
    ::close(fd);
    std::atexit([] { std::remove(input_path().c_str()); });
    return pattern;
  }();
  return path;
}

void write_input(const std::uint8_t* data, std::size_t size) {
  const int fd = ::open(input_path().c_str(), O_WRONLY | O_TRUNC);
  if (fd < 0) std::abort();
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n <= 0) std::abort();
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
}

void check_result(const ai::BagRun& run) {
  // A result is a table the assembler produced: its rows satisfy the table's invariants.
  for (const auto& row : run.table.rows) {
    if (row.n == 0) std::abort();
  }
  if (run.stats.reader != "chunk scan" && run.stats.reader != "rosbag::View") std::abort();
}

// BAG_FUZZ_VERBOSE=1: print each outcome (to see what a corpus file does).
const bool kVerbose = std::getenv("BAG_FUZZ_VERBOSE") != nullptr;

void read_once(bool allow_chunk_scan) {
  ai::BagInputOptions options;
  options.allow_chunk_scan = allow_chunk_scan;
  try {
    const ai::BagRun run = ai::read_bag(input_path(), options);
    check_result(run);
    if (kVerbose) {
      std::fprintf(stderr, "[%s] %s: %zu dwells, %llu IMU, %llu commands\n",
                   allow_chunk_scan ? "scan allowed" : "rosbag", run.stats.reader.c_str(),
                   run.table.rows.size(), static_cast<unsigned long long>(run.stats.imu_messages),
                   static_cast<unsigned long long>(run.stats.command_messages));
    }
  } catch (const ai::BagInputError& e) {
    const std::string message = e.what();
    if (kVerbose)
      std::fprintf(stderr, "[%s] error: %s\n", allow_chunk_scan ? "scan allowed" : "rosbag",
                   e.what());
    if (message.empty() || message.find('\n') != std::string::npos) {
      std::fprintf(stderr, "bad error message: '%s'\n", message.c_str());
      std::abort();
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "escaped exception (not BagInputError): %s\n", e.what());
    std::abort();
  } catch (...) {
    std::fprintf(stderr, "escaped non-std exception\n");
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  write_input(data, size);
  read_once(true);
  read_once(false);
  return 0;
}
