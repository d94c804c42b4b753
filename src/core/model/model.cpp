#include "accel_intrinsics/core/model/model.h"

#include <Eigen/LU>
#include <cmath>
#include <stdexcept>

namespace accel_intrinsics {
namespace core {

Eigen::Vector3d predict_outputs(const Device& device, const DwellGeometry& geom, double g) {
  const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> S = device.S;
  std::vector<double> values;
  values.reserve(device.effects.size());
  for (const Effect& effect : device.effects) values.push_back(effect.value);
  return predict_outputs<double>(S.data(), device.O.data(), device.effects, values.data(), geom, g);
}

void validate(const Device& device) {
  if (!device.S.allFinite()) throw std::invalid_argument("device: S has a non-finite entry");
  if (!device.O.allFinite()) throw std::invalid_argument("device: O has a non-finite entry");
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(device.S);
  if (lu.rank() < 3)
    throw std::invalid_argument("device: S is singular (the three axes are not independent)");
  for (const Effect& effect : device.effects) {
    if (!std::isfinite(effect.value))
      throw std::invalid_argument("device: effect " + effect.label() + " is not finite");
  }
}

}  // namespace core
}  // namespace accel_intrinsics
