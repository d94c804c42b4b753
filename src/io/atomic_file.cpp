#include "accel_intrinsics/io/atomic_file.h"

#include <unistd.h>

#include <cstdio>

namespace accel_intrinsics {
namespace io {

AtomicFile::AtomicFile(std::string path)
    : path_(std::move(path)), temp_(path_ + ".tmp." + std::to_string(::getpid())) {
  stream_.open(temp_, std::ios::out | std::ios::trunc | std::ios::binary);
  if (!stream_) throw IoError("cannot write '" + path_ + "' (cannot create " + temp_ + ")");
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    if (stream_.is_open()) stream_.close();
    std::remove(temp_.c_str());
  }
}

void AtomicFile::close() {
  if (closed_) return;
  closed_ = true;
  stream_.close();
  if (stream_.fail()) throw IoError("cannot write '" + path_ + "' (disk full?)");
}

void AtomicFile::commit() {
  close();
  if (std::rename(temp_.c_str(), path_.c_str()) != 0) {
    throw IoError("cannot write '" + path_ + "' (rename of " + temp_ + " failed)");
  }
  committed_ = true;
}

void write_file_atomically(const std::string& path, const std::string& text) {
  AtomicFile file(path);
  file.stream() << text;
  file.commit();
}

}  // namespace io
}  // namespace accel_intrinsics
