// Typed parameter reading with errors that name the parameter.
#include "accel_intrinsics/ros/params.h"

#include <xmlrpcpp/XmlRpcValue.h>

#include <cmath>
#include <stdexcept>

namespace accel_intrinsics {

namespace {

double number(const XmlRpc::XmlRpcValue& v, const std::string& what) {
  switch (v.getType()) {
    case XmlRpc::XmlRpcValue::TypeDouble: return static_cast<double>(v);
    case XmlRpc::XmlRpcValue::TypeInt: return static_cast<int>(v);
    default: throw ParamError("parameter " + what + " must be a number");
  }
}

bool read_list(const ros::NodeHandle& nh, const std::string& name, int size, double* out) {
  if (!nh.hasParam(name)) return false;
  XmlRpc::XmlRpcValue list;
  nh.getParam(name, list);
  const std::string full = param_name(nh, name);
  if (list.getType() != XmlRpc::XmlRpcValue::TypeArray || list.size() != size) {
    throw ParamError("parameter " + full + " must be a list of " + std::to_string(size) +
                     " numbers");
  }
  for (int i = 0; i < size; ++i) {
    out[i] = number(list[i], full + "[" + std::to_string(i) + "]");
    if (!std::isfinite(out[i])) {
      throw ParamError("parameter " + full + "[" + std::to_string(i) + "] is not finite");
    }
  }
  return true;
}

}  // namespace

bool read_matrix3(const ros::NodeHandle& nh, const std::string& name, Eigen::Matrix3d* value) {
  double v[9];
  if (!read_list(nh, name, 9, v)) return false;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) (*value)(r, c) = v[3 * r + c];
  return true;
}

bool read_vector3(const ros::NodeHandle& nh, const std::string& name, Eigen::Vector3d* value) {
  double v[3];
  if (!read_list(nh, name, 3, v)) return false;
  *value = Eigen::Vector3d(v[0], v[1], v[2]);
  return true;
}

bool read_effects(const ros::NodeHandle& nh, const std::string& name,
                  std::vector<core::Effect>* value) {
  if (!nh.hasParam(name)) return false;
  XmlRpc::XmlRpcValue list;
  nh.getParam(name, list);
  const std::string full = param_name(nh, name);
  if (list.getType() != XmlRpc::XmlRpcValue::TypeArray) {
    throw ParamError("parameter " + full +
                     " must be a list of {name: ..., target: ..., value: ...}");
  }
  std::vector<core::Effect> effects;
  for (int i = 0; i < list.size(); ++i) {
    const std::string entry = full + "[" + std::to_string(i) + "]";
    XmlRpc::XmlRpcValue& item = list[i];
    if (item.getType() != XmlRpc::XmlRpcValue::TypeStruct || !item.hasMember("name") ||
        !item.hasMember("target") || !item.hasMember("value")) {
      throw ParamError("parameter " + entry + " must be {name: ..., target: ..., value: ...}");
    }
    if (item["name"].getType() != XmlRpc::XmlRpcValue::TypeString ||
        item["target"].getType() != XmlRpc::XmlRpcValue::TypeString) {
      throw ParamError("parameter " + entry + ": name and target must be strings");
    }
    const double v = number(item["value"], entry + ".value");
    if (!std::isfinite(v)) throw ParamError("parameter " + entry + ".value is not finite");
    try {
      effects.push_back(core::make_effect(static_cast<std::string>(item["name"]),
                                          static_cast<std::string>(item["target"]), v));
    } catch (const std::invalid_argument& e) {
      throw ParamError("parameter " + entry + ": " + e.what());
    }
  }
  *value = effects;
  return true;
}

core::ProtocolOptions read_protocol(const ros::NodeHandle& nh) {
  core::ProtocolOptions p;
  read_param(nh, "steps", &p.steps_per_phase);
  read_param(nh, "move_s", &p.move_s);
  read_param(nh, "settle_s", &p.settle_s);
  read_param(nh, "dwell_s", &p.dwell_s);
  read_param(nh, "phase_change_s", &p.phase_change_s);
  read_param(nh, "two_way", &p.two_way);
  read_param(nh, "closing_position", &p.closing_position);
  read_param(nh, "initial_rest_s", &p.initial_rest_s);
  try {
    core::validate(p);
  } catch (const std::invalid_argument& e) {
    // The core says "protocol: FIELD must ..."; name the parameter instead of the field
    // (steps_per_phase is the parameter "steps").
    std::string text = e.what();
    const std::string prefix = "protocol: ";
    if (text.rfind(prefix, 0) == 0) text = text.substr(prefix.size());
    std::string field = text.substr(0, text.find(' '));
    if (field == "steps_per_phase") field = "steps";
    const std::string rest =
        text.find(' ') == std::string::npos ? text : text.substr(text.find(' ') + 1);
    throw ParamError("parameter " + param_name(nh, field) + ": " + rest);
  }
  return p;
}

}  // namespace accel_intrinsics
