// offline_fit on hand tumbles (docs/design.md section 11): imu_tk's real Xsens session read as that
// tool ships it and compared with the result imu_tk itself computes for it; a bag holding the IMU
// topic alone, written here with rosbag (duplicated, reordered and shifted stamps); a gimbal run
// fitted with --unknown-orientations against the gimbal fit.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "../support/bag_writer.h"
#include "../support/source_dir.h"
#include "../support/statistical_bounds.h"
#include "../support/test_files.h"
#include "accel_intrinsics/core/dwells/samples_file.h"
#include "accel_intrinsics/core/model/intrinsics.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/core/simulation/tumble_simulator.h"
#include "accel_intrinsics/ros/compare_results.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace accel_intrinsics {
namespace {

using test_support::TempDir;

const std::string kXsens =
    accel_intrinsics::test_support::source_dir() + "/test/data/imu_tk_xsens/";

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

struct ToolRun {
  int status = -1;
  std::string out, err;
};

ToolRun run(const OfflineFitArguments& args) {
  std::ostringstream out, err;
  ToolRun r;
  r.status = run_offline_fit(args, out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

// imu_tk's public session (an Xsens IMU turned by hand, raw counts), read as imu_tk ships it.
// The reference is imu_tk's own calibration of this file (test/data/imu_tk_xsens/
// imu_tk_reference.json: its T K (raw - B) converted to intrinsics, rescaled to our g). Both fit
// |a| = g at the rests; they differ in the rests (imu_tk fits the first 100 samples of each
// interval) and the weights, so they agree within a few of our standard uncertainties, not
// exactly.
TEST(TumbleOffline, ImuTkXsensSessionAgreesWithImuTksOwnResult) {
  TempDir dir;
  OfflineFitArguments args;
  args.samples = kXsens + "xsens_acc.mat";
  args.output_unit = "counts";
  args.json_out = dir.file("xsens.json");
  const ToolRun r = run(args);
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = read_json(args.json_out);
  const nlohmann::json ref = read_json(kXsens + "imu_tk_reference.json");
  EXPECT_EQ(j["method"], "tumble");
  EXPECT_EQ(j["model"], "tumble");
  EXPECT_EQ(j["output_unit"], "counts");
  EXPECT_TRUE(j["coverage"]["complete"].get<bool>());
  // imu_tk found 38 static intervals (the 50 s initial rest among them).
  const std::size_t rests = j["rests"].size();
  EXPECT_GE(rests, 34u);
  EXPECT_LE(rests, 40u);
  EXPECT_FALSE(j["rejected_spans"].empty());
  // Real noise is not white (docs/design.md section 12): with white weights the reduced chi-square
  // is 16.6; with the noise model of the 51 s first rest, GLS across the rests, it is 1.34 (29
  // dof), within its chi-square band (the rests' errors are correlated, as the model says).
  EXPECT_NE(j["noise_model"], "white");
  EXPECT_LT(j["reduced_chi2"].get<double>(), 2.0);

  const nlohmann::json& theirs = ref["intrinsics"];
  const char* const axes[3] = {"u", "v", "w"};
  const char* const angles[3] = {"uv", "vw", "wu"};
  // Within 4.5 of our standard uncertainties (the two fits use different samples of the rests).
  const double k = 4.5;
  for (const char* a : axes) {
    const double ours = j["responsivity"][a], std = j["responsivity_std"][a];
    EXPECT_LT(std::abs(ours - theirs["responsivity_counts_per_m_s2_at_g_9.80665"][a].get<double>()),
              k * std)
        << a;
    const double offset = j["offset"][a], offset_std = j["offset_std"][a];
    EXPECT_LT(std::abs(offset - theirs["offset_counts"][a].get<double>()), k * offset_std) << a;
  }
  for (const char* a : angles) {
    const double ours = j["angles_deg"][a], std = j["angles_std_deg"][a];
    EXPECT_LT(std::abs(ours - theirs["angles_deg"][a].get<double>()), k * std) << a;
  }
}

// The same file rewritten as comma-separated t,x,y,z with a header: the same result.
TEST(TumbleOffline, CommaSeparatedCopyGivesTheSameResult) {
  TempDir dir;
  const std::vector<core::ImuSample> samples = core::read_samples_file(kXsens + "xsens_acc.mat");
  {
    std::ofstream out(dir.file("copy.csv"));
    core::write_samples(out, samples);
  }
  OfflineFitArguments a, b;
  a.samples = kXsens + "xsens_acc.mat";
  b.samples = dir.file("copy.csv");
  a.output_unit = b.output_unit = "counts";
  a.json_out = dir.file("a.json");
  b.json_out = dir.file("b.json");
  ASSERT_EQ(run(a).status, 0);
  ASSERT_EQ(run(b).status, 0);
  EXPECT_EQ(read_json(a.json_out)["responsivity"], read_json(b.json_out)["responsivity"]);
}

// A bag with the IMU topic alone, written here: a simulated tumble whose messages arrive
// duplicated and out of order, on a clock far from zero.
TEST(TumbleOffline, BagWithTheImuTopicAloneIsATumble) {
  TempDir dir;
  core::TumbleSimulationOptions o;
  o.truth = core::random_tumble_device(31);
  o.seed = 4;
  o.start_time_s = 1.7e9;
  const core::TumbleRecording rec = core::simulate_hand_tumble(o);
  {
    test_support::BagWriter bag(dir.file("tumble.bag"));
    for (std::size_t i = 0; i < rec.samples.size(); ++i) {
      // Every 50th message twice, every 97th written after its successor.
      std::size_t k = i;
      if (i % 97 == 0 && i + 1 < rec.samples.size()) k = i + 1;
      if (i % 97 == 1) k = i - 1;
      const double t = rec.samples[k].stamp_s;
      bag.sample(rec.samples[k], t + 0.002);
      if (i % 50 == 0) bag.sample(rec.samples[k], t + 0.003);
    }
  }
  OfflineFitArguments args;
  args.bags = {dir.file("tumble.bag")};
  args.json_out = dir.file("tumble.json");
  const ToolRun r = run(args);
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = read_json(args.json_out);
  EXPECT_EQ(j["method"], "tumble");
  EXPECT_EQ(j["rests"].size(), rec.rests.size());
  const core::Intrinsics truth = core::intrinsics_from_vectors(o.truth.S);
  const double k = statistical_bounds::normal_k(1e-3 / 6.0);
  const char* const axes[3] = {"u", "v", "w"};
  for (int s = 0; s < 3; ++s) {
    EXPECT_LT(std::abs(j["responsivity"][axes[s]].get<double>() - truth.responsivity(s)),
              k * j["responsivity_std"][axes[s]].get<double>())
        << axes[s];
    EXPECT_LT(std::abs(j["offset"][axes[s]].get<double>() - o.truth.O(s)),
              k * j["offset_std"][axes[s]].get<double>())
        << axes[s];
  }
  EXPECT_NE(r.out.find("no gimbal commands: a hand tumble"), std::string::npos) << r.out;
}

// A gimbal run's dwells fitted without their angles: the intrinsics agree with the gimbal fit's
// (the same device), while S is in another frame.
TEST(TumbleOffline, UnknownOrientationsOnAGimbalTableAgreesWithTheGimbalFit) {
  TempDir dir;
  core::SimulationOptions sim;
  sim.truth.S << 1.01, 0.004, -0.002, 0.003, 0.99, 0.006, -0.001, 0.002, 1.005;
  sim.truth.O = Eigen::Vector3d(0.05, -0.03, 0.08);
  sim.protocol.steps_per_phase = 12;
  sim.seed = 3;
  core::write_position_table_file(dir.file("gimbal.csv"), core::simulate_position_table(sim));
  OfflineFitArguments gimbal, tumble;
  gimbal.csv = tumble.csv = dir.file("gimbal.csv");
  tumble.unknown_orientations = true;
  gimbal.json_out = dir.file("gimbal.json");
  tumble.json_out = dir.file("tumble.json");
  ASSERT_EQ(run(gimbal).status, 0);
  const ToolRun r = run(tumble);
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json g = read_json(gimbal.json_out), t = read_json(tumble.json_out);
  EXPECT_EQ(g["method"], "gimbal");
  EXPECT_EQ(t["method"], "tumble");
  EXPECT_EQ(t["rests"].size(), 36u);
  const char* const angles[3] = {"uv", "vw", "wu"};
  for (const char* a : angles) {
    const double diff = t["angles_deg"][a].get<double>() - g["angles_deg"][a].get<double>();
    EXPECT_LT(std::abs(diff), 4.0 * t["angles_std_deg"][a].get<double>()) << a;
  }
  // The tumble's S is lower-triangular (sensor frame), the gimbal's is not.
  EXPECT_EQ(t["vectors"]["u"][1].get<double>(), 0.0);
  EXPECT_NE(g["vectors"]["u"][1].get<double>(), 0.0);
}

// README "Gimbal angle error or device property?": a gimbal whose x encoder reads 0.5 % short
// biases the fit with angles; the same dwells without angles still give the true intrinsics, and
// compare_results says the two disagree.
TEST(TumbleOffline, GimbalAngleScaleErrorShowsOnlyInTheFitWithAngles) {
  TempDir dir;
  core::SimulationOptions sim;
  sim.truth.S << 1.01, 0.004, -0.002, 0.003, 0.99, 0.006, -0.001, 0.002, 1.005;
  sim.truth.O = Eigen::Vector3d(0.05, -0.03, 0.08);
  core::Effect scale;
  scale.kind = core::EffectKind::AngleScale;
  scale.target = 0;  // phase x
  scale.value = 0.005;
  sim.truth.effects.push_back(scale);
  sim.protocol.steps_per_phase = 24;
  sim.seed = 11;
  core::write_position_table_file(dir.file("gimbal.csv"), core::simulate_position_table(sim));
  OfflineFitArguments gimbal, tumble;
  gimbal.csv = tumble.csv = dir.file("gimbal.csv");
  tumble.unknown_orientations = true;
  gimbal.json_out = dir.file("gimbal.json");
  tumble.json_out = dir.file("tumble.json");
  run(gimbal);  // the gate may fail (exit 3): the JSON is written either way
  ASSERT_EQ(run(tumble).status, 0);
  const nlohmann::json g = read_json(gimbal.json_out), t = read_json(tumble.json_out);

  // Truth, with the angles in degrees as the JSON has them.
  const core::Intrinsics truth = core::intrinsics_from_vectors(sim.truth.S);
  const char* const angles[3] = {"uv", "vw", "wu"};
  double worst_gimbal_z = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double true_deg = truth.angles_rad(i) * 180.0 / M_PI;
    const double zt = (t["angles_deg"][angles[i]].get<double>() - true_deg) /
                      t["angles_std_deg"][angles[i]].get<double>();
    const double zg = (g["angles_deg"][angles[i]].get<double>() - true_deg) /
                      g["angles_std_deg"][angles[i]].get<double>();
    EXPECT_LT(std::abs(zt), 4.0) << "tumble fit, theta_" << angles[i];
    worst_gimbal_z = std::max(worst_gimbal_z, std::abs(zg));
  }
  const char* const axes[3] = {"u", "v", "w"};
  for (int i = 0; i < 3; ++i) {
    const double zt = (t["responsivity"][axes[i]].get<double>() - truth.responsivity(i)) /
                      t["responsivity_std"][axes[i]].get<double>();
    const double zg = (g["responsivity"][axes[i]].get<double>() - truth.responsivity(i)) /
                      g["responsivity_std"][axes[i]].get<double>();
    EXPECT_LT(std::abs(zt), 4.0) << "tumble fit, |" << axes[i] << "|";
    worst_gimbal_z = std::max(worst_gimbal_z, std::abs(zg));
  }
  // The fit with angles carries the error: its residuals exceed the noise (its uncertainties,
  // scaled by the reduced chi-square, then hide much of the bias).
  EXPECT_GT(g["reduced_chi2"].get<double>(), 3.0);
  EXPECT_GT(worst_gimbal_z, 1.0) << "the angle-scale error should bias the fit with angles";
  std::cout << "gimbal fit: worst |z| " << worst_gimbal_z << ", reduced chi2 "
            << g["reduced_chi2"].get<double>() << "; fit without angles: reduced chi2 "
            << t["reduced_chi2"].get<double>() << std::endl;

  CompareResultsArguments compare;
  compare.files = {gimbal.json_out, tumble.json_out};
  compare.json_out = dir.file("comparison.json");
  compare.type_a_only = true;  // no budget: U = 2 x the type-A uncertainties
  std::ostringstream out, err;
  EXPECT_EQ(run_compare_results(compare, out, err), kCompareInconsistent) << out.str() << err.str();
}

// Everything downstream takes a tumble result: a budget of g alone (the gimbal sources refused,
// naming why), exports read back by their own equations, the certificate stating the method.
TEST(TumbleOffline, BudgetExportsAndCertificateTakeATumble) {
  TempDir dir;
  {
    std::ofstream out(dir.file("g_only.yaml"));
    // 3e-4: standard gravity's own uncertainty (the fit uses the standard g; less is refused
    // a certificate).
    out << "gravity_std_rel: 3.0e-4\nsamples: 50\ncertificate:\n  lab: Tumble Lab\n";
    std::ofstream gimbal(dir.file("gimbal.yaml"));
    gimbal << "gravity_std_rel: 1.0e-4\nangle_offset_std_deg: 0.01\nsamples: 50\n";
  }
  OfflineFitArguments args;
  args.samples = kXsens + "xsens_acc.mat";
  args.output_unit = "counts";
  args.budget = dir.file("gimbal.yaml");
  ToolRun r = run(args);
  EXPECT_EQ(r.status, kOfflineFitBadInput);
  EXPECT_NE(r.err.find("gravity_std_rel only"), std::string::npos) << r.err;

  args.budget = dir.file("g_only.yaml");
  args.json_out = dir.file("tumble.json");
  args.exports = {"imu_tk=" + dir.file("imu_tk.txt"), "imu_calib=" + dir.file("imu_calib.yaml")};
  args.report_pdf = dir.file("certificate.pdf");
  r = run(args);
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = read_json(args.json_out);
  // g enters every responsivity alike: its relative contribution is gravity_std_rel.
  const nlohmann::json& sources = j["uncertainty_budget"]["sources"];
  bool gravity = false;
  for (const nlohmann::json& source : sources) {
    if (source["name"] != "gravity_std_rel") continue;
    gravity = true;
    EXPECT_NEAR(
        source["responsivity_std"]["u"].get<double>() / j["responsivity"]["u"].get<double>(),
        3.0e-4, 3.0e-6);
  }
  EXPECT_TRUE(gravity) << sources.dump();
  // imu_tk's text file: T (3x3), K (3x3), B (3): a' = T K (raw - B) must give |a'| = g at rests.
  std::ifstream in(dir.file("imu_tk.txt"));
  Eigen::Matrix3d T, K;
  Eigen::Vector3d B;
  for (int i = 0; i < 9; ++i) in >> T(i / 3, i % 3);
  for (int i = 0; i < 9; ++i) in >> K(i / 3, i % 3);
  for (int i = 0; i < 3; ++i) in >> B(i);
  ASSERT_TRUE(in) << "imu_tk export did not parse";
  const double g = j["local_gravity"];
  for (const nlohmann::json& rest : j["rests"]) {
    const Eigen::Vector3d raw(rest["mean"]["u"], rest["mean"]["v"], rest["mean"]["w"]);
    EXPECT_NEAR((T * K * (raw - B)).norm(), g, 0.01) << rest.dump();
  }
  if (std::system("command -v pdftotext >/dev/null") == 0) {
    ASSERT_EQ(
        std::system(("pdftotext -layout " + args.report_pdf + " " + dir.file("c.txt")).c_str()), 0);
    const std::string text = test_support::read_file(dir.file("c.txt"));
    EXPECT_NE(text.find("hand tumble, orientations unknown"), std::string::npos) << text;
  }
}

TEST(TumbleOffline, BadInputsGiveOneLine) {
  TempDir dir;
  {
    std::ofstream out(dir.file("bad.txt"));
    out << "t,x,y,z\n0,1,2,3\n0.01,1,2\n";
  }
  OfflineFitArguments args;
  args.samples = dir.file("bad.txt");
  ToolRun r = run(args);
  EXPECT_EQ(r.status, kOfflineFitBadInput);
  EXPECT_NE(r.err.find("bad.txt:3: expected 4 fields"), std::string::npos) << r.err;

  // Too few rests: the device lying still on the bench.
  {
    std::ofstream out(dir.file("still.txt"));
    for (int i = 0; i < 2000; ++i) out << i * 0.01 << " 0.01 -0.02 9.81\n";
  }
  args.samples = dir.file("still.txt");
  r = run(args);
  EXPECT_EQ(r.status, kOfflineFitBadInput);
  EXPECT_NE(r.err.find("1 rests found in the stream (0 still spans rejected), at least 10 needed"),
            std::string::npos)
      << r.err;
  EXPECT_TRUE(dir.entries().count("out.json") == 0);

  OfflineFitArguments both;
  both.samples = dir.file("still.txt");
  both.csv = dir.file("x.csv");
  EXPECT_EQ(run(both).status, kOfflineFitBadCommandLine);
  OfflineFitArguments rest;
  rest.samples = dir.file("still.txt");
  rest.rest_min_s = 0.0;
  EXPECT_EQ(run(rest).status, kOfflineFitBadCommandLine);
  OfflineFitArguments unknown;
  unknown.samples = dir.file("still.txt");
  unknown.unknown_orientations = true;
  EXPECT_EQ(run(unknown).status, kOfflineFitBadCommandLine);
}

}  // namespace
}  // namespace accel_intrinsics
