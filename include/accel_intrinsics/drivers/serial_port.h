// A serial port (termios, raw 8N1, non-blocking) with line reads under a timeout, for the
// serial gimbal drivers. ROS-free. Works the same on a USB adapter and on a pseudo-terminal
// (the emulators in emulators.h), which is how the drivers are tested.
#pragma once

#include <stdexcept>
#include <string>

namespace accel_intrinsics {

// Any failure of the port itself: cannot open, lost (unplugged: EIO, hang-up), write failed.
// what() names the port and the system's words ("Input/output error").
class SerialError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Printable form of bytes received or sent: control characters and bytes above 0x7e as \xNN,
// so a fault message shows exactly what the device sent.
std::string printable(const std::string& bytes);

class SerialPort {
 public:
  SerialPort() = default;
  ~SerialPort();
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  // Opens `path` raw at `baud` (one of the standard rates 9600 ... 230400), 8N1, with XON/XOFF
  // software flow control both ways when `xon_xoff`. Throws SerialError.
  void open(const std::string& path, int baud, bool xon_xoff = false);
  void close();
  bool is_open() const { return fd_ >= 0; }
  const std::string& path() const { return path_; }

  // Writes all bytes (waits up to timeout_s for room). Throws SerialError.
  void write(const std::string& bytes, double timeout_s = 1.0);
  // The next line without its terminator ("\n", a preceding "\r" dropped), waiting up to
  // timeout_s (wall clock). False on timeout (a partial line stays buffered). Throws SerialError
  // when the port is lost.
  bool read_line(std::string* line, double timeout_s);
  // Waits up to timeout_s for input, then reads everything the driver holds (as many lines as
  // have come, in as few system calls as it takes). False when nothing came. Throws SerialError
  // when the port is lost. The lines are then taken with next_line().
  bool read_available(double timeout_s);
  // The next complete line already received (as read_line), without waiting or a system call;
  // false when no complete line is buffered. Reuses *line's storage.
  bool next_line(std::string* line);
  // Drops everything received so far (buffered and pending in the driver).
  void discard_input();

 private:
  // Reads what is available within timeout_s into buffer_; false on timeout.
  bool fill(double timeout_s);

  int fd_ = -1;
  std::string path_;
  std::string buffer_;
  std::size_t start_ = 0;  // buffer_[0, start_) was handed out already
};

}  // namespace accel_intrinsics
