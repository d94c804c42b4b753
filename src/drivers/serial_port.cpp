// Serial port over termios: raw mode, non-blocking descriptor, poll() for timeouts.
#include "accel_intrinsics/drivers/serial_port.h"

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>

namespace accel_intrinsics {

namespace {

using Clock = std::chrono::steady_clock;

// Bytes per read(): several milliseconds of lines at 1 kHz in one call.
constexpr std::size_t kChunk = 4096;

speed_t baud_constant(int baud) {
  switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    default: return B0;
  }
}

std::string system_error(int err) {
  return std::strerror(err);
}

int remaining_ms(Clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
  return left.count() < 0 ? 0 : static_cast<int>(left.count());
}

Clock::time_point deadline_after(double timeout_s) {
  return Clock::now() + std::chrono::microseconds(static_cast<long long>(timeout_s * 1e6));
}

}  // namespace

std::string printable(const std::string& bytes) {
  std::string out;
  for (const char c : bytes) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u <= 0x7e) {
      out += c;
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", u);
      out += hex;
    }
  }
  return out;
}

SerialPort::~SerialPort() {
  close();
}

void SerialPort::open(const std::string& path, int baud, bool xon_xoff) {
  close();
  const speed_t speed = baud_constant(baud);
  if (speed == B0) {
    throw SerialError("serial port " + path + ": baud " + std::to_string(baud) +
                      " is not supported (use 9600, 19200, 38400, 57600, 115200 or 230400)");
  }
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    throw SerialError("serial port " + path + ": cannot open: " + system_error(errno));
  }
  termios tio{};
  if (tcgetattr(fd, &tio) != 0) {
    const int err = errno;
    ::close(fd);
    throw SerialError("serial port " + path + ": not a serial device: " + system_error(err));
  }
  cfmakeraw(&tio);
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cflag &= ~(CSTOPB | PARENB | CRTSCTS);
  if (xon_xoff) tio.c_iflag |= IXON | IXOFF;  // cfmakeraw clears them
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  cfsetispeed(&tio, speed);
  cfsetospeed(&tio, speed);
  if (tcsetattr(fd, TCSANOW, &tio) != 0) {
    const int err = errno;
    ::close(fd);
    throw SerialError("serial port " + path + ": cannot configure: " + system_error(err));
  }
  fd_ = fd;
  path_ = path;
  buffer_.clear();
  start_ = 0;
}

void SerialPort::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  buffer_.clear();
  start_ = 0;
}

void SerialPort::write(const std::string& bytes, double timeout_s) {
  if (fd_ < 0) throw SerialError("serial port " + path_ + " is not open");
  const Clock::time_point deadline = deadline_after(timeout_s);
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
      throw SerialError("serial port " + path_ + " lost: " + system_error(errno));
    }
    pollfd p{fd_, POLLOUT, 0};
    const int ready = ::poll(&p, 1, remaining_ms(deadline));
    if (ready == 0) throw SerialError("serial port " + path_ + ": write timed out");
    if (ready > 0 && (p.revents & (POLLERR | POLLHUP | POLLNVAL))) {
      throw SerialError("serial port " + path_ + " lost: hang-up");
    }
  }
}

bool SerialPort::fill(double timeout_s) {
  if (fd_ < 0) throw SerialError("serial port " + path_ + " is not open");
  const Clock::time_point deadline = deadline_after(timeout_s);
  for (;;) {
    char chunk[kChunk];
    const ssize_t n = ::read(fd_, chunk, sizeof chunk);
    if (n > 0) {
      buffer_.append(chunk, static_cast<std::size_t>(n));
      return true;
    }
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
      throw SerialError("serial port " + path_ + " lost: " + system_error(errno));
    }
    pollfd p{fd_, POLLIN, 0};
    const int wait = remaining_ms(deadline);
    const int ready = ::poll(&p, 1, wait);
    if (ready < 0 && errno != EINTR) {
      throw SerialError("serial port " + path_ + " lost: " + system_error(errno));
    }
    if (ready > 0 && !(p.revents & POLLIN) && (p.revents & (POLLERR | POLLHUP | POLLNVAL))) {
      throw SerialError("serial port " + path_ + " lost: hang-up (device gone)");
    }
    if (ready > 0 && (p.revents & POLLIN)) {
      const ssize_t m = ::read(fd_, chunk, sizeof chunk);
      if (m > 0) {
        buffer_.append(chunk, static_cast<std::size_t>(m));
        return true;
      }
      if (m == 0 || (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
        // Readable with nothing to read: end of file, the device is gone.
        throw SerialError("serial port " + path_ +
                          " lost: " + (m == 0 ? std::string("end of file") : system_error(errno)));
      }
    }
    if (wait == 0) return false;
  }
}

bool SerialPort::next_line(std::string* line) {
  const std::size_t nl = buffer_.find('\n', start_);
  if (nl == std::string::npos) {
    // Only a partial line left: move it to the front, once, before more bytes are appended.
    if (start_ > 0) {
      buffer_.erase(0, start_);
      start_ = 0;
    }
    return false;
  }
  std::size_t end = nl;
  if (end > start_ && buffer_[end - 1] == '\r') --end;
  line->assign(buffer_, start_, end - start_);
  start_ = nl + 1;
  if (start_ == buffer_.size()) {
    buffer_.clear();
    start_ = 0;
  }
  return true;
}

bool SerialPort::read_available(double timeout_s) {
  std::size_t before = buffer_.size();
  if (!fill(timeout_s)) return false;
  // A full chunk: the driver may hold more; read on without waiting.
  while (buffer_.size() - before == kChunk) {
    before = buffer_.size();
    if (!fill(0.0)) break;
  }
  return true;
}

bool SerialPort::read_line(std::string* line, double timeout_s) {
  const Clock::time_point deadline = deadline_after(timeout_s);
  for (;;) {
    if (next_line(line)) return true;
    const int left = remaining_ms(deadline);
    if (!fill(left / 1000.0)) {
      if (left == 0 || Clock::now() >= deadline) return false;
    }
  }
}

void SerialPort::discard_input() {
  if (fd_ < 0) return;
  buffer_.clear();
  start_ = 0;
  tcflush(fd_, TCIFLUSH);
  while (fill(0.0)) buffer_.clear();
}

}  // namespace accel_intrinsics
