// DriverParams over a NodeHandle (ros_driver_params.h).
#include "accel_intrinsics/ros/ros_driver_params.h"

#include <xmlrpcpp/XmlRpcValue.h>

#include <stdexcept>

#include "accel_intrinsics/ros/params.h"

namespace accel_intrinsics {

namespace {

using XmlRpc::XmlRpcValue;

std::invalid_argument wrong(const std::string& name, const std::string& what) {
  return std::invalid_argument("parameter " + name + " must be " + what);
}

}  // namespace

std::string RosDriverParams::name(const std::string& key) const {
  return param_name(pnh_, key);
}

bool RosDriverParams::has(const std::string& key) const {
  return pnh_.hasParam(key);
}

bool RosDriverParams::get(const std::string& key, double* value) const {
  XmlRpcValue v;
  if (!pnh_.getParam(key, v)) return false;
  if (v.getType() == XmlRpcValue::TypeDouble) {
    *value = static_cast<double>(v);
  } else if (v.getType() == XmlRpcValue::TypeInt) {
    *value = static_cast<int>(v);
  } else {
    throw wrong(name(key), "a number");
  }
  return true;
}

bool RosDriverParams::get(const std::string& key, int* value) const {
  XmlRpcValue v;
  if (!pnh_.getParam(key, v)) return false;
  if (v.getType() != XmlRpcValue::TypeInt) throw wrong(name(key), "an integer");
  *value = static_cast<int>(v);
  return true;
}

bool RosDriverParams::get(const std::string& key, bool* value) const {
  XmlRpcValue v;
  if (!pnh_.getParam(key, v)) return false;
  if (v.getType() != XmlRpcValue::TypeBoolean) throw wrong(name(key), "true or false");
  *value = static_cast<bool>(v);
  return true;
}

bool RosDriverParams::get(const std::string& key, std::string* value) const {
  XmlRpcValue v;
  if (!pnh_.getParam(key, v)) return false;
  if (v.getType() == XmlRpcValue::TypeString) {
    *value = static_cast<std::string>(v);
  } else if (v.getType() == XmlRpcValue::TypeInt) {
    *value = std::to_string(static_cast<int>(v));
  } else {
    throw wrong(name(key), "a string");
  }
  return true;
}

std::vector<std::string> RosDriverParams::keys(const std::string& key) const {
  std::vector<std::string> out;
  XmlRpcValue v;
  if (!pnh_.getParam(key, v)) return out;
  if (v.getType() != XmlRpcValue::TypeStruct) throw wrong(name(key), "a map ({key: value, ...})");
  for (auto it = v.begin(); it != v.end(); ++it) out.push_back(it->first);
  return out;
}

bool RosDriverParams::get_effects(const std::string& key,
                                  std::vector<core::Effect>* effects) const {
  return read_effects(pnh_, key, effects);
}

}  // namespace accel_intrinsics
