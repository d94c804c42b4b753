// The live tumble's progress document (io/tumble_progress.h), parsed back with nlohmann_json:
// every key carries its own field (values chosen all different, so a field under the wrong key
// shows), non-finite numbers become null.
#include "accel_intrinsics/io/tumble_progress.h"

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

namespace accel_intrinsics {
namespace {

TEST(TumbleProgress, EveryFieldUnderItsOwnKey) {
  core::TumbleProgress p;
  p.rests = 7;
  p.rejected = 2;
  p.samples = 12345;
  p.still_s = 1.25;
  p.fitted = true;
  p.fit_error = "";
  core::TumbleCoverage coverage;
  coverage.missing = {"no rest with w pointing down within 45 deg"};
  p.coverage = coverage;
  core::RelativeUncertainty r;
  r.name = "responsivity_u";
  r.value = 3e-4;
  p.relative = {r};
  p.largest_relative_std = 3e-4;
  p.largest_name = "responsivity_u";
  p.next_up = Eigen::Vector3d(0.0, 0.0, -1.0);
  p.next_pose_words = "w down";
  p.target_reached = false;
  p.message = "hold still";
  const nlohmann::json j = nlohmann::json::parse(io::tumble_progress_json(p));
  EXPECT_EQ(j["rests"].get<int>(), 7);
  EXPECT_EQ(j["rejected"].get<int>(), 2);
  EXPECT_EQ(j["samples"].get<int>(), 12345);
  EXPECT_DOUBLE_EQ(j["still_s"].get<double>(), 1.25);
  EXPECT_TRUE(j["fitted"].get<bool>());
  EXPECT_FALSE(j["coverage"]["complete"].get<bool>());
  ASSERT_EQ(j["coverage"]["missing"].size(), 1u);
  EXPECT_DOUBLE_EQ(j["relative_std"]["responsivity_u"].get<double>(), 3e-4);
  EXPECT_EQ(j["largest_name"], "responsivity_u");
  EXPECT_DOUBLE_EQ(j["next_pose"]["up"][2].get<double>(), -1.0);
  EXPECT_EQ(j["next_pose"]["words"], "w down");
  EXPECT_FALSE(j["target_reached"].get<bool>());
  EXPECT_EQ(j["message"], "hold still");
  // Before the first fit: no coverage, no largest figure.
  core::TumbleProgress empty;
  const nlohmann::json e = nlohmann::json::parse(io::tumble_progress_json(empty));
  EXPECT_TRUE(e["coverage"].is_null());
  EXPECT_TRUE(e["largest_relative_std"].is_null());
}

}  // namespace
}  // namespace accel_intrinsics
