// calibration as a nodelet (accel_intrinsics/CalibrationNodelet): the same node classes as the
// calibration node (mode: gimbal, CalibrationNode; mode: tumble, TumbleCalibrationNode), in the
// IMU driver's nodelet manager, where the IMU messages pass by pointer (no serialization, no
// sockets). Parameters as the node's (config/calibration.yaml).
#include <nodelet/nodelet.h>

#include <memory>
#include <pluginlib/class_list_macros.hpp>
#include <string>

#include "accel_intrinsics/ros/calibration_node.h"
#include "accel_intrinsics/ros/params.h"
#include "accel_intrinsics/ros/tumble_calibration_node.h"

namespace accel_intrinsics {

class CalibrationNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    try {
      const std::string mode = pnh.param<std::string>("mode", "gimbal");
      if (mode == "tumble") {
        tumble_.reset(
            new TumbleCalibrationNode(getNodeHandle(), pnh, TumbleNodeOptions::load(pnh)));
        return;
      }
      if (mode != "gimbal") throw ParamError("parameter ~mode: '" + mode + "' (gimbal or tumble)");
      CalibrationOptions options = CalibrationOptions::load(pnh);
      // In a manager the IMU publisher's thread is the driver's: unless asked otherwise, that
      // thread only appends each message's pointer to the node's batch, and the node's own thread
      // handles every imu_batch_s what came meanwhile (one wake-up per period).
      if (!pnh.hasParam("immediate_imu")) options.immediate_imu = false;
      node_.reset(new CalibrationNode(getNodeHandle(), pnh, options));
    } catch (const ParamError& e) {
      NODELET_FATAL("calibration: refusing to start: %s", e.what());
      throw;
    }
  }

  std::unique_ptr<CalibrationNode> node_;
  std::unique_ptr<TumbleCalibrationNode> tumble_;
};

}  // namespace accel_intrinsics

PLUGINLIB_EXPORT_CLASS(accel_intrinsics::CalibrationNodelet, nodelet::Nodelet)
