// A callback queue that runs each callback at once, in the thread that adds it (roscpp's
// network thread). For the IMU stream it saves the queue hand-off and the wake-up of the spinner
// thread per message, which dominate the calibration node's CPU use at 10 kHz.
#pragma once

#include <ros/callback_queue_interface.h>

#include <chrono>
#include <functional>

namespace accel_intrinsics {

class ImmediateCallbackQueue : public ros::CallbackQueueInterface {
 public:
  void addCallback(const ros::CallbackInterfacePtr& callback, uint64_t owner_id = 0) override;
  void removeByID(uint64_t owner_id) override;
  // Coalesce network wake-ups: when a message arrives after the thread was idle, nap for this
  // long so that the following messages pile up in the socket and are read in one go. 0: off.
  void set_coalesce_period(double seconds) { coalesce_s_ = seconds; }
  // Called in that thread when a message wakes it from idle, before the nap: the messages handled
  // since the previous wake-up form a complete batch (the apply node sends its output then).
  void set_on_wake(std::function<void()> on_wake) { on_wake_ = std::move(on_wake); }

 private:
  double coalesce_s_ = 0.0;
  std::function<void()> on_wake_;
  std::chrono::steady_clock::time_point last_return_{};
};

}  // namespace accel_intrinsics
