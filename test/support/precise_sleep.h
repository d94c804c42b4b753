// Device programs in tests (a serial device writing lines on its own clock) sleep to absolute
// deadlines with a fine timer slack: a writer preempted between reading the clock and sleeping
// still wakes on time, and Linux does not delay its wake-ups (by up to 50 us by default) to
// group them with others'.
#pragma once

#include <sys/prctl.h>
#include <time.h>

#include <cerrno>
#include <cmath>

namespace accel_intrinsics {
namespace precise_sleep {

// While alive, the calling thread's timer slack is 1 ns; the previous slack is restored after.
class PreciseWakeUps {
 public:
  PreciseWakeUps() : before_(::prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0)) {
    ::prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);
  }
  ~PreciseWakeUps() {
    if (before_ > 0) ::prctl(PR_SET_TIMERSLACK, static_cast<unsigned long>(before_), 0, 0, 0);
  }
  PreciseWakeUps(const PreciseWakeUps&) = delete;
  PreciseWakeUps& operator=(const PreciseWakeUps&) = delete;

 private:
  int before_;
};

// Sleeps until `clock` reads t_s seconds (a deadline, not a duration); at once if it has passed.
inline void sleep_until(clockid_t clock, double t_s) {
  timespec deadline{};
  const double whole = std::floor(t_s);
  deadline.tv_sec = static_cast<time_t>(whole);
  deadline.tv_nsec = static_cast<long>((t_s - whole) * 1e9);
  if (deadline.tv_nsec >= 1000000000L) {  // rounding up to the next second
    deadline.tv_nsec -= 1000000000L;
    ++deadline.tv_sec;
  }
  while (::clock_nanosleep(clock, TIMER_ABSTIME, &deadline, nullptr) == EINTR) {
  }
}

}  // namespace precise_sleep
}  // namespace accel_intrinsics
