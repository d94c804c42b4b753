#include "accel_intrinsics/io/tumble_progress.h"

#include <cmath>
#include <nlohmann/json.hpp>

namespace accel_intrinsics {
namespace io {

std::string tumble_progress_json(const core::TumbleProgress& p) {
  auto number = [](double x) {
    return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr);
  };
  nlohmann::json j;
  j["rests"] = p.rests;
  j["rejected"] = p.rejected;
  j["samples"] = p.samples;
  j["still_s"] = number(p.still_s);
  j["fitted"] = p.fitted;
  j["fit_error"] = p.fit_error;
  if (p.coverage) {
    j["coverage"] = {{"complete", p.coverage->complete()}, {"missing", p.coverage->missing}};
  } else {
    j["coverage"] = nullptr;
  }
  nlohmann::json relative = nlohmann::json::object();
  for (const core::RelativeUncertainty& u : p.relative) relative[u.name] = number(u.value);
  j["relative_std"] = relative;
  j["largest_relative_std"] = number(p.largest_relative_std);
  j["largest_name"] = p.largest_name;
  j["next_pose"] = {{"up", {p.next_up.x(), p.next_up.y(), p.next_up.z()}},
                    {"words", p.next_pose_words}};
  j["target_reached"] = p.target_reached;
  j["message"] = p.message;
  return j.dump();
}

}  // namespace io
}  // namespace accel_intrinsics
