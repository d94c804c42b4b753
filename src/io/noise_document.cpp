#include "accel_intrinsics/io/noise_document.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "kalibr_noise_keys.h"

namespace accel_intrinsics {
namespace io {
namespace {

constexpr const char* kAxes[3] = {"u", "v", "w"};

nlohmann::json number(double v) {
  if (!std::isfinite(v)) return nullptr;
  return v;
}

template <typename Get>
nlohmann::json per_axis(const core::StaticRecordNoise& noise, Get get) {
  nlohmann::json j = nlohmann::json::object();
  for (int a = 0; a < 3; ++a) j[kAxes[a]] = number(get(noise.axes[a]));
  return j;
}

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

constexpr char kConventions[] =
    "noise_density N: continuous-time white-noise density (Kalibr's), per-sample std = N * "
    "sqrt(rate_hz), read on the -1/2 line of the Allan deviation at tau = 1 s; random_walk K: on "
    "the +1/2 line at tau = 3 s; bias_instability B: the Allan minimum / 0.664 at "
    "bias_instability_tau_s";

}  // namespace

std::string noise_json_text(const core::StaticRecordNoise& noise, const std::string& source) {
  nlohmann::json j = nlohmann::json::object();
  j["noise_density"] =
      per_axis(noise, [](const core::NoiseParameters& p) { return p.white_density; });
  j["noise_density_std"] =
      per_axis(noise, [](const core::NoiseParameters& p) { return p.white_density_std; });
  j["bias_instability"] =
      per_axis(noise, [](const core::NoiseParameters& p) { return p.bias_instability; });
  j["bias_instability_std"] =
      per_axis(noise, [](const core::NoiseParameters& p) { return p.bias_instability_std; });
  j["bias_instability_tau_s"] =
      per_axis(noise, [](const core::NoiseParameters& p) { return p.bias_instability_tau_s; });
  nlohmann::json floor_seen = nlohmann::json::object();
  for (int a = 0; a < 3; ++a) floor_seen[kAxes[a]] = noise.axes[a].bias_instability_floor_seen;
  j["bias_instability_floor_seen"] = floor_seen;
  j["random_walk"] = per_axis(noise, [](const core::NoiseParameters& p) { return p.random_walk; });
  j["random_walk_std"] =
      per_axis(noise, [](const core::NoiseParameters& p) { return p.random_walk_std; });
  j["rate_hz"] = number(noise.rate_hz);
  j["duration_s"] = number(noise.duration_s);
  j["samples"] = noise.curve.samples;
  j["source"] = source;
  j["conventions"] = kConventions;
  nlohmann::json allan = nlohmann::json::object();
  allan["tau_s"] = noise.curve.tau_s;
  allan["relative_std"] = noise.curve.relative_std;
  nlohmann::json adev = nlohmann::json::object();
  for (int a = 0; a < 3; ++a) {
    nlohmann::json list = nlohmann::json::array();
    for (const Eigen::Vector3d& v : noise.curve.adev) list.push_back(number(v(a)));
    adev[kAxes[a]] = list;
  }
  allan["adev"] = adev;
  j["allan"] = allan;
  return j.dump(2) + "\n";
}

std::string kalibr_imu_noise_yaml(const core::StaticRecordNoise& noise, const std::string& source,
                                  const std::string& rostopic) {
  Eigen::Vector3d density, walk;
  for (int a = 0; a < 3; ++a) {
    density(a) = noise.axes[a].white_density;
    walk(a) = noise.axes[a].random_walk;
  }
  std::string out;
  out += "# kalibr IMU configuration, accelerometer keys, from accel_intrinsics noise_report\n";
  out += "# source: " + source + "\n";
  out += "# accelerometer_noise_density: continuous-time white-noise density, (m/s^2)/sqrt(Hz)\n";
  out += "#   (per-sample std = density * sqrt(update_rate)); accelerometer_random_walk:\n";
  out += "#   (m/s^3)/sqrt(Hz). Both are the largest of the three axes (u, v, w: " +
         num(noise.axes[0].white_density) + ", " + num(noise.axes[1].white_density) + ", " +
         num(noise.axes[2].white_density) + "; " + num(noise.axes[0].random_walk) + ", " +
         num(noise.axes[1].random_walk) + ", " + num(noise.axes[2].random_walk) + ").\n";
  out += "# Measured on a static record: kalibr's users often inflate them (e.g. x10) for the\n";
  out += "# unmodelled effects of a moving platform. Add the gyroscope_* keys from your gyro.\n";
  out += "rostopic: " + rostopic + "\n";
  out += detail::kalibr_noise_keys(density, walk, noise.rate_hz, "").lines;
  return out;
}

}  // namespace io
}  // namespace accel_intrinsics
