// The apply node's calibration file (io/apply_calibration_file.h): our results (JSON and the
// node's YAML) and an imu_calib YAML give the same P and O; noise gives the per-sample std; a bad
// file is refused naming it.
#include "accel_intrinsics/io/apply_calibration_file.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "../support/test_files.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/exporters.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {
namespace {

using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

namespace fs = std::filesystem;

core::CalibrationReport report() {
  core::SimulationOptions sim;
  sim.seed = 9;
  sim.truth.S << 1.01, 0.01, -0.02, 0.015, 0.98, 0.01, -0.01, 0.02, 1.02;
  sim.truth.O << 0.05, -0.03, 0.1;
  return core::calibrate(core::simulate_position_table(sim), nullptr, core::CalibrateOptions{});
}

TEST(ApplyCalibrationFile, ResultsAndImuCalibAgree) {
  TempDir dir;
  const core::CalibrationReport r = report();
  ASSERT_TRUE(r.noise.has_value());
  io::write_result_json(dir.file("result.json"), r, io::ResultContext{});
  io::write_result_yaml(dir.file("intrinsics.yaml"), r, io::ResultContext{});
  io::write_export(dir.file("imu_calib.yaml"), io::ExportFormat::ImuCalib,
                   io::calibration_to_export(r, "test"));
  const Eigen::Matrix3d P = r.certificate.S.inverse();
  for (const char* name : {"result.json", "intrinsics.yaml", "imu_calib.yaml"}) {
    const io::ApplyCalibration c = io::read_apply_calibration(dir.file(name));
    EXPECT_TRUE(c.P.isApprox(P, 1e-12)) << name;
    EXPECT_TRUE(c.O.isApprox(r.certificate.O, 1e-12)) << name;
  }
  const io::ApplyCalibration result = io::read_apply_calibration(dir.file("result.json"));
  EXPECT_EQ(result.kind, "result");
  const Eigen::Vector3d expected = r.noise->density * std::sqrt(r.noise->rate_hz);
  EXPECT_TRUE(result.sample_std.isApprox(expected, 1e-12));
  EXPECT_TRUE(result.sample_std.isApprox(r.noise->sample_std, 1e-9));
  const io::ApplyCalibration calib = io::read_apply_calibration(dir.file("imu_calib.yaml"));
  EXPECT_EQ(calib.kind, "imu_calib");
  EXPECT_FALSE(calib.sample_std.allFinite());
}

TEST(ApplyCalibrationFile, RefusesABadFileNamingIt) {
  TempDir dir;
  std::ofstream(dir.file("garbage.yaml")) << "SM: [1, 2\n";
  std::ofstream(dir.file("other.yaml")) << "answer: 42\n";
  std::ofstream(dir.file("short.yaml")) << "SM: [1, 0, 0, 0, 1, 0]\nbias: [0, 0, 0]\n";
  std::ofstream(dir.file("singular.yaml")) << "SM: [1, 0, 0, 1, 0, 0, 0, 0, 1]\nbias: [0, 0, 0]\n";
  for (const char* name :
       {"missing.yaml", "garbage.yaml", "other.yaml", "short.yaml", "singular.yaml"}) {
    try {
      io::read_apply_calibration(dir.file(name));
      ADD_FAILURE() << name;
    } catch (const io::IoError& e) {
      EXPECT_NE(std::string(e.what()).find(dir.file(name)), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace accel_intrinsics
