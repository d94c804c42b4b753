// The parameters of a gimbal driver as its options reader sees them (docs/design.md section 15):
// a ROS-free view of the controller's private parameters, so that a row of the driver table
// (gimbal_driver_table.h) reads its own ~<driver>/... keys without the ROS layer knowing them.
// The gimbal controller implements it over its NodeHandle (ros/ros_driver_params.h); a test can
// implement it over a map.
#pragma once

#include <string>
#include <vector>

#include "accel_intrinsics/core/model/effects.h"

namespace accel_intrinsics {

class DriverParams {
 public:
  virtual ~DriverParams() = default;
  // The full name of a key for messages ("/gimbal_controller/ros_joint/tolerance_deg").
  virtual std::string name(const std::string& key) const = 0;
  virtual bool has(const std::string& key) const = 0;
  // Each get() leaves *value alone and returns false when the key is absent; a value of the
  // wrong type throws std::invalid_argument naming the key. A double accepts an integer; a
  // string accepts an integer (an SMC100 address).
  virtual bool get(const std::string& key, double* value) const = 0;
  virtual bool get(const std::string& key, int* value) const = 0;
  virtual bool get(const std::string& key, bool* value) const = 0;
  virtual bool get(const std::string& key, std::string* value) const = 0;
  // The keys of a map ({X: ..., Y: ...}); empty when absent; throws when not a map.
  virtual std::vector<std::string> keys(const std::string& key) const = 0;
  // A list of effects in the format of the simulated gimbal's ~simulated/effects.
  virtual bool get_effects(const std::string& key, std::vector<core::Effect>* effects) const = 0;
};

}  // namespace accel_intrinsics
