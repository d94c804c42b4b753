#include "accel_intrinsics/core/result_json.h"

#include <cmath>
#include <limits>

#include "accel_intrinsics/core/constants.h"
#include "accel_intrinsics/core/protocol.h"

namespace accel_intrinsics {
namespace core {
namespace {

// nlohmann writes NaN/inf as null already; being explicit keeps the intent visible.
nlohmann::json number(double value) {
  if (!std::isfinite(value)) return nullptr;
  return value;
}

nlohmann::json row_list(const Eigen::Vector3d& values) {
  return nlohmann::json::array({number(values(0)), number(values(1)), number(values(2))});
}

nlohmann::json matrix_rows(const Eigen::Matrix3d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) rows.push_back(row_list(m.row(r).transpose()));
  return rows;
}

nlohmann::json angle_object(const Eigen::Vector3d& values) {
  return {{"uv", number(values(0))}, {"vw", number(values(1))}, {"wu", number(values(2))}};
}

// {u: {x, y, z}, v: ..., w: ...} from a matrix with rows u, v, w and columns x, y, z.
nlohmann::json accelerometer_by_phase(const Eigen::Matrix3d& m) {
  nlohmann::json out = nlohmann::json::object();
  for (int s = 0; s < 3; ++s) out[accelerometer_name(s)] = phase_object(m.row(s).transpose());
  return out;
}

}  // namespace

nlohmann::json accelerometer_object(const Eigen::Vector3d& values) {
  nlohmann::json out = nlohmann::json::object();
  for (int s = 0; s < 3; ++s) out[accelerometer_name(s)] = number(values(s));
  return out;
}

nlohmann::json phase_object(const Eigen::Vector3d& values) {
  nlohmann::json out = nlohmann::json::object();
  for (Phase p : kPhases) out[phase_name(p)] = number(values(index(p)));
  return out;
}

nlohmann::json to_json(const FitResult& result) {
  nlohmann::json j = nlohmann::json::object();
  j["model"] = model_name(result.model);
  j["model_label"] = result.model_label();
  j["local_gravity"] = number(result.local_gravity);

  const Intrinsics& in = result.intrinsics;
  j["responsivity"] = accelerometer_object(in.responsivity);
  j["responsivity_std"] = accelerometer_object(in.responsivity_std);
  Eigen::Vector3d angles_deg, angles_std_deg;
  for (int i = 0; i < 3; ++i) {
    angles_deg(i) = rad_to_deg(in.angles_rad(i));
    angles_std_deg(i) = rad_to_deg(in.angles_std_rad(i));
  }
  j["angles_deg"] = angle_object(angles_deg);
  j["angles_std_deg"] = angle_object(angles_std_deg);

  // Rows of S are the vectors; covariance is over (S row-major, O).
  nlohmann::json vectors = nlohmann::json::object();
  nlohmann::json vectors_std = nlohmann::json::object();
  for (int s = 0; s < 3; ++s) {
    Eigen::Vector3d std_row;
    for (int c = 0; c < 3; ++c) {
      const double var = result.covariance(3 * s + c, 3 * s + c);
      std_row(c) = var >= 0.0 ? std::sqrt(var) : std::numeric_limits<double>::quiet_NaN();
    }
    vectors[accelerometer_name(s)] = row_list(result.S.row(s).transpose());
    vectors_std[accelerometer_name(s)] = row_list(std_row);
  }
  j["vectors"] = vectors;
  j["vectors_std"] = vectors_std;

  j["offset"] = accelerometer_object(result.O);
  j["offset_std"] = accelerometer_object(result.O_std);
  j["offset_per_phase"] = accelerometer_by_phase(result.offset_per_phase);
  j["offset_per_phase_std"] = accelerometer_by_phase(result.offset_per_phase_std);

  j["cross_sensitivity"] = matrix_rows(result.cross_sensitivity);
  j["cross_sensitivity_std"] = matrix_rows(result.cross_sensitivity_std);

  j["reduced_chi2"] = number(result.reduced_chi2);
  j["chi2"] = number(result.chi2);
  j["dof"] = result.dof;
  j["residual_rms"] = number(result.residual_rms);
  j["positions"] = {{"x", result.positions[0]}, {"y", result.positions[1]}, {"z", result.positions[2]}};

  nlohmann::json fitted = nlohmann::json::array();
  for (std::size_t i = 0; i < result.effects.size(); ++i) {
    const Effect& e = result.effects[i];
    const double std_value = i < result.effects_std.size()
                                 ? result.effects_std[i]
                                 : std::numeric_limits<double>::quiet_NaN();
    fitted.push_back({{"name", e.name()},
                      {"target", e.target_name()},
                      {"value", number(e.value)},
                      {"std", number(std_value)}});
  }
  j["fitted_effects"] = fitted;
  return j;
}

}  // namespace core
}  // namespace accel_intrinsics
