#include "accel_intrinsics/io/budget_file.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <limits>
#include <stdexcept>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "json_documents.h"

namespace accel_intrinsics {
namespace io {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw IoError("uncertainty budget '" + path + "': " + what);
}

double number(const std::string& path, const YAML::Node& node, const std::string& key) {
  try {
    const double v = node.as<double>();
    if (!std::isfinite(v)) fail(path, key + " is not a finite number");
    return v;
  } catch (const YAML::Exception&) {
    fail(path, key + " is not a number");
  }
}

nlohmann::json num(double v) {
  if (!std::isfinite(v)) return nullptr;
  return v;
}

nlohmann::json triple(const Eigen::Vector3d& v, const char* const names[3], double scale = 1.0) {
  nlohmann::json out = nlohmann::json::object();
  for (int i = 0; i < 3; ++i) out[names[i]] = num(scale * v(i));
  return out;
}

const char* const kAccelerometers[3] = {"u", "v", "w"};
const char* const kAngles[3] = {"uv", "vw", "wu"};
const double kDeg = 180.0 / core::kPi;

}  // namespace

BudgetFile read_budget_file(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    fail(path, "cannot read the file");
  } catch (const YAML::Exception& e) {
    fail(path, std::string("cannot parse: ") + e.what());
  }
  BudgetFile out;
  out.path = path;
  if (root.IsNull()) return out;  // an empty file: all sources 0
  if (!root.IsMap()) fail(path, "not a map of keys");
  core::BudgetSpec& s = out.spec;
  for (auto it = root.begin(); it != root.end(); ++it) {
    const std::string key = it->first.as<std::string>("");
    const YAML::Node& value = it->second;
    if (key == "gravity_std_rel") {
      s.gravity_std_rel = number(path, value, key);
    } else if (key == "angle_random_std_deg") {
      s.angle_random_std_deg = number(path, value, key);
    } else if (key == "angle_offset_std_deg") {
      s.angle_offset_std_deg = number(path, value, key);
    } else if (key == "angle_scale_std") {
      s.angle_scale_std = number(path, value, key);
    } else if (key == "axis_tilt_std_deg") {
      s.axis_tilt_std_deg = number(path, value, key);
    } else if (key == "mount_misalignment_std_deg") {
      s.mount_misalignment_std_deg = number(path, value, key);
    } else if (key == "samples") {
      const double v = number(path, value, key);
      if (v != std::floor(v) || v < 0 || v > 1e9) fail(path, "samples must be a whole number");
      s.samples = static_cast<int>(v);
    } else if (key == "seed") {
      const double v = number(path, value, key);
      if (v != std::floor(v) || v < 0 || v > 9e15) fail(path, "seed must be a whole number >= 0");
      s.seed = static_cast<std::uint64_t>(v);
    } else if (key == "certificate") {
      if (value.IsNull()) continue;
      if (!value.IsMap()) fail(path, "certificate must be a map of fields (lab: ..., device: ...)");
      for (auto f = value.begin(); f != value.end(); ++f) {
        const std::string field = f->first.as<std::string>("");
        if (!f->second.IsScalar() && !f->second.IsNull())
          fail(path, "certificate." + field + " must be a single value");
        out.certificate.emplace_back(field, f->second.IsNull() ? "" : f->second.as<std::string>());
      }
    } else {
      fail(path, "unknown key '" + key +
                     "' (expected gravity_std_rel, angle_random_std_deg, angle_offset_std_deg, "
                     "angle_scale_std, axis_tilt_std_deg, mount_misalignment_std_deg, samples, "
                     "seed, certificate)");
    }
  }
  try {
    core::validate(s);
  } catch (const std::invalid_argument& e) {
    fail(path, e.what());
  }
  return out;
}

namespace detail {

nlohmann::json budget_json(const core::UncertaintyBudget& b) {
  auto block = [](const core::IntrinsicValues& v, const char* resp, const char* ang,
                  const char* off, nlohmann::json* out) {
    (*out)[resp] = triple(v.responsivity, kAccelerometers);
    (*out)[ang] = triple(v.angles_rad, kAngles, kDeg);
    (*out)[off] = triple(v.offset, kAccelerometers);
  };
  nlohmann::json sources = nlohmann::json::array();
  for (const core::BudgetSource& s : b.sources) {
    nlohmann::json j = {{"name", s.name}, {"input", num(s.input)}};
    block(s.std, "responsivity_std", "angles_std_deg", "offset_std", &j);
    nlohmann::json shift = nlohmann::json::object();
    block(s.mean_shift, "responsivity", "angles_deg", "offset", &shift);
    j["mean_shift"] = shift;
    sources.push_back(j);
  }
  nlohmann::json combined = nlohmann::json::object();
  block(b.combined, "responsivity", "angles_deg", "offset", &combined);
  nlohmann::json expanded = {{"k", b.coverage_factor}};
  block(b.expanded, "responsivity", "angles_deg", "offset", &expanded);
  return {{"sources", sources},        {"combined_std", combined}, {"expanded", expanded},
          {"samples", b.spec.samples}, {"seed", b.spec.seed},      {"method", b.method}};
}

}  // namespace detail
}  // namespace io
}  // namespace accel_intrinsics
