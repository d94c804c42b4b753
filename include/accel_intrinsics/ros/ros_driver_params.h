// DriverParams (drivers/driver_params.h) over a NodeHandle: the gimbal controller's private
// parameters as the gimbal driver table's options readers see them.
#pragma once

#include <ros/ros.h>

#include <string>
#include <vector>

#include "accel_intrinsics/drivers/driver_params.h"

namespace accel_intrinsics {

class RosDriverParams : public DriverParams {
 public:
  explicit RosDriverParams(const ros::NodeHandle& pnh) : pnh_(pnh) {}

  std::string name(const std::string& key) const override;
  bool has(const std::string& key) const override;
  bool get(const std::string& key, double* value) const override;
  bool get(const std::string& key, int* value) const override;
  bool get(const std::string& key, bool* value) const override;
  bool get(const std::string& key, std::string* value) const override;
  std::vector<std::string> keys(const std::string& key) const override;
  bool get_effects(const std::string& key, std::vector<core::Effect>* effects) const override;

 private:
  ros::NodeHandle pnh_;
};

}  // namespace accel_intrinsics
