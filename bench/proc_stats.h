// /proc readers for the live load benchmarks (calibration_node_load, apply_calibration_load):
// CPU time of a process or of one of its threads, resident memory. Linux only; resolution one
// clock tick (10 ms), so measure over seconds.
#pragma once

#include <sys/syscall.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

namespace bench {

// utime + stime in seconds from a /proc/.../stat file; -1 when it cannot be read (gone).
inline double stat_cpu_seconds(const std::string& stat_path) {
  std::ifstream in(stat_path);
  std::string line;
  if (!std::getline(in, line) || line.rfind(')') == std::string::npos) return -1.0;
  // Fields after the command name (which is in parentheses and may hold spaces).
  std::istringstream s(line.substr(line.rfind(')') + 2));
  std::string field;
  unsigned long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && s >> field; ++i) {
    if (i == 14) utime = std::stoul(field);
    if (i == 15) stime = std::stoul(field);
  }
  return static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

// CPU seconds of process `pid`, all its threads.
inline double cpu_seconds(int pid) {
  return stat_cpu_seconds("/proc/" + std::to_string(pid) + "/stat");
}

// CPU seconds of thread `tid` of this process.
inline double thread_cpu_seconds(long tid) {
  return stat_cpu_seconds("/proc/self/task/" + std::to_string(tid) + "/stat");
}

inline long current_thread_id() {
  return static_cast<long>(syscall(SYS_gettid));
}

// VmRSS of process `pid` in kB; -1 when it cannot be read.
inline long rss_kb(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::atol(line.c_str() + 6);
  }
  return -1;
}

}  // namespace bench
