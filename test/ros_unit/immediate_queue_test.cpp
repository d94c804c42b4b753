// The calibration node's ImmediateCallbackQueue: with wake-up coalescing on, every IMU callback
// still runs exactly once, in the order roscpp hands them over, in the adding thread. No roscore.
#include <gtest/gtest.h>
#include <ros/callback_queue_interface.h>

#include <boost/make_shared.hpp>
#include <memory>
#include <thread>
#include <vector>

#include "accel_intrinsics/ros/immediate_callback_queue.h"

namespace {

class RecordingCallback : public ros::CallbackInterface {
 public:
  RecordingCallback(int id, std::vector<int>* calls, std::thread::id* thread)
      : id_(id), calls_(calls), thread_(thread) {}
  CallResult call() override {
    calls_->push_back(id_);
    *thread_ = std::this_thread::get_id();
    return Success;
  }

 private:
  int id_;
  std::vector<int>* calls_;
  std::thread::id* thread_;
};

}  // namespace

TEST(ImmediateCallbackQueue, CoalescingRunsEveryCallbackOnceInOrder) {
  for (double coalesce_s : {0.0, 0.0005}) {
    accel_intrinsics::ImmediateCallbackQueue queue;
    queue.set_coalesce_period(coalesce_s);
    std::vector<int> calls;
    std::thread::id thread;
    for (int i = 0; i < 200; ++i) {
      queue.addCallback(boost::make_shared<RecordingCallback>(i, &calls, &thread));
      if (i % 50 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));  // idle gaps
    }
    ASSERT_EQ(calls.size(), 200u) << "coalesce " << coalesce_s;
    for (int i = 0; i < 200; ++i) EXPECT_EQ(calls[i], i);
    EXPECT_EQ(thread, std::this_thread::get_id());
  }
}
