// apply_calibration as a nodelet (accel_intrinsics/ApplyCalibrationNodelet): the same node class,
// in a nodelet manager beside the IMU driver and the orientation filter, where messages pass by
// pointer (no serialization, no sockets). Parameters as the node's (apply_calibration_node.h).
#include <nodelet/nodelet.h>

#include <memory>
#include <pluginlib/class_list_macros.hpp>

#include "accel_intrinsics/ros/apply_calibration_node.h"
#include "accel_intrinsics/ros/params.h"

namespace accel_intrinsics {

class ApplyCalibrationNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    try {
      io::ApplyCalibration calibration;
      ApplyCalibrationOptions options =
          ApplyCalibrationOptions::load(getPrivateNodeHandle(), &calibration);
      // In a manager the publisher's thread may be a driver's: unless asked otherwise, messages
      // go to the nodelet's own queue and thread (which naps coalesce_s to handle them in
      // batches; coalesce_s 0: the manager's queue), never napping in someone else's thread
      // unless `immediate` is set.
      if (!getPrivateNodeHandle().hasParam("immediate")) options.immediate = false;
      // In a manager the subscribers are in process: every message goes out on its own.
      options.batch_output = false;
      node_.reset(new ApplyCalibrationNode(getNodeHandle(), options, calibration));
    } catch (const ParamError& e) {
      NODELET_FATAL("apply_calibration: refusing to start: %s", e.what());
      throw;
    }
  }

  std::unique_ptr<ApplyCalibrationNode> node_;
};

}  // namespace accel_intrinsics

PLUGINLIB_EXPORT_CLASS(accel_intrinsics::ApplyCalibrationNodelet, nodelet::Nodelet)
