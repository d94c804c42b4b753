// Random truth devices for the core tests that screen for hidden effects.
#pragma once

#include <Eigen/Geometry>
#include <random>

#include "accel_intrinsics/core/model/model.h"

namespace accel_intrinsics {
namespace core {
namespace testing_devices {

// A random triad in a random mounting: responsivities 1 +- 3 %, misalignments ~10 mrad,
// offsets ~0.1 m/s^2, the whole triad rotated arbitrarily in the DUT frame.
inline Device random_device(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  Eigen::Matrix3d M = Eigen::Matrix3d::Identity();
  for (int i = 0; i < 3; ++i) {
    M(i, i) = 1.0 + 0.03 * n(rng);
    for (int j = 0; j < 3; ++j) {
      if (i != j) M(i, j) = 0.01 * n(rng);
    }
  }
  Device d;
  d.S = M * q.toRotationMatrix();
  d.O = 0.1 * Eigen::Vector3d(n(rng), n(rng), n(rng));
  return d;
}

}  // namespace testing_devices
}  // namespace core
}  // namespace accel_intrinsics
