// Files that appear whole or not at all: written to "<path>.tmp.<pid>" and renamed into place,
// so a reader (or a node restarted after SIGKILL) never sees half a file. The one helper for
// every writer in the package.
#pragma once

#include <fstream>
#include <stdexcept>
#include <string>

namespace accel_intrinsics {
namespace io {

// A file that could not be read or written; the message names the path.
class IoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Writes `text` to `path` atomically. Throws IoError naming the path.
void write_file_atomically(const std::string& path, const std::string& text);

// Streaming form: write into stream(), then commit(). Destroyed without commit() (an exception
// on the way), the temporary file is removed and `path` keeps its old content. Several files can
// be prepared and then committed together (all or nothing, as far as a rename allows).
class AtomicFile {
 public:
  explicit AtomicFile(std::string path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ostream& stream() { return stream_; }
  // Closes the temporary file; throws IoError when anything failed to write (disk full).
  void close();
  // close() if needed, then rename into place; throws IoError.
  void commit();
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::string temp_;
  std::ofstream stream_;
  bool closed_ = false;
  bool committed_ = false;
};

}  // namespace io
}  // namespace accel_intrinsics
