#include "accel_intrinsics/io/run_directory.h"

#include <unistd.h>

#include <cmath>
#include <ctime>
#include <filesystem>
#include <system_error>

#include "accel_intrinsics/io/atomic_file.h"

namespace accel_intrinsics {
namespace io {
namespace {

namespace fs = std::filesystem;

std::string format_utc(double unix_s, const char* format) {
  const std::time_t t = static_cast<std::time_t>(std::floor(unix_s));
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buffer[32];
  const std::size_t n = std::strftime(buffer, sizeof(buffer), format, &tm);
  return std::string(buffer, n);
}

}  // namespace

std::string utc_basic_time(double unix_s) {
  return format_utc(unix_s, "%Y%m%dT%H%M%SZ");
}

std::string utc_iso_time(double unix_s) {
  return format_utc(unix_s, "%Y-%m-%dT%H:%M:%SZ");
}

std::string device_directory_name(const std::string& serial) {
  std::string name;
  for (char c : serial) {
    const bool keep = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                      c == '-' || c == '_' || c == '.' || c == '+';
    name += keep ? c : '_';
  }
  if (name.empty() || name == "." || name == "..") return kUnnamedDevice;
  return name;
}

std::string RunDirectories::device_dir(const std::string& serial) const {
  if (!enabled()) return "";
  return (fs::path(base_) / device_directory_name(serial)).string();
}

std::string RunDirectories::latest_link(const std::string& serial) const {
  if (!enabled()) return "";
  return (fs::path(device_dir(serial)) / "latest").string();
}

std::string RunDirectories::start_run(const std::string& serial, double unix_s) const {
  if (!enabled()) return "";
  const fs::path device = device_dir(serial);
  std::error_code ec;
  fs::create_directories(device, ec);
  if (ec) throw IoError("cannot create directory '" + device.string() + "': " + ec.message());
  const std::string stamp = utc_basic_time(unix_s);
  fs::path run;
  for (int n = 1;; ++n) {
    run = device / (n == 1 ? stamp : stamp + "-" + std::to_string(n));
    // create_directory is false (no error) when it exists: an earlier run is never reused.
    if (fs::create_directory(run, ec)) break;
    if (ec) throw IoError("cannot create directory '" + run.string() + "': " + ec.message());
    if (n > 1000) throw IoError("cannot find a free run directory beside '" + run.string() + "'");
  }
  // `latest`: a new link beside it, renamed over the old one (rename(2) is atomic).
  const fs::path link = latest_link(serial);
  const fs::path temporary = device / (".latest.tmp." + std::to_string(::getpid()));
  fs::remove(temporary, ec);
  fs::create_directory_symlink(run.filename(), temporary, ec);
  if (!ec) fs::rename(temporary, link, ec);
  if (ec) {
    fs::remove(temporary, ec);
    throw IoError("cannot point '" + link.string() + "' at '" + run.string() + "'");
  }
  return run.string();
}

std::string RunDirectories::latest_run(const std::string& serial) const {
  if (!enabled()) return "";
  const fs::path link = latest_link(serial);
  std::error_code ec;
  if (!fs::is_symlink(fs::symlink_status(link, ec))) return "";
  const fs::path target = fs::read_symlink(link, ec);
  if (ec) return "";
  const fs::path run = target.is_absolute() ? target : fs::path(device_dir(serial)) / target;
  return fs::is_directory(run, ec) ? run.string() : "";
}

}  // namespace io
}  // namespace accel_intrinsics
