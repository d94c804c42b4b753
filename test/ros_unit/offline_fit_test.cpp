// offline_fit end to end, without a roscore: the test writes bags (test_support::BagWriter) and
// CSV files, runs offline_fit in process (run_offline_fit of ros/offline_fit.h, with the arguments
// the command line would give) and checks exit status, stderr and the JSON/CSV it writes. A few
// smoke tests run the built binary (--help, command-line errors, one bag and one CSV run); it is
// found next to this test binary (catkin puts both in devel/lib/accel_intrinsics) or through the
// environment variable ACCEL_OFFLINE_FIT.
#include "accel_intrinsics/ros/offline_fit.h"

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Imu.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "../support/bag_writer.h"
#include "../support/statistical_bounds.h"
#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/ros/bag_input.h"
#include "accel_intrinsics/ros/conversions.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;
using nlohmann::json;

namespace {

constexpr double kG = 9.80665;
constexpr double kPi = 3.14159265358979323846;

// ---- running the tool ---------------------------------------------------------------------------

std::string offline_fit_binary() {
  if (const char* env = std::getenv("ACCEL_OFFLINE_FIT")) return env;
  char self[4096];
  const ssize_t n = ::readlink("/proc/self/exe", self, sizeof(self) - 1);
  if (n > 0) {
    self[n] = '\0';
    std::string dir(self);
    dir = dir.substr(0, dir.rfind('/'));
    return dir + "/offline_fit";
  }
  return "offline_fit";
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

bool file_exists(const std::string& path) {
  struct stat info;
  return ::stat(path.c_str(), &info) == 0;
}

std::string quote(const std::string& arg) {
  std::string out = "'";
  for (char c : arg) out += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

int count_lines(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

class TempDir {
 public:
  TempDir() {
    char templ[] = "/tmp/offline_fit_test_XXXXXX";
    path_ = ::mkdtemp(templ);
  }
  ~TempDir() {
    if (!path_.empty() && std::getenv("KEEP_TEST_FILES") == nullptr) {
      std::system(("rm -rf " + quote(path_)).c_str());
    }
  }
  std::string file(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

struct ToolRun {
  int status = -1;
  std::string out;
  std::string err;
};

// The built binary with `args`, through the shell (the command-line smoke tests).
ToolRun run_binary(const std::vector<std::string>& args, const TempDir& dir) {
  std::string command = quote(offline_fit_binary());
  for (const std::string& a : args) command += " " + quote(a);
  const std::string out = dir.file("stdout.txt");
  const std::string err = dir.file("stderr.txt");
  command += " >" + quote(out) + " 2>" + quote(err);
  const int raw = std::system(command.c_str());
  ToolRun r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + (WIFSIGNALED(raw) ? WTERMSIG(raw) : 0);
  r.out = read_file(out);
  r.err = read_file(err);
  return r;
}

// What the command line gives run_offline_fit for `args`: the tool's own parser (well-formed
// options only: values that do not parse are the binary's business, see run_binary).
ai::OfflineFitArguments parse_arguments(const std::vector<std::string>& args) {
  ai::OfflineFitArguments a;
  int status = 0;
  std::ostringstream out, err;
  if (!ai::parse_offline_fit_arguments(args, &a, &status, out, err))
    ADD_FAILURE() << "the command line did not parse (" << status << "): " << err.str();
  return a;
}

// offline_fit in process with the arguments of `args`.
ToolRun run_tool(const std::vector<std::string>& args, const TempDir&) {
  std::ostringstream out, err;
  ToolRun r;
  r.status = ai::run_offline_fit(parse_arguments(args), out, err);
  r.out = out.str();
  r.err = err.str();
  return r;
}

// ---- writing bags
// ---------------------------------------------------------------------------------

// Messages are written with a bag (receive) time 1 ms after their stamp, as a recorder would, and
// IMU messages carry fields around linear_acceleration (and a frame id) the readers must skip.
class HandBagWriter : public ai::test_support::BagWriter {
 public:
  explicit HandBagWriter(const std::string& path) : BagWriter(path) {
    receive_delay_s = 0.001;
    padded_imu = true;
    frame_id = "dut_accelerometer_frame";
  }
  void imu(double t, const Eigen::Vector3d& r) { sample(t, r); }
};

// The device of the hand-made runs: R = S g f + O.
Eigen::Matrix3d device_S() {
  Eigen::Matrix3d S;
  S << 1.01, 0.02, -0.01, 0.0, 0.99, 0.03, 0.01, -0.02, 1.02;
  return S;
}
Eigen::Vector3d device_O() {
  return Eigen::Vector3d(0.1, -0.2, 0.05);
}

Eigen::Vector3d direction(int phase, double a) {
  if (phase == 0) return Eigen::Vector3d(0, std::sin(a), std::cos(a));
  if (phase == 1) return Eigen::Vector3d(std::sin(a), 0, std::cos(a));
  return Eigen::Vector3d(std::sin(a), std::cos(a), 0);
}

// One hand-made dwell: the samples written inside it and their mean and sample std computed here.
struct HandDwell {
  int phase;
  std::uint32_t step;
  double angle;
  std::vector<Eigen::Vector3d> samples;
  Eigen::Vector3d mean() const {
    Eigen::Vector3d m = Eigen::Vector3d::Zero();
    for (const auto& s : samples) m += s;
    return m / static_cast<double>(samples.size());
  }
  Eigen::Vector3d std() const {
    const Eigen::Vector3d m = mean();
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    for (const auto& s : samples) v += (s - m).cwiseAbs2();
    return (v / static_cast<double>(samples.size() - 1)).cwiseSqrt();
  }
};

struct HandRunOptions {
  std::uint32_t steps = 6;
  std::vector<int> phases{0, 1, 2};
  std::vector<std::uint32_t> dwells_per_phase;  // default: steps in each
  bool write_done = true;
  int nan_samples_per_dwell = 0;  // extra NaN samples inside each dwell (dropped and counted)
  std::string ns;                 // topic namespace, e.g. "/stand1"
};

// What the bag should produce.
struct HandRun {
  std::vector<HandDwell> dwells;
  std::uint64_t imu_messages = 0;
  std::uint64_t command_messages = 0;
  std::uint64_t dropped_outside = 0;
  std::uint64_t dropped_nan = 0;
  double first_command = 0.0;
};

// Timeline per position: MOVING at t; a sample while moving (dropped); SETTLED at t + 0.5 with a
// sample exactly at that stamp (kept: the dwell is [SETTLED, next MOVING)); 4 more samples 0.1 s
// apart; a sample exactly at the next MOVING or DONE stamp (dropped); after DONE, one more
// (dropped). The samples are the model value plus -2d, -d, 0, +d, +2d with d = 0.01 per axis.
HandRun write_hand_run(HandBagWriter& writer, const HandRunOptions& o) {
  HandRun run;
  const Eigen::Matrix3d S = device_S();
  const Eigen::Vector3d O = device_O();
  double t = 100.0;
  run.first_command = t;
  for (std::size_t pi = 0; pi < o.phases.size(); ++pi) {
    const int phase = o.phases[pi];
    const std::uint32_t n_dwells = o.dwells_per_phase.empty() ? o.steps : o.dwells_per_phase[pi];
    for (std::uint32_t step = 0; step < n_dwells; ++step) {
      const double angle = 2.0 * kPi * step / o.steps;
      writer.command(t, phase, step, o.steps, angle, ai::GimbalCommand::MOVING);
      ++run.command_messages;
      writer.imu(t + 0.2, Eigen::Vector3d(1000, 1000, 1000));  // moving: dropped
      ++run.imu_messages;
      ++run.dropped_outside;
      const double settled = t + 0.5;
      writer.command(settled, phase, step, o.steps, angle, ai::GimbalCommand::SETTLED);
      ++run.command_messages;
      HandDwell dwell{phase, step, angle, {}};
      const Eigen::Vector3d truth = S * (kG * direction(phase, angle)) + O;
      for (int k = 0; k < 5; ++k) {
        const Eigen::Vector3d r = truth + Eigen::Vector3d(0.01, 0.02, 0.03) * (k - 2) *
                                              (k % 2 ? 1.0 : -1.0);  // zero-mean pattern
        writer.imu(settled + 0.1 * k, r);
        ++run.imu_messages;
        dwell.samples.push_back(r);
        if (k < o.nan_samples_per_dwell) {
          writer.imu(settled + 0.1 * k + 0.05,
                     Eigen::Vector3d(std::numeric_limits<double>::quiet_NaN(), 1.0, 1.0));
          ++run.imu_messages;
          ++run.dropped_nan;
        }
      }
      t = settled + 0.5;
      writer.imu(t, Eigen::Vector3d(2000, 2000, 2000));  // at the next MOVING/DONE stamp: dropped
      ++run.imu_messages;
      ++run.dropped_outside;
      run.dwells.push_back(dwell);
    }
  }
  if (o.write_done) {
    writer.command(t, o.phases.back(), o.steps - 1, o.steps, 0.0, ai::GimbalCommand::DONE);
    ++run.command_messages;
    writer.imu(t + 0.3, Eigen::Vector3d(3000, 3000, 3000));  // after DONE: dropped
    ++run.imu_messages;
    ++run.dropped_outside;
  } else {
    // The last sample at t joined nothing in this case only if a MOVING/DONE came; without DONE
    // the last dwell stays open and takes it. Keep the expectations honest:
    run.dropped_outside -= 1;
  }
  return run;
}

HandRun make_hand_bag(const std::string& path, const HandRunOptions& o = {}) {
  HandBagWriter writer(path);
  if (!o.ns.empty()) {
    writer.imu_topic = o.ns + "/imu/data_raw";
    writer.command_topic = o.ns + "/gimbal/command";
  }
  HandRun run = write_hand_run(writer, o);
  writer.close();
  return run;
}

// Writes a simulated recording as a bag: merged by stamp, a command first at equal stamps, as the
// messages would arrive. The callbacks see each message as it is written.
void write_recording_bag(const std::string& path, const core::Recording& rec,
                         const std::function<void(const core::GimbalEvent&)>& on_command = {},
                         const std::function<void(const sensor_msgs::Imu&)>& on_sample = {}) {
  ai::test_support::BagWriter writer(path);
  writer.recording(rec, on_command, on_sample);
}

json load_json(const std::string& path) {
  return json::parse(read_file(path));
}

void expect_single_line_error(const ToolRun& r, const std::string& needle) {
  EXPECT_NE(r.status, 0);
  EXPECT_EQ(count_lines(r.err), 1) << r.err;
  EXPECT_NE(r.err.find("offline_fit: error: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << "expected '" << needle << "' in: " << r.err;
}

// The contract keys (docs/design.md section 2) and their shapes.
void expect_contract_keys(const json& j) {
  for (const char* key :
       {"model", "responsivity", "responsivity_std", "angles_deg", "angles_std_deg", "vectors",
        "offset", "offset_per_phase", "cross_sensitivity", "local_gravity", "reduced_chi2",
        "residual_rms", "positions"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  for (const char* s : {"u", "v", "w"}) {
    EXPECT_TRUE(j["responsivity"][s].is_number());
    EXPECT_TRUE(j["responsivity_std"][s].is_number());
    EXPECT_TRUE(j["offset"][s].is_number());
    EXPECT_EQ(j["vectors"][s].size(), 3u);
    for (const char* p : {"x", "y", "z"}) EXPECT_TRUE(j["offset_per_phase"][s][p].is_number());
  }
  for (const char* a : {"uv", "vw", "wu"}) {
    EXPECT_TRUE(j["angles_deg"][a].is_number());
    EXPECT_TRUE(j["angles_std_deg"][a].is_number());
  }
  ASSERT_EQ(j["cross_sensitivity"].size(), 3u);
  for (const auto& row : j["cross_sensitivity"]) EXPECT_EQ(row.size(), 3u);
  for (const char* p : {"x", "y", "z"}) EXPECT_TRUE(j["positions"][p].is_number_integer());
}

// The fit part of the JSON: everything but where the data came from.
json fit_part(json j) {
  j.erase("input");
  j.erase("complete");
  j.erase("warnings");
  j.erase("local_gravity_source");  // offline_fit's context, like the three above
  return j;
}

// ---- tests --------------------------------------------------------------------------------------

TEST(OfflineFit, BinaryIsThere) {
  ASSERT_TRUE(file_exists(offline_fit_binary()))
      << offline_fit_binary() << " missing; set ACCEL_OFFLINE_FIT to the built binary";
}

TEST(OfflineFit, HandMadeBagGivesHandComputedDwellMeans) {
  TempDir dir;
  const HandRun run = make_hand_bag(dir.file("run.bag"));
  const ToolRun r = run_tool({"--bag", dir.file("run.bag"), "--csv-out", dir.file("table.csv"),
                              "--json", dir.file("result.json")},
                             dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_NE(r.out.find("|u|"), std::string::npos) << r.out;

  const core::PositionTable table = core::read_position_table_file(dir.file("table.csv"));
  ASSERT_EQ(table.rows.size(), run.dwells.size());
  for (std::size_t i = 0; i < run.dwells.size(); ++i) {
    const HandDwell& d = run.dwells[i];
    const core::DwellRecord& row = table.rows[i];
    EXPECT_EQ(core::index(row.phase), d.phase) << i;
    EXPECT_EQ(row.step, d.step) << i;
    EXPECT_DOUBLE_EQ(row.angle_rad, d.angle) << i;
    EXPECT_EQ(row.n, d.samples.size()) << i;
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(row.mean(k), d.mean()(k), 1e-12) << "row " << i << " axis " << k;
      EXPECT_NEAR(row.std(k), d.std()(k), 1e-12) << "row " << i << " axis " << k;
    }
  }
  const json j = load_json(dir.file("result.json"));
  expect_contract_keys(j);
  EXPECT_EQ(j["model"], "joint");
  EXPECT_EQ(j["local_gravity"].get<double>(), kG);
  EXPECT_EQ(j["positions"]["x"], 6);
  EXPECT_EQ(j["complete"], true);
  EXPECT_EQ(j["input"]["imu_messages"].get<std::uint64_t>(), run.imu_messages);
  EXPECT_EQ(j["input"]["command_messages"].get<std::uint64_t>(), run.command_messages);
  EXPECT_EQ(j["input"]["dropped_outside_dwell"].get<std::uint64_t>(), run.dropped_outside);
  EXPECT_EQ(j["input"]["samples_used"].get<std::uint64_t>(), 5u * run.dwells.size());
  EXPECT_EQ(j["input"]["imu_topic"], "/imu/data_raw");
  // The zero-mean pattern leaves the dwell means on the model: the fit returns the device.
  const Eigen::Matrix3d S = device_S();
  const char* names[] = {"u", "v", "w"};
  for (int s = 0; s < 3; ++s) {
    EXPECT_NEAR(j["responsivity"][names[s]].get<double>(), S.row(s).norm(), 1e-9) << names[s];
    EXPECT_NEAR(j["offset"][names[s]].get<double>(), device_O()(s), 1e-9) << names[s];
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(j["vectors"][names[s]][c].get<double>(), S(s, c), 1e-9);
  }
  const double cos_uv = S.row(0).dot(S.row(1)) / (S.row(0).norm() * S.row(1).norm());
  EXPECT_NEAR(j["angles_deg"]["uv"].get<double>(), std::acos(cos_uv) * 180.0 / kPi, 1e-7);
  const Eigen::Matrix3d P = S.inverse();
  for (int r2 = 0; r2 < 3; ++r2)
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(j["cross_sensitivity"][r2][c].get<double>(), P(r2, c), 1e-9);
}

TEST(OfflineFit, CsvInEqualsBagIn) {
  TempDir dir;
  make_hand_bag(dir.file("run.bag"));
  for (const std::string model : {"joint", "eq4"}) {
    const ToolRun from_bag =
        run_tool({"--bag", dir.file("run.bag"), "--model", model, "--gravity", "9.8123",
                  "--csv-out", dir.file("table.csv"), "--json", dir.file("bag.json")},
                 dir);
    ASSERT_EQ(from_bag.status, 0) << from_bag.err;
    const ToolRun from_csv = run_tool({"--csv", dir.file("table.csv"), "--model", model,
                                       "--gravity", "9.8123", "--json", dir.file("csv.json")},
                                      dir);
    ASSERT_EQ(from_csv.status, 0) << from_csv.err;
    const json jb = load_json(dir.file("bag.json"));
    const json jc = load_json(dir.file("csv.json"));
    EXPECT_EQ(jb["model"], model);
    EXPECT_EQ(jb["local_gravity"].get<double>(), 9.8123);
    EXPECT_EQ(jc["input"]["type"], "csv");
    EXPECT_EQ(fit_part(jb), fit_part(jc)) << model;  // to the last digit
  }
}

TEST(OfflineFit, CsvRoundTripThroughCsvOut) {
  TempDir dir;
  make_hand_bag(dir.file("run.bag"));
  ASSERT_EQ(run_tool({"--bag", dir.file("run.bag"), "--csv-out", dir.file("a.csv")}, dir).status,
            0);
  const ToolRun r = run_tool({"--csv", dir.file("a.csv"), "--csv-out", dir.file("b.csv")}, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string a = read_file(dir.file("a.csv"));
  EXPECT_EQ(a.substr(0, a.find('\n')), core::kPositionTableHeader);
  EXPECT_EQ(a, read_file(dir.file("b.csv")));
  EXPECT_EQ(count_lines(a), 1 + 18);
}

TEST(OfflineFit, JsonToStdoutIsPureJson) {
  TempDir dir;
  make_hand_bag(dir.file("run.bag"));
  const ToolRun r = run_tool({"--bag", dir.file("run.bag"), "--json", "-"}, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = json::parse(r.out);  // throws (fails the test) on anything but JSON
  expect_contract_keys(j);
  EXPECT_NE(r.err.find("|u|"), std::string::npos);  // the report went to stderr
}

// The simulated stand: offline_fit equals the dwell assembly + fit done in process, message by
// message (the calibration node's code path), to the last digit, and finds the truth.
TEST(OfflineFit, SimulatedRecordingMatchesInProcessPipeline) {
  TempDir dir;
  core::SimulationOptions sim;
  sim.truth.S << 1.02, 0.01, -0.005, 0.003, 0.98, 0.02, -0.01, 0.015, 1.005;
  sim.truth.O = Eigen::Vector3d(0.05, -0.03, 0.12);
  sim.protocol.steps_per_phase = 8;
  sim.protocol.dwell_s = 1.0;
  sim.seed = 7;
  core::Recording rec = core::simulate_recording(sim);
  // The simulator's clock starts at 0; a bag needs positive times (the stand runs on wall time).
  for (auto& e : rec.commands) e.stamp_s += 1000.0;
  for (auto& e : rec.samples) e.stamp_s += 1000.0;
  ASSERT_FALSE(rec.commands.empty());
  ASSERT_FALSE(rec.samples.empty());

  // Write and feed alike, in the order the messages would arrive.
  core::DwellAssembler assembler;
  write_recording_bag(
      dir.file("sim.bag"), rec, [&](const core::GimbalEvent& e) { assembler.add_command(e); },
      [&](const sensor_msgs::Imu& msg) {
        assembler.add_sample(ai::to_core(msg));  // the stamp as it travels (ros::Time)
      });
  assembler.flush();
  const core::FitResult expected = core::fit(assembler.table());

  const ToolRun r = run_tool({"--bag", dir.file("sim.bag"), "--json", dir.file("sim.json")}, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = load_json(dir.file("sim.json"));
  core::CalibrationReport report;
  report.base_fit = report.certificate = expected;
  report.noise = core::dwell_noise(assembler.table());  // calibrate() adds the dwells' noise
  EXPECT_EQ(fit_part(j), fit_part(json::parse(ai::io::result_json_text(report, {}))));
  EXPECT_EQ(j["positions"]["z"], 8);
  const char* names[] = {"u", "v", "w"};
  for (int s = 0; s < 3; ++s) {
    const double std_s = j["responsivity_std"][names[s]].get<double>();
    EXPECT_GT(std_s, 0.0);
    EXPECT_NEAR(j["responsivity"][names[s]].get<double>(), sim.truth.S.row(s).norm(), 6 * std_s)
        << names[s];
  }
}

TEST(OfflineFit, AnalyzeNamesATimingLagHiddenInTheRawStreams) {
  // Only the raw streams around the moves show a lag between IMU stamps and the gimbal: a bag
  // carries them, so --analyze must estimate it, name it and recover its value.
  TempDir dir;
  core::SimulationOptions sim;
  sim.truth.S << 1.01, 0.004, -0.006, 0.002, 0.99, 0.01, -0.008, 0.005, 1.02;
  sim.truth.O = Eigen::Vector3d(0.02, -0.04, 0.06);
  const double lag_s = 0.010;
  sim.truth.effects = {core::make_effect("timing_lag", "all", lag_s)};
  sim.protocol.steps_per_phase = 8;
  sim.protocol.dwell_s = 1.0;
  sim.rate_hz = 200.0;
  sim.seed = 11;
  core::Recording rec = core::simulate_recording(sim);
  for (auto& e : rec.commands) e.stamp_s += 1000.0;  // a bag needs positive times
  for (auto& e : rec.samples) e.stamp_s += 1000.0;
  write_recording_bag(dir.file("lag.bag"), rec);
  const ToolRun r =
      run_tool({"--bag", dir.file("lag.bag"), "--analyze", "--json", dir.file("lag.json")}, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = load_json(dir.file("lag.json"));
  ASSERT_TRUE(j.contains("timing_lag")) << j.dump();
  EXPECT_TRUE(j["timing_lag"]["ok"].get<bool>()) << j["timing_lag"].dump();
  EXPECT_TRUE(j["timing_lag"]["detected"].get<bool>()) << j["timing_lag"].dump();
  const double value = j["timing_lag"]["value"].get<double>();
  const double std_s = j["timing_lag"]["std"].get<double>();
  EXPECT_GT(std_s, 0.0);
  // One run: k std with a two-sided tail of 1e-4 (3 std would fail 1 seed in 370).
  EXPECT_NEAR(value, lag_s, ai::statistical_bounds::normal_k(1e-4) * std_s);
  bool named = false;
  for (const auto& e : j["effects"])
    named = named || (e["name"] == "timing_lag" && e["target"] == "all");
  EXPECT_TRUE(named) << j["effects"].dump();
}

TEST(OfflineFit, NanSamplesAreDroppedCountedAndFitSucceeds) {
  TempDir dir;
  HandRunOptions o;
  o.nan_samples_per_dwell = 2;
  const HandRun run = make_hand_bag(dir.file("nan.bag"), o);
  const ToolRun r = run_tool({"--bag", dir.file("nan.bag"), "--json", dir.file("nan.json"),
                              "--csv-out", dir.file("nan.csv")},
                             dir);
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = load_json(dir.file("nan.json"));
  EXPECT_EQ(j["input"]["dropped_non_finite"].get<std::uint64_t>(), run.dropped_nan);
  EXPECT_EQ(run.dropped_nan, 2u * 18u);
  EXPECT_EQ(j["input"]["samples_used"].get<std::uint64_t>(), 5u * 18u);
  EXPECT_EQ(j["complete"], true);
  const core::PositionTable table = core::read_position_table_file(dir.file("nan.csv"));
  ASSERT_EQ(table.rows.size(), run.dwells.size());
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    EXPECT_EQ(table.rows[i].n, 5u);
    EXPECT_NEAR(table.rows[i].mean(0), run.dwells[i].mean()(0), 1e-12);
  }
  EXPECT_NEAR(j["responsivity"]["u"].get<double>(), device_S().row(0).norm(), 1e-9);
}

TEST(OfflineFit, NamespacedTopicsResolve) {
  TempDir dir;
  HandRunOptions o;
  o.ns = "/stand1";
  make_hand_bag(dir.file("ns.bag"), o);
  ToolRun r = run_tool({"--bag", dir.file("ns.bag"), "--json", dir.file("ns.json")}, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(load_json(dir.file("ns.json"))["input"]["imu_topic"], "/stand1/imu/data_raw");
  // Leading slash on the request: that exact topic.
  r = run_tool({"--bag", dir.file("ns.bag"), "--imu-topic", "/stand1/imu/data_raw",
                "--command-topic", "stand1/gimbal/command"},
               dir);
  EXPECT_EQ(r.status, 0) << r.err;
  r = run_tool({"--bag", dir.file("ns.bag"), "--imu-topic", "/imu/data_raw"}, dir);
  expect_single_line_error(r, "topic '/imu/data_raw' not found");
}

TEST(OfflineFit, TwoNamespacesNeedAChoice) {
  TempDir dir;
  {
    HandBagWriter writer(dir.file("two.bag"));
    writer.imu_topic = "/stand1/imu/data_raw";
    writer.command_topic = "/stand1/gimbal/command";
    write_hand_run(writer, {});
    writer.imu_topic = "/stand2/imu/data_raw";
    writer.command_topic = "/stand2/gimbal/command";
    write_hand_run(writer, {});
    writer.close();
  }
  ToolRun r = run_tool({"--bag", dir.file("two.bag")}, dir);
  expect_single_line_error(r, "ambiguous");
  EXPECT_NE(r.err.find("/stand2/imu/data_raw"), std::string::npos) << r.err;
  // Naming one topic picks the other from the same namespace.
  r = run_tool({"--bag", dir.file("two.bag"), "--imu-topic", "stand2/imu/data_raw", "--json",
                dir.file("t.json")},
               dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(load_json(dir.file("t.json"))["input"]["command_topic"], "/stand2/gimbal/command");
  r = run_tool({"--bag", dir.file("two.bag"), "--command-topic", "/stand1/gimbal/command", "--json",
                dir.file("t.json")},
               dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(load_json(dir.file("t.json"))["input"]["imu_topic"], "/stand1/imu/data_raw");
}

// --settle-discard S drops the samples of the first S seconds after each SETTLED stamp. In the
// hand-made run the kept samples sit at SETTLED + 0, 0.1, 0.2, 0.3, 0.4 s: with S = 0.25 the
// first three of each dwell go, n = 2, and the means are those of the last two samples. Two
// samples per dwell fail the quality gate: the outputs are written and the exit status is 3.
TEST(OfflineFit, SettleDiscardDropsTheFirstSecondsOfEachDwell) {
  TempDir dir;
  const HandRun run = make_hand_bag(dir.file("run.bag"));
  const ToolRun r = run_tool({"--bag", dir.file("run.bag"), "--settle-discard", "0.25", "--csv-out",
                              dir.file("table.csv"), "--json", dir.file("result.json")},
                             dir);
  ASSERT_EQ(r.status, ai::kOfflineFitQualityFailed) << r.err;
  EXPECT_NE(r.err.find("has 2 samples, fewer than 3"), std::string::npos) << r.err;
  const core::PositionTable table = core::read_position_table_file(dir.file("table.csv"));
  ASSERT_EQ(table.rows.size(), run.dwells.size());
  for (std::size_t i = 0; i < run.dwells.size(); ++i) {
    const HandDwell& d = run.dwells[i];
    const core::DwellRecord& row = table.rows[i];
    EXPECT_EQ(row.n, 2u) << i;
    const Eigen::Vector3d mean = (d.samples[3] + d.samples[4]) / 2.0;
    const Eigen::Vector3d std = (d.samples[3] - d.samples[4]).cwiseAbs() / std::sqrt(2.0);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(row.mean(k), mean(k), 1e-12) << "row " << i << " axis " << k;
      EXPECT_NEAR(row.std(k), std(k), 1e-12) << "row " << i << " axis " << k;
    }
  }
  const json j = load_json(dir.file("result.json"));
  EXPECT_FALSE(j["quality"]["pass"].get<bool>());
  EXPECT_EQ(j["quality"]["reasons"].size(), 1u);
  EXPECT_EQ(j["input"]["settle_discard_s"].get<double>(), 0.25);
  EXPECT_EQ(j["input"]["samples_used"].get<std::uint64_t>(), 2u * run.dwells.size());
  EXPECT_EQ(j["input"]["dropped_settle_discard"].get<std::uint64_t>(), 3u * run.dwells.size());
  EXPECT_EQ(j["input"]["dropped_outside_dwell"].get<std::uint64_t>(), run.dropped_outside);

  // The built binary, as a shell sees it: exit status 3 (the number, not the enum), the result
  // file written, the export asked for not.
  const ToolRun bin =
      run_binary({"--bag", dir.file("run.bag"), "--settle-discard", "0.25", "--json",
                  dir.file("bin.json"), "--export", "px4=" + dir.file("bin_px4.params")},
                 dir);
  EXPECT_EQ(bin.status, 3) << bin.err;
  EXPECT_FALSE(load_json(dir.file("bin.json"))["quality"]["pass"].get<bool>());
  EXPECT_FALSE(file_exists(dir.file("bin_px4.params"))) << bin.err;
  EXPECT_NE(bin.err.find("has 2 samples, fewer than 3"), std::string::npos) << bin.err;

  // 0 (the default, spelled out) is the old behaviour: all five samples.
  const ToolRun zero = run_tool(
      {"--bag", dir.file("run.bag"), "--settle-discard", "0", "--json", dir.file("zero.json")},
      dir);
  ASSERT_EQ(zero.status, 0) << zero.err;
  const json z = load_json(dir.file("zero.json"));
  EXPECT_EQ(z["input"]["samples_used"].get<std::uint64_t>(), 5u * run.dwells.size());
  EXPECT_EQ(z["input"]["dropped_settle_discard"].get<std::uint64_t>(), 0u);

  // Refused: negative, not a number, with --csv.
  ToolRun bad = run_tool({"--bag", dir.file("run.bag"), "--settle-discard", "-1"}, dir);
  EXPECT_EQ(bad.status, 2);
  expect_single_line_error(bad, "--settle-discard");
  bad = run_tool({"--csv", dir.file("table.csv"), "--settle-discard", "0.1"}, dir);
  EXPECT_EQ(bad.status, 2);
  expect_single_line_error(bad, "--settle-discard applies to --bag only");
}

// ---- bad input ----------------------------------------------------------------------------------

TEST(OfflineFitBadInput, MissingFile) {
  TempDir dir;
  const ToolRun r = run_tool({"--bag", dir.file("nope.bag"), "--json", dir.file("out.json")}, dir);
  EXPECT_EQ(r.status, 1);
  expect_single_line_error(r, "No such file");
  EXPECT_NE(r.err.find("nope.bag"), std::string::npos);
  EXPECT_FALSE(file_exists(dir.file("out.json")));
  const ToolRun c = run_tool({"--csv", dir.file("nope.csv")}, dir);
  EXPECT_EQ(c.status, 1);
  expect_single_line_error(c, "nope.csv");
}

TEST(OfflineFitBadInput, TruncatedBag) {
  TempDir dir;
  make_hand_bag(dir.file("run.bag"));
  const std::string full = read_file(dir.file("run.bag"));
  for (double fraction : {0.5, 0.9, 0.02}) {
    const std::string cut = dir.file("cut.bag");
    std::ofstream(cut, std::ios::binary)
        << full.substr(0, static_cast<std::size_t>(full.size() * fraction));
    const ToolRun r = run_tool(
        {"--bag", cut, "--json", dir.file("out.json"), "--csv-out", dir.file("out.csv")}, dir);
    EXPECT_EQ(r.status, 1) << fraction;
    expect_single_line_error(r, "cannot read bag");
    EXPECT_NE(r.err.find("truncated"), std::string::npos) << r.err;
    EXPECT_FALSE(file_exists(dir.file("out.json")));
    EXPECT_FALSE(file_exists(dir.file("out.csv")));
  }
}

TEST(OfflineFitBadInput, CorruptBag) {
  TempDir dir;
  // Not a bag at all.
  std::ofstream(dir.file("text.bag")) << "this is not a bag\n";
  ToolRun r = run_tool({"--bag", dir.file("text.bag")}, dir);
  EXPECT_EQ(r.status, 1);
  expect_single_line_error(r, "not a ROS bag");
  // A real bag with its chunk data overwritten (index intact): error, not a crash or a result.
  make_hand_bag(dir.file("run.bag"));
  std::string bytes = read_file(dir.file("run.bag"));
  // Past the version line, the file header and the connection records at the start of the chunk:
  // the middle fifth of the file holds message records.
  for (std::size_t i = bytes.size() * 2 / 5; i < bytes.size() * 3 / 5; ++i) {
    bytes[i] = static_cast<char>((i * 2654435761u) >> 13);
  }
  std::ofstream(dir.file("garbled.bag"), std::ios::binary) << bytes;
  r = run_tool({"--bag", dir.file("garbled.bag"), "--json", dir.file("g.json")}, dir);
  EXPECT_EQ(r.status, 1) << r.out;
  expect_single_line_error(r, "bag");
  EXPECT_FALSE(file_exists(dir.file("g.json")));
}

TEST(OfflineFitBadInput, MissingTopicIsNamedAndBagTopicsListed) {
  TempDir dir;
  make_hand_bag(dir.file("run.bag"));
  ToolRun r = run_tool({"--bag", dir.file("run.bag"), "--imu-topic", "accel/raw"}, dir);
  EXPECT_EQ(r.status, 1);
  expect_single_line_error(r, "topic 'accel/raw' not found");
  EXPECT_NE(r.err.find("/imu/data_raw (sensor_msgs/Imu"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("/gimbal/command (accel_intrinsics/GimbalCommand"), std::string::npos)
      << r.err;

  // A bag with IMU data only is a hand tumble (docs/design.md section 11); one second of the device
  // lying still has one rest, far too few.
  {
    HandBagWriter writer(dir.file("imu_only.bag"));
    for (int i = 0; i < 100; ++i) writer.imu(100 + 0.01 * i, Eigen::Vector3d(0, 0, kG));
    writer.close();
  }
  r = run_tool({"--bag", dir.file("imu_only.bag"), "--rest-min-s", "0.2"}, dir);
  EXPECT_EQ(r.status, 1);
  expect_single_line_error(r, "no gimbal commands");
  EXPECT_NE(r.err.find("1 rests found in the stream"), std::string::npos) << r.err;
  // A command topic named but absent from a bag that has none: still a tumble, named.
  r = run_tool({"--bag", dir.file("imu_only.bag"), "--command-topic", "stand/gimbal/command"}, dir);
  EXPECT_EQ(r.status, 1);
  expect_single_line_error(r, "no gimbal commands");

  // Right name, wrong type.
  r = run_tool({"--bag", dir.file("run.bag"), "--imu-topic", "gimbal/command"}, dir);
  expect_single_line_error(r, "has type accel_intrinsics/GimbalCommand, expected sensor_msgs/Imu");
}

TEST(OfflineFitBadInput, MalformedCsvRowNamesItsLine) {
  TempDir dir;
  make_hand_bag(dir.file("run.bag"));
  ASSERT_EQ(run_tool({"--bag", dir.file("run.bag"), "--csv-out", dir.file("good.csv")}, dir).status,
            0);
  std::istringstream in(read_file(dir.file("good.csv")));
  std::string line;
  std::vector<std::string> lines;
  while (std::getline(in, line)) lines.push_back(line);
  ASSERT_GT(lines.size(), 6u);

  auto with_line5 = [&](const std::string& replacement, const std::string& name) {
    std::vector<std::string> copy = lines;
    copy[4] = replacement;  // line 5 of the file
    {
      std::ofstream out(dir.file(name));
      for (const auto& l : copy) out << l << "\n";
    }
    return run_tool({"--csv", dir.file(name), "--json", dir.file("bad.json")}, dir);
  };
  ToolRun r = with_line5("x,3,0.5,1,2,10,1.0,oops,3.0,0.1,0.1,0.1", "word.csv");
  EXPECT_EQ(r.status, 1);
  expect_single_line_error(r, "line 5");
  EXPECT_NE(r.err.find("mean_v"), std::string::npos) << r.err;
  r = with_line5("x,3,0.5,1,2,10,1.0", "short.csv");
  expect_single_line_error(r, "line 5");
  r = with_line5("q,3,0.5,1,2,10,1.0,2.0,3.0,0.1,0.1,0.1", "phase.csv");
  expect_single_line_error(r, "line 5");
  r = with_line5("x,3,0.5,1,2,10,1.0,nan,3.0,0.1,0.1,0.1", "nan.csv");
  expect_single_line_error(r, "line 5");
  EXPECT_FALSE(file_exists(dir.file("bad.json")));
}

// eq4 needs the three phases; joint fits a run missing one (two phases determine S and O) and
// marks it incomplete, naming the phase.
TEST(OfflineFitBadInput, MissingPhaseIsNamed) {
  TempDir dir;
  HandRunOptions o;
  o.phases = {0, 1};
  make_hand_bag(dir.file("xy.bag"), o);
  ToolRun r = run_tool(
      {"--bag", dir.file("xy.bag"), "--model", "eq4", "--json", dir.file("out.json")}, dir);
  EXPECT_EQ(r.status, 1);
  expect_single_line_error(r, "phase z is missing");
  EXPECT_FALSE(file_exists(dir.file("out.json")));

  o.phases = {0, 2};
  make_hand_bag(dir.file("xz.bag"), o);
  r = run_tool({"--bag", dir.file("xz.bag"), "--model", "eq4"}, dir);
  expect_single_line_error(r, "phase y is missing");

  r = run_tool({"--bag", dir.file("xz.bag"), "--json", dir.file("xz.json")}, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("warning: incomplete run"), std::string::npos) << r.err;
  const json j = load_json(dir.file("xz.json"));
  EXPECT_EQ(j["complete"], false);
  EXPECT_NE(j["warnings"].dump().find("phase y is missing: fitted by joint"), std::string::npos);
  EXPECT_EQ(j["positions"]["y"], 0);
}

TEST(OfflineFitBadInput, TooFewDwells) {
  TempDir dir;
  HandRunOptions o;
  o.dwells_per_phase = {6, 2, 6};
  make_hand_bag(dir.file("few.bag"), o);
  const ToolRun r = run_tool({"--bag", dir.file("few.bag")}, dir);
  EXPECT_EQ(r.status, 1);
  expect_single_line_error(r, "too few dwells in phase y: 2");
}

// A run cut short (no DONE, last dwell open, positions missing): a result is given, but marked
// incomplete in the report, the JSON and on stderr, never as complete.
TEST(OfflineFitBadInput, IncompleteRunIsMarked) {
  TempDir dir;
  HandRunOptions o;
  o.dwells_per_phase = {6, 6, 4};
  o.write_done = false;
  make_hand_bag(dir.file("cut.bag"), o);
  const ToolRun r = run_tool({"--bag", dir.file("cut.bag"), "--json", dir.file("cut.json")}, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("INCOMPLETE"), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("warning: incomplete run"), std::string::npos) << r.err;
  const json j = load_json(dir.file("cut.json"));
  EXPECT_EQ(j["complete"], false);
  EXPECT_EQ(j["positions"]["z"], 3);  // the 4th dwell of z never closed
  const std::string warnings = j["warnings"].dump();
  EXPECT_NE(warnings.find("DONE"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("phase z: 3 of 6"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("still open"), std::string::npos) << warnings;
}

TEST(OfflineFitBadInput, CommandLine) {
  TempDir dir;
  make_hand_bag(dir.file("run.bag"));
  ToolRun r = run_tool({}, dir);
  EXPECT_EQ(r.status, 2);
  expect_single_line_error(r, "exactly one of --bag FILE, --csv FILE or --samples FILE");
  r = run_tool({"--bag", dir.file("run.bag"), "--csv", dir.file("x.csv")}, dir);
  EXPECT_EQ(r.status, 2);
  expect_single_line_error(r, "exactly one of");
  r = run_tool({"--bag", dir.file("run.bag"), "--model", "eq5"}, dir);
  EXPECT_EQ(r.status, 2);
  expect_single_line_error(r, "--model");
  r = run_tool({"--bag", dir.file("run.bag"), "--gravity", "980.665"}, dir);
  EXPECT_EQ(r.status, 2);
  expect_single_line_error(r, "--gravity 980.665");
}

// ---- the command line (the binary)
// ---------------------------------------------------------------

TEST(OfflineFitCommandLine, HelpAndBadArguments) {
  TempDir dir;
  make_hand_bag(dir.file("run.bag"));
  ToolRun r = run_binary({"--bag", dir.file("run.bag"), "--gravity", "abc"}, dir);
  EXPECT_EQ(r.status, 2);
  expect_single_line_error(r, "gravity");
  r = run_binary({"--bag", dir.file("run.bag"), "--frobnicate"}, dir);
  EXPECT_EQ(r.status, 2);
  expect_single_line_error(r, "frobnicate");
  r = run_binary({"--bag", dir.file("run.bag"), "--settle-discard", "abc"}, dir);
  EXPECT_EQ(r.status, 2);
  expect_single_line_error(r, "settle-discard");
  r = run_binary({"--bag", dir.file("run.bag"), "--model", "eq5"}, dir);
  EXPECT_EQ(r.status, 2);
  expect_single_line_error(r, "--model");
  r = run_binary({"--help"}, dir);
  EXPECT_EQ(r.status, 0);
  for (const char* opt : {"--bag", "--csv", "--imu-topic", "--command-topic", "--gravity",
                          "--model", "--analyze", "--json", "--csv-out", "--settle-discard"}) {
    EXPECT_NE(r.out.find(opt), std::string::npos) << opt;
  }
}

// One bag run and one CSV run through the binary: the same files and report as in process.
TEST(OfflineFitCommandLine, BagAndCsvRunsEqualTheLibrary) {
  TempDir dir;
  make_hand_bag(dir.file("run.bag"));
  const ToolRun bin = run_binary({"--bag", dir.file("run.bag"), "--json", dir.file("bin.json"),
                                  "--csv-out", dir.file("bin.csv")},
                                 dir);
  ASSERT_EQ(bin.status, 0) << bin.err;
  EXPECT_EQ(bin.err, "");
  const ToolRun lib = run_tool({"--bag", dir.file("run.bag"), "--json", dir.file("lib.json"),
                                "--csv-out", dir.file("lib.csv")},
                               dir);
  ASSERT_EQ(lib.status, 0) << lib.err;
  EXPECT_EQ(read_file(dir.file("bin.csv")), read_file(dir.file("lib.csv")));
  json jb = load_json(dir.file("bin.json"));
  json jl = load_json(dir.file("lib.json"));
  jb["input"].erase("read_wall_s");  // wall time of the read
  jl["input"].erase("read_wall_s");
  EXPECT_EQ(jb, jl);

  const ToolRun csv =
      run_binary({"--csv", dir.file("bin.csv"), "--model", "eq4", "--json", "-"}, dir);
  ASSERT_EQ(csv.status, 0) << csv.err;
  const ToolRun csv_lib =
      run_tool({"--csv", dir.file("bin.csv"), "--model", "eq4", "--json", "-"}, dir);
  EXPECT_EQ(csv.out, csv_lib.out);  // the JSON on stdout
  EXPECT_EQ(csv.err, csv_lib.err);  // the report on stderr
  EXPECT_EQ(json::parse(csv.out)["model"], "eq4");
}

// --analyze adds the analysis keys of the contract (the analysis is always built in: the run
// must succeed and carry them).
TEST(OfflineFit, AnalyzeAddsContractKeys) {
  TempDir dir;
  make_hand_bag(dir.file("run.bag"));
  const ToolRun r =
      run_tool({"--bag", dir.file("run.bag"), "--analyze", "--json", dir.file("a.json")}, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = load_json(dir.file("a.json"));
  expect_contract_keys(j);
  ASSERT_TRUE(j.contains("effects") && j.contains("ambiguous") && j.contains("gap")) << j.dump();
  EXPECT_TRUE(j["effects"].is_array());
  EXPECT_TRUE(j["ambiguous"].is_array());
  for (const char* when : {"before", "after"}) {
    EXPECT_TRUE(j["gap"][when]["reduced_chi2"].is_number()) << when;
    EXPECT_TRUE(j["gap"][when]["rms"].is_number()) << when;
  }
  EXPECT_EQ(j["model"], "joint");  // the analysis never replaces the main result's keys
}

// --csv with --analyze (a promise of the README): the analysis of a position table, without the
// raw streams, so without the timing lag; an effect hidden in the table is named.
TEST(OfflineFit, CsvWithAnalyzeNamesAHiddenEffect) {
  TempDir dir;
  core::SimulationOptions sim;
  sim.truth.S << 1.02, 0.01, -0.005, 0.003, 0.98, 0.02, -0.01, 0.015, 1.005;
  sim.truth.effects.push_back(
      core::Effect{core::EffectKind::AngleOffset, 1, 0.0015});  // y, 0.09 deg
  sim.protocol.steps_per_phase = 12;
  sim.seed = 5;
  core::write_position_table_file(dir.file("table.csv"), core::simulate_position_table(sim));
  const ToolRun r =
      run_tool({"--csv", dir.file("table.csv"), "--analyze", "--json", dir.file("a.json")}, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  const json j = load_json(dir.file("a.json"));
  ASSERT_TRUE(j["effects"].is_array()) << j.dump();
  ASSERT_FALSE(j["effects"].empty()) << j["effects"].dump();
  EXPECT_NE(j["effects"].dump().find("angle_offset"), std::string::npos) << j["effects"].dump();
  EXPECT_FALSE(j.contains("timing_lag")) << "a table has no raw streams";
  EXPECT_TRUE(j["quality"]["pass"].get<bool>());
}

// ---- bag_input API
// --------------------------------------------------------------------------------

TEST(BagInput, ResolveTopicRules) {
  const std::vector<ai::BagTopic> topics = {
      {"/a/imu/data_raw", "sensor_msgs/Imu", 1},
      {"/b/imu/data_raw", "sensor_msgs/Imu", 1},
      {"/imu/data_raw", "sensor_msgs/Imu", 1},
      {"/b/gimbal/command", "accel_intrinsics/GimbalCommand", 1}};
  EXPECT_EQ(ai::resolve_topic("imu/data_raw", topics, "sensor_msgs/Imu"), "/imu/data_raw");
  EXPECT_EQ(ai::resolve_topic("/imu/data_raw", topics, ""), "/imu/data_raw");
  EXPECT_EQ(ai::resolve_topic("a/imu/data_raw", topics, ""), "/a/imu/data_raw");
  EXPECT_EQ(ai::resolve_topic("gimbal/command", topics, ""), "/b/gimbal/command");
  EXPECT_EQ(ai::topic_namespace("/b/gimbal/command", "gimbal/command"), "/b/");
  EXPECT_EQ(ai::topic_namespace("/gimbal/command", "gimbal/command"), "/");
  EXPECT_THROW(ai::resolve_topic("/gimbal/command", topics, ""), ai::BagInputError);
  EXPECT_THROW(ai::resolve_topic("data_raw", topics, ""), ai::BagInputError);  // 3 candidates
  EXPECT_EQ(ai::resolve_topic("data_raw", {topics[0], topics[1]}, "", "/b/imu/"),
            "/b/imu/data_raw");
  try {
    ai::resolve_topic("gimbal/command", topics, "sensor_msgs/Imu");
    FAIL();
  } catch (const ai::BagInputError& e) {
    EXPECT_NE(std::string(e.what()).find("has type accel_intrinsics/GimbalCommand"),
              std::string::npos);
  }
}

// The fast IMU reader must see exactly what sensor_msgs::Imu deserialization sees.
TEST(BagInput, FastImuReaderMatchesFullMessage) {
  TempDir dir;
  // One dwell around each sample, so each dwell mean is that sample as offline_fit read it.
  std::vector<sensor_msgs::Imu> written;
  {
    HandBagWriter b(dir.file("imu2.bag"));
    b.receive_delay_s = 0.0;
    for (int i = 0; i < 50; ++i) {
      const double t = 10.0 + 0.01 * i;
      sensor_msgs::Imu msg =
          b.imu_message(core::ImuSample{t, Eigen::Vector3d(0.1 * i, -3.25 + i, 9.5 - 0.003 * i)});
      msg.header.frame_id = std::string(static_cast<std::size_t>(i % 7), 'f');  // varying lengths
      msg.header.seq = i;
      b.command(t - 0.004, 0, i, 50, 0.0, 0);
      b.command(t - 0.002, 0, i, 50, 0.0, 1);
      b.write(b.imu_topic, t, msg);
      written.push_back(msg);
    }
    b.command(11.0, 0, 49, 50, 0.0, 2);
  }
  const ai::BagRun run = ai::read_bag(dir.file("imu2.bag"));
  ASSERT_EQ(run.table.rows.size(), written.size());
  for (std::size_t i = 0; i < written.size(); ++i) {
    const core::ImuSample full = ai::to_core(written[i]);
    EXPECT_EQ(run.table.rows[i].mean, full.outputs) << i;
    EXPECT_EQ(run.table.rows[i].n, 1u);
  }
  EXPECT_EQ(run.stats.imu_messages, written.size());
  EXPECT_TRUE(run.stats.done_seen);
}

}  // namespace

namespace {

void expect_same_run(const ai::BagRun& a, const ai::BagRun& b) {
  ASSERT_EQ(a.table.rows.size(), b.table.rows.size());
  for (std::size_t i = 0; i < a.table.rows.size(); ++i) {
    const core::DwellRecord& x = a.table.rows[i];
    const core::DwellRecord& y = b.table.rows[i];
    EXPECT_EQ(x.phase, y.phase);
    EXPECT_EQ(x.step, y.step);
    EXPECT_EQ(x.angle_rad, y.angle_rad);
    EXPECT_EQ(x.t_start_s, y.t_start_s);
    EXPECT_EQ(x.t_end_s, y.t_end_s);
    EXPECT_EQ(x.n, y.n);
    EXPECT_EQ(x.mean, y.mean) << i;  // to the last digit
    EXPECT_EQ(x.std, y.std) << i;
  }
  EXPECT_EQ(a.table.time_origin_s, b.table.time_origin_s);
  EXPECT_EQ(a.stats.imu_messages, b.stats.imu_messages);
  EXPECT_EQ(a.stats.command_messages, b.stats.command_messages);
  EXPECT_EQ(a.stats.bag_start_s, b.stats.bag_start_s);
  EXPECT_EQ(a.stats.bag_end_s, b.stats.bag_end_s);
  EXPECT_EQ(a.stats.counters.samples_used, b.stats.counters.samples_used);
  EXPECT_EQ(a.stats.counters.dropped_outside_dwell, b.stats.counters.dropped_outside_dwell);
  EXPECT_EQ(a.stats.counters.dropped_non_finite, b.stats.counters.dropped_non_finite);
  EXPECT_EQ(a.stats.done_seen, b.stats.done_seen);
}

}  // namespace

// The memory-mapped chunk scan reads exactly what rosbag::View reads; compressed bags take View.
TEST(BagInput, ChunkScanEqualsView) {
  TempDir dir;
  HandRunOptions nan;
  nan.nan_samples_per_dwell = 1;
  make_hand_bag(dir.file("hand.bag"));
  make_hand_bag(dir.file("nan.bag"), nan);
  ai::BagInputOptions view_only;
  view_only.allow_chunk_scan = false;
  for (const std::string name : {"hand.bag", "nan.bag"}) {
    const ai::BagRun scan = ai::read_bag(dir.file(name));
    const ai::BagRun view = ai::read_bag(dir.file(name), view_only);
    EXPECT_EQ(scan.stats.reader, "chunk scan");
    EXPECT_EQ(view.stats.reader, "rosbag::View");
    expect_same_run(scan, view);
  }
  // The same topic listing (names, types, message counts) in the error of a missing topic.
  std::string scan_error, view_error;
  ai::BagInputOptions missing;
  missing.imu_topic = "no/such/topic";
  try {
    ai::read_bag(dir.file("hand.bag"), missing);
  } catch (const ai::BagInputError& e) {
    scan_error = e.what();
  }
  missing.allow_chunk_scan = false;
  try {
    ai::read_bag(dir.file("hand.bag"), missing);
  } catch (const ai::BagInputError& e) {
    view_error = e.what();
  }
  EXPECT_NE(scan_error.find("/imu/data_raw (sensor_msgs/Imu, 127 msgs)"), std::string::npos)
      << scan_error;
  EXPECT_EQ(scan_error, view_error);
  for (auto compression : {rosbag::compression::LZ4, rosbag::compression::BZ2}) {
    HandBagWriter writer(dir.file("packed.bag"));
    writer.bag().setCompression(compression);
    write_hand_run(writer, nan);
    writer.close();
    const ai::BagRun packed = ai::read_bag(dir.file("packed.bag"));
    EXPECT_EQ(packed.stats.reader, "rosbag::View");
    expect_same_run(packed, ai::read_bag(dir.file("nan.bag")));
  }
}
