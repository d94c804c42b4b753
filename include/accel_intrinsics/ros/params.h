// Reading node parameters into options structs: once, typed, and with errors that name the
// parameter. A parameter of the wrong type is an error, never silently replaced by its default.
#pragma once

#include <ros/node_handle.h>

#include <Eigen/Core>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "accel_intrinsics/core/model/effects.h"
#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {

// Thrown for a missing, mistyped or invalid parameter; what() names the parameter.
class ParamError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Fully resolved name of `name` under `nh`, for messages ("/rig1/calibration/local_gravity").
inline std::string param_name(const ros::NodeHandle& nh, const std::string& name) {
  return nh.resolveName(name);
}

// Reads `name` into *value when present (leaving the default otherwise); throws ParamError when
// it is present with the wrong type. Returns true when the parameter was set.
template <typename T>
bool read_param(const ros::NodeHandle& nh, const std::string& name, T* value) {
  if (!nh.hasParam(name)) return false;
  T read{};
  if (!nh.getParam(name, read)) {
    throw ParamError("parameter " + param_name(nh, name) + " has the wrong type");
  }
  *value = read;
  return true;
}

// Same, for unsigned integers (the parameter server stores int).
inline bool read_param(const ros::NodeHandle& nh, const std::string& name, std::uint32_t* value) {
  int read = 0;
  if (!read_param(nh, name, &read)) return false;
  if (read < 0) {
    throw ParamError("parameter " + param_name(nh, name) + " must not be negative (got " +
                     std::to_string(read) + ")");
  }
  *value = static_cast<std::uint32_t>(read);
  return true;
}

// Throws ParamError naming the parameter unless `ok`.
inline void require(bool ok, const ros::NodeHandle& nh, const std::string& name,
                    const std::string& what) {
  if (!ok) throw ParamError("parameter " + param_name(nh, name) + ": " + what);
}

// A 3x3 matrix given as a list of 9 numbers, row-major (S: u then v then w).
bool read_matrix3(const ros::NodeHandle& nh, const std::string& name, Eigen::Matrix3d* value);
// A 3-vector given as a list of 3 numbers.
bool read_vector3(const ros::NodeHandle& nh, const std::string& name, Eigen::Vector3d* value);
// Effect terms: a list of {name: quadratic_nonlinearity, target: u, value: 1.0e-4}
// (docs/design.md section 3). Throws ParamError naming the entry ("effects[1].target").
bool read_effects(const ros::NodeHandle& nh, const std::string& name,
                  std::vector<core::Effect>* value);
// The protocol (steps, move_s, settle_s, dwell_s, phase_change_s, two_way, closing_position),
// validated.
core::ProtocolOptions read_protocol(const ros::NodeHandle& nh);

}  // namespace accel_intrinsics
