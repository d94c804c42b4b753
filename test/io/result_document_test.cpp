// The result document: JSON and YAML from one key list (same keys, same values), read back by
// read_result_file (both writers' files and an old node YAML), written atomically.
#include "accel_intrinsics/io/result_document.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>

#include "../support/test_files.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/text_report.h"

namespace accel_intrinsics {
namespace {

using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

namespace fs = std::filesystem;
using namespace core;

// A run with a quadratic term and a timing lag, analyzed, the refit as certificate: every kind of
// key (fitted_effects, effects, timing_lag, nulls of a csv input) appears.
CalibrationReport analyzed_report() {
  SimulationOptions sim;
  sim.seed = 7;
  sim.truth.S << 1.01, 0.01, -0.02, 0.015, 0.98, 0.01, -0.01, 0.02, 1.02;
  sim.truth.O << 0.1, -0.2, 0.05;
  sim.truth.effects = {Effect{EffectKind::QuadraticNonlinearity, 1, 4e-4},
                       Effect{EffectKind::TimingLag, 0, 0.02}};
  const Recording recording = simulate_recording(sim);
  DwellAssembler assembler;
  feed_in_stamp_order(recording, &assembler);
  RawStreams raw{recording.commands, recording.samples};
  CalibrateOptions options;
  options.analyze = true;
  options.certificate_refit = true;
  options.analysis.monte_carlo_draws = 2000;
  return calibrate(assembler.table(), &raw, options);
}

const CalibrationReport& report() {
  static const CalibrationReport r = analyzed_report();
  return r;
}

io::ResultContext full_context() {
  io::ResultContext c;
  c.stamp_s = 1700000000.25;
  AssemblerCounters counters;
  counters.samples_used = 12345;
  counters.dropped_outside_dwell = 17;
  counters.dropped_late = 2;
  c.samples = counters;
  io::InputDescription input;
  input.path = "/tmp/run.bag";
  input.dwells = 72;
  io::BagInputDescription bag;
  bag.imu_topic = "/imu/data_raw";
  bag.command_topic = "/gimbal/command";
  bag.imu_messages = 20000;
  bag.counters = counters;
  bag.done_seen = false;
  input.bag = bag;
  input.summary = "bag /tmp/run.bag";
  c.input = input;
  c.complete = false;
  c.warnings = {"the recording ends before the controller's DONE", "true", "1.5", ""};
  return c;
}

// A fit with a noise model states it: kind, source, rest and the parameters per axis, in JSON and
// YAML alike (issue 23).
TEST(ResultDocument, NoiseModelOfTheLongRest) {
  SimulationOptions sim;
  sim.seed = 11;
  sim.protocol.initial_rest_s = 120.0;
  sim.bias_gm_sigma = 0.0015;
  sim.bias_gm_tau_s = 30.0;
  RestSamples rest;
  const PositionTable table = simulate_position_table(sim, &rest);
  const std::optional<NoiseModel> m = noise_model_of_run(table, rest.stamps_s, rest.outputs, 120.0);
  ASSERT_TRUE(m.has_value());
  CalibrateOptions options;
  options.fit.noise_model = *m;
  const CalibrationReport r = calibrate(table, nullptr, options);
  // What the fit used: the rest's model with its slow part fitted again to the run
  // (slow_part_from_run); its source starts with the rest's.
  const NoiseModel& used = r.base_fit.noise_model;
  EXPECT_EQ(used.source.find(m->source), 0u) << used.source;
  const nlohmann::json j = nlohmann::json::parse(io::result_json_text(r, {}));
  ASSERT_TRUE(j["noise_model"].is_object());
  EXPECT_EQ(j["noise_model"]["kind"], used.kind());
  EXPECT_EQ(j["noise_model"]["rest"]["samples"], m->rest_samples);
  EXPECT_DOUBLE_EQ(j["noise_model"]["axes"]["v"]["gm_sigma"].get<double>(), used.axes[1].gm_sigma);
  const YAML::Node y = YAML::Load(io::result_yaml_text(r, {}));
  EXPECT_EQ(y["noise_model"]["kind"].as<std::string>(), used.kind());
  std::ostringstream text;
  io::write_text_report(text, r, {});
  EXPECT_NE(text.str().find("noise model:   " + used.kind()), std::string::npos) << text.str();
}

// The YAML tree equals the JSON tree: the same keys everywhere, the same values (numbers to the
// last bit, strings that look like numbers or bools still strings, null for null).
void expect_same_tree(const nlohmann::json& j, const YAML::Node& y, const std::string& where) {
  if (j.is_object()) {
    ASSERT_TRUE(y.IsMap()) << where;
    std::set<std::string> json_keys, yaml_keys;
    for (auto it = j.begin(); it != j.end(); ++it) json_keys.insert(it.key());
    for (auto it = y.begin(); it != y.end(); ++it) yaml_keys.insert(it->first.as<std::string>());
    ASSERT_EQ(json_keys, yaml_keys) << where;
    for (auto it = j.begin(); it != j.end(); ++it) {
      expect_same_tree(it.value(), y[it.key()], where + "." + it.key());
    }
  } else if (j.is_array()) {
    ASSERT_TRUE(y.IsSequence()) << where;
    ASSERT_EQ(j.size(), y.size()) << where;
    for (std::size_t i = 0; i < j.size(); ++i) {
      expect_same_tree(j[i], y[i], where + "[" + std::to_string(i) + "]");
    }
  } else if (j.is_null()) {
    EXPECT_TRUE(y.IsNull()) << where;
  } else if (j.is_boolean()) {
    EXPECT_EQ(y.as<bool>(), j.get<bool>()) << where;
  } else if (j.is_number()) {
    EXPECT_EQ(y.as<double>(), j.get<double>()) << where << " = " << y.Scalar();
  } else {
    const std::string s = j.get<std::string>();
    char* end = nullptr;
    std::strtod(s.c_str(), &end);
    if (s.empty() || s == "true" || (end != s.c_str() && *end == '\0')) {
      EXPECT_EQ(y.Tag(), "!") << where << ": '" << s << "' must stay a quoted string";
    }
    EXPECT_EQ(y.as<std::string>(), j.get<std::string>()) << where;
  }
}

TEST(ResultDocument, JsonAndYamlHaveTheSameKeysAndValues) {
  const io::ResultContext context = full_context();
  const nlohmann::json j = nlohmann::json::parse(io::result_json_text(report(), context));
  const YAML::Node y = YAML::Load(io::result_yaml_text(report(), context));
  expect_same_tree(j, y, "");

  // The keys and their meanings (docs/design.md section 2).
  for (const char* key : {"model",
                          "responsivity",
                          "responsivity_std",
                          "angles_deg",
                          "angles_std_deg",
                          "vectors",
                          "offset",
                          "offset_per_phase",
                          "cross_sensitivity",
                          "local_gravity",
                          "reduced_chi2",
                          "residual_rms",
                          "positions",
                          "effects",
                          "ambiguous",
                          "gap",
                          "fitted_effects",
                          "certificate_model",
                          "certificate_policy",
                          "model_label",
                          "timing_lag",
                          "stamp",
                          "samples",
                          "input",
                          "complete",
                          "warnings"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  ASSERT_TRUE(report().certificate_is_refit);
  EXPECT_EQ(j["model"], "joint");
  EXPECT_EQ(j["model_label"], report().certificate.model_label());
  EXPECT_EQ(j["certificate_model"], report().certificate.model_label());
  EXPECT_EQ(j["certificate_policy"], "refit");
  // fitted_effects: the terms of the certificate model; effects: what the analysis named.
  ASSERT_EQ(j["fitted_effects"].size(), report().certificate.effects.size());
  EXPECT_EQ(j["fitted_effects"][0]["name"], report().certificate.effects[0].name());
  EXPECT_EQ(j["effects"].size(), report().analysis->effects.size() + 1);  // + timing_lag
  // The noise the weights assumed and the out-of-sample gap (issue 23): white here.
  EXPECT_EQ(j["noise_model"], "white");
  EXPECT_TRUE(j["gap"]["before"]["cv_chi2_per_point"].is_number());
  EXPECT_TRUE(j["gap"]["after"]["cv_chi2_per_point"].is_number());
  EXPECT_LT(j["gap"]["after"]["cv_chi2_per_point"].get<double>(),
            j["gap"]["before"]["cv_chi2_per_point"].get<double>());
  ASSERT_EQ(j["noise_entries"].size(), 1u);
  EXPECT_EQ(j["noise_entries"][0]["name"], "correlated_noise");
  EXPECT_EQ(j["noise_entries"][0]["named"], false);
  EXPECT_EQ(j["samples"]["used"], 12345);
  EXPECT_EQ(j["samples"]["dropped_late"], 2);
  EXPECT_EQ(j["input"]["type"], "bag");
  EXPECT_EQ(j["complete"], false);
  EXPECT_EQ(j["stamp"], 1700000000.25);

  // Without context: no stamp, samples, input, complete, warnings; a CSV input: complete null.
  const nlohmann::json bare = nlohmann::json::parse(io::result_json_text(report(), {}));
  for (const char* key : {"stamp", "samples", "input", "complete", "warnings"}) {
    EXPECT_FALSE(bare.contains(key)) << key;
  }
  io::ResultContext csv;
  csv.input = io::InputDescription{"table.csv", 72, std::nullopt, "position table"};
  const nlohmann::json from_csv = nlohmann::json::parse(io::result_json_text(report(), csv));
  EXPECT_TRUE(from_csv["complete"].is_null());
  EXPECT_EQ(from_csv["input"],
            nlohmann::json({{"type", "csv"}, {"path", "table.csv"}, {"rows", 72}}));
}

void expect_certificate(const io::StoredResult& got, const FitResult& want) {
  EXPECT_EQ(got.model, want.model);
  EXPECT_EQ(got.model_label, want.model_label());
  EXPECT_EQ(got.S, want.S);
  EXPECT_EQ(got.O, want.O);
  EXPECT_EQ(got.cross_sensitivity, want.cross_sensitivity);
  EXPECT_EQ(got.local_gravity, want.local_gravity);
  EXPECT_EQ(got.intrinsics.responsivity, want.intrinsics.responsivity);
  EXPECT_EQ(got.intrinsics.responsivity_std, want.intrinsics.responsivity_std);
  for (int i = 0; i < 3; ++i) {
    // Through degrees and back: equal to the last few bits.
    EXPECT_NEAR(got.intrinsics.angles_rad(i), want.intrinsics.angles_rad(i), 1e-15);
    EXPECT_NEAR(got.intrinsics.angles_std_rad(i), want.intrinsics.angles_std_rad(i), 1e-18);
  }
  ASSERT_EQ(got.fitted_effects.size(), want.effects.size());
  for (std::size_t i = 0; i < want.effects.size(); ++i) {
    EXPECT_EQ(got.fitted_effects[i].name, want.effects[i].name());
    EXPECT_EQ(got.fitted_effects[i].target, want.effects[i].target_name());
    EXPECT_EQ(got.fitted_effects[i].value, want.effects[i].value);
    EXPECT_EQ(got.fitted_effects[i].std, want.effects_std[i]);
  }
}

TEST(ResultDocument, ReadBackFromBothWriters) {
  TempDir dir;
  io::write_result_json(dir.file("r.json"), report(), full_context());
  io::write_result_yaml(dir.file("r.yaml"), report(), full_context());
  expect_certificate(io::read_result_file(dir.file("r.json")), report().certificate);
  expect_certificate(io::read_result_file(dir.file("r.yaml")), report().certificate);
  EXPECT_EQ(dir.entries(), (std::set<std::string>{"r.json", "r.yaml"})) << "no temporary file left";

  // An eq4 base fit without analysis.
  CalibrationReport eq4;
  CalibrateOptions options;
  options.fit.model = FitModel::Eq4;
  SimulationOptions sim;
  eq4 = calibrate(simulate_position_table(sim), nullptr, options);
  io::write_result_yaml(dir.file("eq4.yaml"), eq4, {});
  const io::StoredResult got = io::read_result_file(dir.file("eq4.yaml"));
  EXPECT_EQ(got.model, FitModel::Eq4);
  expect_certificate(got, eq4.certificate);
}

TEST(ResultDocument, ReadsAnOldNodeYamlWhoseEffectsWereTheFittedTerms) {
  TempDir dir;
  std::ofstream(dir.file("old.yaml"))
      << "# accel_intrinsics calibration result (keys as offline_fit's JSON, docs/design.md)\n"
         "stamp: 1700000000.5\n"
         "model: joint+quadratic_nonlinearity[u]\n"
         "responsivity:\n  u: 1.01\n  v: 0.99\n  w: 1.02\n"
         "responsivity_std:\n  u: 1e-05\n  v: 2e-05\n  w: 3e-05\n"
         "angles_deg:\n  uv: 90.1\n  vw: 89.9\n  wu: 90\n"
         "angles_std_deg:\n  uv: 0.001\n  vw: 0.002\n  wu: 0.003\n"
         "vectors:\n  u: [1.01, 0, 0]\n  v: [0, 0.99, 0]\n  w: [0, 0, 1.02]\n"
         "offset:\n  u: 0.1\n  v: -0.2\n  w: 0.05\n"
         "offset_std:\n  u: 1e-4\n  v: 1e-4\n  w: 1e-4\n"
         "offset_per_phase:\n  u: {x: 0.1, y: 0.1, z: 0.1}\n  v: {x: -0.2, y: -0.2, z: -0.2}\n"
         "  w: {x: 0.05, y: 0.05, z: 0.05}\n"
         "cross_sensitivity:\n  - [0.990099, 0, 0]\n  - [0, 1.010101, 0]\n  - [0, 0, 0.980392]\n"
         "effects:\n  - {name: quadratic_nonlinearity, target: u, value: 0.0004, std: 2e-06}\n"
         "local_gravity: 9.80665\nreduced_chi2: 1.02\nresidual_rms: 0.0003\n"
         "positions: {x: 24, y: 24, z: 24}\n"
         "samples:\n  used: 100\n  dropped_outside_dwell: 3\n";
  const io::StoredResult r = io::read_result_file(dir.file("old.yaml"));
  EXPECT_EQ(r.model, FitModel::Joint);
  EXPECT_EQ(r.model_label, "joint+quadratic_nonlinearity[u]");
  EXPECT_EQ(r.intrinsics.responsivity(1), 0.99);
  EXPECT_NEAR(r.intrinsics.angles_rad(0), deg_to_rad(90.1), 1e-15);
  EXPECT_EQ(r.S(2, 2), 1.02);
  EXPECT_EQ(r.O(1), -0.2);
  EXPECT_EQ(r.cross_sensitivity(1, 1), 1.010101);
  EXPECT_EQ(r.local_gravity, 9.80665);
  ASSERT_EQ(r.fitted_effects.size(), 1u);
  EXPECT_EQ(r.fitted_effects[0].name, "quadratic_nonlinearity");
  EXPECT_EQ(r.fitted_effects[0].target, "u");
  EXPECT_EQ(r.fitted_effects[0].value, 0.0004);
}

TEST(ResultDocument, ReadErrorsNameThePathAndTheKey) {
  TempDir dir;
  try {
    io::read_result_file(dir.file("none.yaml"));
    FAIL() << "no IoError";
  } catch (const io::IoError& e) {
    EXPECT_NE(std::string(e.what()).find(dir.file("none.yaml")), std::string::npos) << e.what();
  }
  std::ofstream(dir.file("partial.json")) << "{\"model\": \"joint\", \"responsivity\": {}}\n";
  try {
    io::read_result_file(dir.file("partial.json"));
    FAIL() << "no IoError";
  } catch (const io::IoError& e) {
    EXPECT_NE(std::string(e.what()).find("responsivity.u"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("partial.json"), std::string::npos) << e.what();
  }
}

TEST(AtomicFile, FailureNamesThePathAndLeavesNoTemporaryFile) {
  TempDir dir;
  const std::string missing_dir_file = dir.file("no/such/dir/result.yaml");
  try {
    io::write_result_yaml(missing_dir_file, report(), {});
    FAIL() << "no IoError";
  } catch (const io::IoError& e) {
    EXPECT_NE(std::string(e.what()).find(missing_dir_file), std::string::npos) << e.what();
  }
  EXPECT_TRUE(dir.entries().empty());

  // An exception between writing and commit(): the old file stays, no temporary file remains.
  io::write_file_atomically(dir.file("result.json"), "old\n");
  try {
    io::AtomicFile file(dir.file("result.json"));
    file.stream() << "half a docu";
    throw std::runtime_error("writer failed");
  } catch (const std::runtime_error&) {
  }
  EXPECT_EQ(read_file(dir.file("result.json")), "old\n");
  EXPECT_EQ(dir.entries(), std::set<std::string>{"result.json"});
}

}  // namespace
}  // namespace accel_intrinsics
