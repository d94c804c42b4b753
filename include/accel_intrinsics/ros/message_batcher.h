// Hands messages from the thread that receives them to a thread of its own, in batches.
//
// Why: at 50 kHz roscpp's per-message hand-off between two threads (a callback-queue entry,
// locks and reference counts both threads touch, memory freed in the other thread) costs more
// than the calibration node's own work on a sample. Here the receiving thread only appends the
// pointer to a vector; the batch thread swaps the vector once per nap, hands the whole batch to
// its handler (which takes the node's lock once) and releases the messages itself.
#pragma once

#include <boost/shared_ptr.hpp>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace accel_intrinsics {

template <typename Message>
class MessageBatcher {
 public:
  using Ptr = boost::shared_ptr<const Message>;
  using Handler = std::function<void(const std::vector<Ptr>&)>;

  // capacity: messages held at most (as a full subscriber queue: a stalled handler does not
  // grow memory forever); nap_s: the pause after each batch, so the next ones pile up (one
  // wake-up per nap_s at most). Starts its thread.
  MessageBatcher(std::size_t capacity, double nap_s, Handler handler)
      : capacity_(capacity), nap_(nap_s), handler_(std::move(handler)) {
    thread_ = std::thread(&MessageBatcher::serve, this);
  }
  ~MessageBatcher() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      serving_ = false;
    }
    wake_.notify_all();
    thread_.join();
  }
  MessageBatcher(const MessageBatcher&) = delete;
  MessageBatcher& operator=(const MessageBatcher&) = delete;

  // From the receiving thread. False when the batch is full and the message was dropped.
  bool push(const Ptr& msg) {
    bool wake = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (pending_.size() >= capacity_) return false;
      pending_.push_back(msg);
      wake = idle_ && pending_.size() == 1;
    }
    if (wake) wake_.notify_one();
    return true;
  }
  std::size_t capacity() const { return capacity_; }

 private:
  void serve() {
    std::vector<Ptr> batch;
    std::unique_lock<std::mutex> lock(mutex_);
    while (serving_) {
      if (pending_.empty()) {  // an idle spell: wait for its first message
        idle_ = true;
        wake_.wait(lock, [this] { return !pending_.empty() || !serving_; });
        idle_ = false;
      }
      batch.swap(pending_);  // the receiver appends to the emptied vector's capacity
      lock.unlock();
      if (!batch.empty()) handler_(batch);
      batch.clear();  // the messages are released here, not in the receiving thread
      std::this_thread::sleep_for(nap_);
      lock.lock();
    }
  }

  const std::size_t capacity_;
  const std::chrono::duration<double> nap_;
  const Handler handler_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::vector<Ptr> pending_;
  bool idle_ = false;    // serve() waits for a first message
  bool serving_ = true;  // under mutex_
  std::thread thread_;   // last: starts after every member above is built
};

}  // namespace accel_intrinsics
