// A setup mistake through the package's simulator and offline_fit (docs/design.md section 15; issue
// 33 item 4): a run whose phase y turned the wrong way (the simulator's gimbal-side angle_scale of
// -2 on phase y: true angle = -alpha) fails the quality gate with a reason that names axis_sign[y]
// and offers --unknown-orientations; --analyze names the mistake and no physical effect; and the
// advice holds: --unknown-orientations on the same table recovers the simulated intrinsics.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;
using nlohmann::json;

namespace {

class Dir {
 public:
  Dir() {
    char templ[] = "/tmp/offline_fit_setup_XXXXXX";
    path_ = ::mkdtemp(templ);
  }
  ~Dir() {
    if (!path_.empty()) std::system(("rm -rf '" + path_ + "'").c_str());
  }
  std::string file(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

struct ToolOutput {
  int status = -1;
  std::string out;
  std::string err;
};

ToolOutput offline_fit(const std::vector<std::string>& args) {
  ai::OfflineFitArguments a;
  int status = 0;
  std::ostringstream out, err;
  ToolOutput r;
  if (!ai::parse_offline_fit_arguments(args, &a, &status, out, err)) {
    ADD_FAILURE() << "the command line did not parse: " << err.str();
    return r;
  }
  r.status = ai::run_offline_fit(a, out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

json load(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return json::parse(s.str());
}

core::SimulationOptions wrong_sign_run() {
  core::SimulationOptions sim;
  sim.truth.S << 1.02, 0.01, -0.005, 0.003, 0.98, 0.02, -0.01, 0.015, 1.005;
  sim.truth.O << 0.05, -0.1, 0.08;
  // Phase y turns the other way: true angle = alpha (1 + eps) = -alpha.
  sim.truth.effects.push_back(core::Effect{core::EffectKind::AngleScale, 1, -2.0});
  sim.protocol.steps_per_phase = 12;
  sim.seed = 9;
  return sim;
}

TEST(OfflineFitSetupMistake, GateNamesAxisSignAndOffersUnknownOrientations) {
  Dir dir;
  const core::SimulationOptions sim = wrong_sign_run();
  core::write_position_table_file(dir.file("table.csv"), core::simulate_position_table(sim));
  const ToolOutput r = offline_fit({"--csv", dir.file("table.csv"), "--json", dir.file("r.json")});
  ASSERT_EQ(r.status, 3) << r.err;  // the quality gate
  EXPECT_NE(r.err.find("axis_sign[y]"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--unknown-orientations"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("wrong g or units"), std::string::npos) << r.err;
  const json j = load(dir.file("r.json"));
  ASSERT_FALSE(j["quality"]["pass"].get<bool>());
  const std::string first = j["quality"]["reasons"][0].get<std::string>();
  EXPECT_EQ(first.rfind("setup mistake axis_sign[y]", 0), 0u) << first;
  EXPECT_NE(first.find("phases.y.sign"), std::string::npos) << first;

  // The analysis names the mistake first and no physical effect (today: cubic_nonlinearity[u],
  // angle_offset[y]).
  const ToolOutput a =
      offline_fit({"--csv", dir.file("table.csv"), "--analyze", "--json", dir.file("a.json")});
  EXPECT_EQ(a.status, 3) << a.err;
  const json ja = load(dir.file("a.json"));
  ASSERT_TRUE(ja["setup_mistakes"].is_array()) << ja.dump();
  ASSERT_FALSE(ja["setup_mistakes"].empty());
  EXPECT_EQ(ja["setup_mistakes"][0]["name"], "axis_sign");
  EXPECT_EQ(ja["setup_mistakes"][0]["target"], "y");
  EXPECT_TRUE(ja["effects"].empty()) << ja["effects"].dump();

  // The second opinion: the same rests without gimbal angles give the simulated intrinsics.
  const ToolOutput t = offline_fit(
      {"--csv", dir.file("table.csv"), "--unknown-orientations", "--json", dir.file("t.json")});
  ASSERT_EQ(t.status, 0) << t.err;
  const json jt = load(dir.file("t.json"));
  const char* names[3] = {"u", "v", "w"};
  for (int s = 0; s < 3; ++s) {
    const double fitted = jt["responsivity"][names[s]].get<double>();
    const double std = jt["responsivity_std"][names[s]].get<double>();
    EXPECT_NEAR(fitted, sim.truth.S.row(s).norm(), 5.0 * std) << names[s];
  }
}

// The same simulator without the mistake: the gate passes and nothing is named.
TEST(OfflineFitSetupMistake, CleanRunNamesNone) {
  Dir dir;
  core::SimulationOptions sim = wrong_sign_run();
  sim.truth.effects.clear();
  core::write_position_table_file(dir.file("table.csv"), core::simulate_position_table(sim));
  const ToolOutput a =
      offline_fit({"--csv", dir.file("table.csv"), "--analyze", "--json", dir.file("a.json")});
  ASSERT_EQ(a.status, 0) << a.err;
  const json ja = load(dir.file("a.json"));
  EXPECT_TRUE(ja["setup_mistakes"].empty()) << ja["setup_mistakes"].dump();
  EXPECT_TRUE(ja["quality"]["pass"].get<bool>());
}

}  // namespace
