#include "accel_intrinsics/ros/immediate_callback_queue.h"

#include <thread>

namespace accel_intrinsics {

void ImmediateCallbackQueue::addCallback(const ros::CallbackInterfacePtr& callback, uint64_t) {
  if (coalesce_s_ > 0.0 || on_wake_) {
    // roscpp reads messages already waiting in the socket back to back (a few microseconds
    // apart); a longer gap since the previous callback returned means this thread has just been
    // woken from its poll by a fresh message. Then nap, so that the next messages pile up in
    // the socket and are read in one go: one wake-up per period instead of one per message.
    constexpr std::chrono::microseconds kIdleGap(20);
    const auto now = std::chrono::steady_clock::now();
    if (now - last_return_ > kIdleGap) {
      if (on_wake_) on_wake_();
      if (coalesce_s_ > 0.0)
        std::this_thread::sleep_for(std::chrono::duration<double>(coalesce_s_));
    }
  }
  // TryAgain only happens for callbacks that refuse concurrent calls; a subscription queue with
  // a single subscriber never does. Retry a few times to be safe, then leave it.
  for (int i = 0; i < 100; ++i) {
    if (callback->ready() && callback->call() != ros::CallbackInterface::TryAgain) break;
  }
  last_return_ = std::chrono::steady_clock::now();
}

void ImmediateCallbackQueue::removeByID(uint64_t) {}

}  // namespace accel_intrinsics
