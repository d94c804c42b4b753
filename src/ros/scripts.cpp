#include "accel_intrinsics/ros/scripts.h"

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>

namespace accel_intrinsics {

std::string package_script(const std::string& name) {
  auto exists = [](const std::string& path) {
    struct stat info;
    return ::stat(path.c_str(), &info) == 0;
  };
  if (const char* dir = std::getenv("ACCEL_INTRINSICS_SCRIPTS"))
    return std::string(dir) + "/" + name;
  char self[4096];
  const ssize_t n = ::readlink("/proc/self/exe", self, sizeof(self) - 1);
  if (n > 0) {
    self[n] = '\0';
    std::string dir(self);
    dir = dir.substr(0, dir.rfind('/'));
    if (exists(dir + "/" + name)) return dir + "/" + name;
  }
  return std::string(ACCEL_INTRINSICS_SOURCE_DIR) + "/scripts/" + name;
}

int run_package_script(const std::string& name, const std::vector<std::string>& args) {
  const std::string script = package_script(name);
  std::vector<const char*> argv = {"/usr/bin/python3", script.c_str()};
  for (const std::string& a : args) argv.push_back(a.c_str());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    ::execv(argv[0], const_cast<char* const*>(argv.data()));
    ::_exit(127);
  }
  int status = 0;
  if (::waitpid(pid, &status, 0) != pid || !WIFEXITED(status)) return -1;
  return WEXITSTATUS(status);
}

}  // namespace accel_intrinsics
