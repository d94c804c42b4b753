// offline_fit on a bag of a retried run (issue 21): the calibration node, after a fault in a dwell
// (on_fault: retry), has the controller measure the position again and drops the dwell the fault
// cut short. The bag holds both; offline_fit keeps the dwell measured again, as the node does, and
// says so. The bag is written here by hand: the same run with and without the cut-short dwell
// must give the same fit.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "../support/bag_writer.h"
#include "../support/test_files.h"
#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;
using nlohmann::json;

namespace {

using ai::test_support::TempDir;

constexpr std::uint32_t kSteps = 6;

// 3 phases x 6 positions, one-way. At phase y, step 2 the first dwell is cut short after 3
// samples (with `cut_short`: written; without: the bag has only the controller's second MOVING
// there, as if nothing had been measured) and measured again after a MOVING to the same position.
void write_run(const std::string& path, bool cut_short) {
  ai::test_support::BagWriter bag(path);
  bag.receive_delay_s = 0.001;
  Eigen::Matrix3d S;
  S << 1.01, 0.02, -0.01, 0.0, 0.99, 0.03, 0.01, -0.02, 1.02;
  const Eigen::Vector3d O(0.1, -0.2, 0.05);
  double t = 100.0;
  for (int phase = 0; phase < 3; ++phase) {
    for (std::uint32_t step = 0; step < kSteps; ++step) {
      const double a = 2.0 * core::kPi * step / kSteps;
      const Eigen::Vector3d f = core::in_plane_direction(static_cast<core::Phase>(phase), a);
      const Eigen::Vector3d R = S * (core::kStandardGravity * f) + O;
      bag.command(t, phase, step, kSteps, a, ai::GimbalCommand::MOVING);
      if (phase == 1 && step == 2) {
        if (cut_short) {
          bag.command(t + 0.5, phase, step, kSteps, a, ai::GimbalCommand::SETTLED);
          // A stalled IMU: three samples far off, then silence until the retry.
          for (int i = 0; i < 3; ++i)
            bag.sample(t + 0.5 + 0.1 * i, R + Eigen::Vector3d(0.5, -0.4, 0.3));
        }
        t += 2.0;
        bag.command(t, phase, step, kSteps, a, ai::GimbalCommand::MOVING);
      }
      bag.command(t + 0.5, phase, step, kSteps, a, ai::GimbalCommand::SETTLED);
      for (int i = 0; i < 5; ++i)
        bag.sample(t + 0.5 + 0.1 * i,
                   R + Eigen::Vector3d(0.01 * (i - 2), -0.01 * (i - 2), 0.005 * (i - 2)));
      t += 1.0;
    }
  }
  bag.command(t, 2, kSteps - 1, kSteps, 2.0 * core::kPi * (kSteps - 1) / kSteps,
              ai::GimbalCommand::DONE);
}

json fit(const std::string& bag, const std::string& json_path, std::string* err_text) {
  ai::OfflineFitArguments args;
  args.bags = {bag};
  args.json_out = json_path;
  std::ostringstream out, err;
  const int status = ai::run_offline_fit(args, out, err);
  *err_text = err.str();
  EXPECT_EQ(status, 0) << err.str();
  std::ifstream in(json_path);
  return json::parse(in);
}

}  // namespace

TEST(OfflineFitRetriedRun, KeepsTheDwellMeasuredAgainAsTheNodeDoes) {
  TempDir dir;
  write_run(dir.file("retried.bag"), true);
  write_run(dir.file("clean.bag"), false);
  std::string retried_err, clean_err;
  const json retried = fit(dir.file("retried.bag"), dir.file("retried.json"), &retried_err);
  const json clean = fit(dir.file("clean.bag"), dir.file("clean.json"), &clean_err);
  EXPECT_EQ(retried["positions"], clean["positions"]);
  EXPECT_EQ(retried["positions"]["y"], static_cast<int>(kSteps));
  for (const char* key : {"responsivity", "angles_deg", "offset", "reduced_chi2", "residual_rms"})
    EXPECT_EQ(retried[key], clean[key]) << key;
  // Said, with the position and where the dropped dwell began.
  const std::string warnings = retried.value("warnings", json::array()).dump();
  EXPECT_NE(warnings.find("1 dwell measured again"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("phase y step 2 at t=108.500"), std::string::npos) << warnings;
  EXPECT_EQ(clean.value("warnings", json::array()).dump().find("measured again"),
            std::string::npos);
}
