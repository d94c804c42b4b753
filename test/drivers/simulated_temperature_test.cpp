// The simulated accelerometer's temperature (docs/design.md section 10): readings follow the
// configured profile from the first gimbal command on, and the temperature effects act on T -
// reference_c, checked against the docs/design.md terms written out here.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "accel_intrinsics/drivers/accelerometer_source.h"

namespace accel_intrinsics {
namespace {

TEST(SimulatedTemperature, ReadingsFollowTheProfileAndDriveTheEffects) {
  SimulatedAccelerometerOptions o;
  o.noise_density = 0.0;
  o.rate_hz = 10.0;
  o.truth.effects = {core::make_effect("offset_temperature_coefficient", "u", 0.01),
                     core::make_effect("scale_temperature_coefficient", "w", 2e-3)};
  o.temperature.recorded = true;
  o.temperature.start_c = 20.0;
  o.temperature.rate_c_per_s = 0.1;
  o.temperature.rate_hz = 2.0;
  o.temperature_reference_c = 21.0;
  SimulatedAccelerometer sensor(o, [](double, Eigen::Matrix3d* R) {
    *R = Eigen::Matrix3d::Identity();  // z up: f = (0, 0, g)
    return OrientationStatus::Available;
  });
  EXPECT_TRUE(sensor.publishes_temperature());
  sensor.set_time_origin(100.0);
  std::vector<core::ImuSample> samples;
  std::vector<core::TemperatureSample> readings;
  sensor.poll(100.0, &samples);
  sensor.poll_temperatures(100.0, &readings);
  sensor.poll(110.0, &samples);
  sensor.poll_temperatures(110.0, &readings);
  ASSERT_EQ(samples.size(), 101u);
  ASSERT_EQ(readings.size(), 21u);
  const double g = o.local_gravity;
  for (const core::ImuSample& s : samples) {
    const double T = 20.0 + 0.1 * (s.stamp_s - 100.0);
    EXPECT_NEAR(s.outputs(0), 0.01 * (T - 21.0), 1e-12) << s.stamp_s;  // c (T - T_ref)
    EXPECT_NEAR(s.outputs(1), 0.0, 1e-12);
    EXPECT_NEAR(s.outputs(2), g + 2e-3 * (T - 21.0) * g, 1e-12) << s.stamp_s;  // c (T-T_ref) L_w
  }
  for (const core::TemperatureSample& r : readings)
    EXPECT_NEAR(r.temperature_c, 20.0 + 0.1 * (r.stamp_s - 100.0), 1e-12) << r.stamp_s;

  // Off by default: no readings.
  SimulatedAccelerometerOptions quiet;
  SimulatedAccelerometer silent(quiet, [](double, Eigen::Matrix3d* R) {
    *R = Eigen::Matrix3d::Identity();
    return OrientationStatus::Available;
  });
  EXPECT_FALSE(silent.publishes_temperature());
  readings.clear();
  silent.poll_temperatures(5.0, &readings);
  EXPECT_TRUE(readings.empty());
}

TEST(SimulatedTemperature, BadProfileIsRejectedNamingTheParameter) {
  SimulatedAccelerometerOptions o;
  o.temperature.rate_hz = 0.0;
  try {
    o.validate();
    FAIL() << "a temperature rate of 0 Hz was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("temperature/rate_hz"), std::string::npos) << e.what();
  }
}

// After a long gap (2000 readings pending) one poll hands out the documented 1000 and the next
// the following 1000, consecutive: bounded work per poll, no reading lost or repeated.
TEST(SimulatedTemperature, APollAfterALongGapIsCappedAndTheNextContinues) {
  SimulatedAccelerometerOptions o;
  o.temperature.recorded = true;
  o.temperature.rate_hz = 2.0;
  SimulatedAccelerometer sensor(o, [](double, Eigen::Matrix3d* R) {
    *R = Eigen::Matrix3d::Identity();
    return OrientationStatus::Available;
  });
  std::vector<core::TemperatureSample> first, second, third;
  sensor.poll_temperatures(100.0, &first);  // reading 200, at 100 s
  ASSERT_EQ(first.size(), 1u);
  first.clear();
  sensor.poll_temperatures(1100.0, &first);  // readings 201 .. 2200 are due
  ASSERT_EQ(first.size(), 1000u);
  sensor.poll_temperatures(1100.0, &second);
  ASSERT_EQ(second.size(), 1000u);
  sensor.poll_temperatures(1100.0, &third);
  EXPECT_TRUE(third.empty());
  for (std::size_t k = 0; k < 1000; ++k) {
    EXPECT_NEAR(first[k].stamp_s, 100.5 + 0.5 * k, 1e-9) << k;
    EXPECT_NEAR(second[k].stamp_s, 600.5 + 0.5 * k, 1e-9) << k;
  }
}

}  // namespace
}  // namespace accel_intrinsics
