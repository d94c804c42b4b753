// offline_fit: recalibrates from a recorded bag or a CSV position table, without playback
// (DESIGN.md section 2, "Offline tool").
//
//   offline_fit (--bag FILE | --csv FILE) [--imu-topic T] [--command-topic T] [--gravity G]
//               [--model joint|eq4] [--analyze] [--json OUT] [--csv-out FILE]
//               [--settle-discard SECONDS]
//
// --settle-discard (optional, default 0: the old behaviour) drops the samples of the first
// SECONDS of each dwell (after SETTLED), as the calibration node's settle_discard_s does: for a
// gimbal that still rings when it reports settled. Bags only.
// The bag goes through core::DwellAssembler, the dwell assignment of the calibration node, so
// the result equals the online one for the same messages. Exit status: 0 success, 1 bad input or
// failed fit, 2 bad command line; every failure prints exactly one line "offline_fit: error: ..."
// on stderr and writes no output file. Outputs (--json, --csv-out) are written only on success,
// each through a temporary file renamed into place.
#include <console_bridge/console.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "accel_intrinsics/core/constants.h"
#include "accel_intrinsics/core/discrepancy.h"
#include "accel_intrinsics/core/fit.h"
#include "accel_intrinsics/core/position_table.h"
#include "accel_intrinsics/core/raw_stream_analysis.h"
#include "accel_intrinsics/core/result_json.h"
#include "accel_intrinsics/ros/bag_input.h"
#include "accel_intrinsics/ros/names.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;

namespace {

constexpr char kProgram[] = "offline_fit";
// Accepted local gravity, m/s^2, exclusive bounds: the calibration node's
// (config/calibration.yaml); Earth's surface spans 9.76..9.84, and unit slips (cm/s^2, or 1 for
// "one g") are refused.
constexpr double kMinGravity = 9.7;
constexpr double kMaxGravity = 9.9;

// A failure with its exit status; the message is printed as one line.
struct Failure {
  int status;
  std::string message;
};

std::string one_line(std::string text) {
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return text;
}

struct Arguments {
  std::string bag;
  std::string csv;
  std::string imu_topic = ai::names::kImuTopic;
  std::string command_topic = ai::names::kGimbalCommandTopic;
  double gravity = core::kStandardGravity;
  std::string model = "joint";
  bool analyze = false;
  std::string json_out;
  std::string csv_out;
  double settle_discard_s = 0.0;
  bool imu_topic_given = false;
  bool command_topic_given = false;
  bool settle_discard_given = false;
};

// What was read, whatever the source.
struct Input {
  core::PositionTable table;
  nlohmann::json description;  // "input" key of the JSON
  std::string summary;         // one line for the text report
  bool from_bag = false;
  bool complete = true;               // bag: DONE seen, no open dwell, every announced step found
  std::vector<std::string> warnings;  // why not complete, and anything else worth a look
  // Bag with --analyze: the raw streams, for the timing-lag estimate.
  std::vector<core::GimbalEvent> raw_commands;
  std::vector<core::ImuSample> raw_samples;
};

// --analyze: the discrepancy analysis (core/discrepancy.h) on the same position table with the
// same local gravity; its base model is always `joint` (plus the effects it names), whatever
// --model says for the main result. Its keys (effects [{name, target, value, std, p_value, ...}],
// ambiguous [...], gap {before, after}, screening, ...) are added to the JSON next to the main
// result's (never replacing one), its report follows the result table. On a bag the timing lag
// is screened too, from the raw streams (core::screen_timing_lag, with its false-alarm budget).

void run_analysis(const Input& input, const core::FitOptions& options, nlohmann::json& json,
                  std::ostream& text) {
  const core::PositionTable& table = input.table;
  core::AnalysisOptions analysis_options;
  analysis_options.local_gravity = options.local_gravity;
  core::AnalysisResult analysis;
  try {
    analysis = core::analyze(table, analysis_options);
  } catch (const std::exception& e) {
    throw Failure{1, "--analyze: discrepancy analysis failed: " + one_line(e.what())};
  }
  const nlohmann::json extra = core::analysis_to_json(analysis);
  for (auto it = extra.begin(); it != extra.end(); ++it) {
    if (!json.contains(it.key())) json[it.key()] = it.value();
  }
  core::write_analysis_report(text, analysis);

  // Timing lag shows only in the raw streams around the moves, which a bag has.
  if (!input.from_bag) return;
  const core::TimingLagEstimate lag = core::screen_timing_lag(
      input.raw_commands, input.raw_samples, table, analysis.after_fit, &json);
  text << "  timing lag (raw streams): " << (lag.ok ? "" : "no estimate: ") << lag.message << "\n";
}

Input read_csv_input(const Arguments& args) {
  Input input;
  try {
    input.table = core::read_position_table_file(args.csv);
  } catch (const core::PositionTableError& e) {
    throw Failure{1, one_line(e.what())};
  }
  input.description = {{"type", "csv"}, {"path", args.csv}, {"rows", input.table.rows.size()}};
  input.summary =
      "position table " + args.csv + " (" + std::to_string(input.table.rows.size()) + " dwells)";
  return input;
}

Input read_bag_input(const Arguments& args) {
  ai::BagInputOptions options;
  options.imu_topic = args.imu_topic;
  options.command_topic = args.command_topic;
  options.assembler.settle_discard_s = args.settle_discard_s;
  options.progress_stream = &std::cerr;
  options.progress_label = std::string(kProgram) + ": reading " + args.bag;

  Input input;
  if (args.analyze) {
    options.raw_commands = &input.raw_commands;
    options.raw_samples = &input.raw_samples;
  }
  ai::BagRun run;
  try {
    run = ai::read_bag(args.bag, options);
  } catch (const ai::BagInputError& e) {
    throw Failure{1, one_line(e.what())};
  }
  const ai::BagInputStats& st = run.stats;
  const core::AssemblerCounters& c = st.counters;

  if (st.command_messages == 0) {
    throw Failure{1, "no gimbal commands on '" + st.command_topic + "' in " + args.bag};
  }
  if (st.imu_messages == 0)
    throw Failure{1, "no IMU messages on '" + st.imu_topic + "' in " + args.bag};

  input.from_bag = true;
  input.table = std::move(run.table);
  const double duration = st.bag_end_s - st.bag_start_s;
  input.description = {
      {"type", "bag"},
      {"path", args.bag},
      {"imu_topic", st.imu_topic},
      {"command_topic", st.command_topic},
      {"imu_messages", st.imu_messages},
      {"command_messages", st.command_messages},
      {"invalid_commands", st.invalid_commands},
      {"duration_s", duration},
      {"read_wall_s", st.read_wall_s},
      {"dwells", input.table.rows.size()},
      {"samples_used", c.samples_used},
      {"dropped_outside_dwell", c.dropped_outside_dwell},
      {"settle_discard_s", args.settle_discard_s},
      {"dropped_settle_discard", c.dropped_settle_discard},
      {"dropped_non_finite", c.dropped_non_finite},
      {"dropped_backwards", c.dropped_backwards},
      {"dropped_late", c.dropped_late},
      {"commands_out_of_order", c.commands_out_of_order},
      {"done_seen", st.done_seen},
      {"time_origin_s", input.table.time_origin_s},
  };
  std::ostringstream summary;
  summary << "bag " << args.bag << " (" << st.imu_messages << " IMU messages on " << st.imu_topic
          << ", " << st.command_messages << " commands on " << st.command_topic << ", "
          << std::fixed << std::setprecision(1) << duration << " s)";
  input.summary = summary.str();

  if (!st.done_seen) {
    input.complete = false;
    input.warnings.push_back("the recording ends before the controller's DONE");
  }
  if (st.open_dwell) {
    input.complete = false;
    input.warnings.push_back(
        std::string("the dwell (phase ") + core::phase_name(st.open_dwell_phase) + ", step " +
        std::to_string(st.open_dwell_step) + ") was still open at the end of the bag (" +
        std::to_string(st.open_dwell_samples) + " samples not used)");
  }
  const std::array<int, 3> found = core::positions_per_phase(input.table);
  for (core::Phase p : core::kPhases) {
    const std::uint32_t announced = st.steps_announced[core::index(p)];
    if (announced > 0 && found[core::index(p)] < static_cast<int>(announced)) {
      input.complete = false;
      input.warnings.push_back(std::string("phase ") + core::phase_name(p) + ": " +
                               std::to_string(found[core::index(p)]) + " of " +
                               std::to_string(announced) + " positions have a dwell");
    }
  }
  if (c.dropped_non_finite > 0) {
    input.warnings.push_back(std::to_string(c.dropped_non_finite) +
                             " IMU samples with non-finite values dropped");
  }
  if (c.dropped_late > 0) {
    input.warnings.push_back(
        std::to_string(c.dropped_late) +
        " messages arrived (in bag order) later than the reorder window and were dropped");
  }
  if (st.invalid_commands > 0) {
    input.warnings.push_back(
        std::to_string(st.invalid_commands) +
        " malformed gimbal commands ignored (phase, state, step/steps, angle or stamp)");
  }
  if (c.commands_out_of_order > 0) {
    input.warnings.push_back(std::to_string(c.commands_out_of_order) +
                             " gimbal commands out of protocol order (last: " + c.last_warning +
                             ")");
  }
  return input;
}

// Each phase present with enough dwells; named in the message when not.
void check_phases(const core::PositionTable& table, int min_positions) {
  const std::array<int, 3> counts = core::positions_per_phase(table);
  std::ostringstream tally;
  tally << "dwells per phase: x=" << counts[0] << ", y=" << counts[1] << ", z=" << counts[2];
  for (core::Phase p : core::kPhases) {
    if (counts[core::index(p)] == 0) {
      throw Failure{
          1, std::string("phase ") + core::phase_name(p) + " is missing (" + tally.str() + ")"};
    }
  }
  for (core::Phase p : core::kPhases) {
    if (counts[core::index(p)] < min_positions) {
      throw Failure{1, std::string("too few dwells in phase ") + core::phase_name(p) + ": " +
                           std::to_string(counts[core::index(p)]) + ", at least " +
                           std::to_string(min_positions) + " needed (" + tally.str() + ")"};
    }
  }
}

void print_report(std::ostream& out, const Input& input, const core::FitResult& r) {
  const core::Intrinsics& in = r.intrinsics;
  out << "accel_intrinsics offline_fit\n";
  out << "input:         " << input.summary << "\n";
  if (!input.complete) out << "INCOMPLETE RUN: the result below uses only the dwells found\n";
  for (const std::string& w : input.warnings) out << "warning:       " << w << "\n";
  out << "model:         " << r.model_label() << "\n";
  out << "local gravity: " << std::setprecision(9) << r.local_gravity << " m/s^2\n";
  out << "positions:     x " << r.positions[0] << ", y " << r.positions[1] << ", z "
      << r.positions[2] << "\n\n";

  auto line = [&out](const std::string& name, double value, double std_value,
                     const std::string& unit) {
    out << "  " << std::left << std::setw(18) << name << std::right << std::setw(20)
        << std::setprecision(12) << value << "  +- " << std::left << std::setw(12)
        << std::setprecision(3) << std_value << std::right << " " << unit << "\n";
  };
  out << "  " << std::left << std::setw(18) << "parameter" << std::right << std::setw(20) << "value"
      << "     std (k=1)\n";
  static const char* const kAngles[] = {"theta_uv", "theta_vw", "theta_wu"};
  for (int s = 0; s < 3; ++s) {
    line(std::string("|") + core::accelerometer_name(s) + "|", in.responsivity(s),
         in.responsivity_std(s), "");
  }
  for (int a = 0; a < 3; ++a) {
    line(kAngles[a], core::rad_to_deg(in.angles_rad(a)), core::rad_to_deg(in.angles_std_rad(a)),
         "deg");
  }
  for (int s = 0; s < 3; ++s) {
    line(std::string("O_") + core::accelerometer_name(s), r.O(s), r.O_std(s), "m/s^2");
  }
  if (r.model == core::FitModel::Eq4) {
    for (int s = 0; s < 3; ++s) {
      for (core::Phase p : core::kPhases) {
        line(std::string("O_") + core::accelerometer_name(s) + core::phase_name(p),
             r.offset_per_phase(s, core::index(p)), r.offset_per_phase_std(s, core::index(p)),
             "m/s^2");
      }
    }
  }
  for (std::size_t i = 0; i < r.effects.size(); ++i) {
    line(r.effects[i].label(), r.effects[i].value,
         i < r.effects_std.size() ? r.effects_std[i] : NAN, "");
  }
  out << "\n  vectors (rows of S, DUT frame x y z):\n";
  for (int s = 0; s < 3; ++s) {
    out << "    " << core::accelerometer_name(s) << " = [";
    for (int c = 0; c < 3; ++c)
      out << (c ? ", " : "") << std::setw(17) << std::setprecision(10) << r.S(s, c);
    out << "]\n";
  }
  out << "  cross-sensitivity P = S^-1 (row-major):\n";
  for (int s = 0; s < 3; ++s) {
    out << "    [";
    for (int c = 0; c < 3; ++c) {
      out << (c ? ", " : "") << std::setw(17) << std::setprecision(10) << r.cross_sensitivity(s, c);
    }
    out << "]\n";
  }
  out << "\n  reduced chi2:  " << std::setprecision(6) << r.reduced_chi2 << " (chi2 " << r.chi2
      << ", dof " << r.dof << ")\n";
  out << "  residual rms:  " << std::setprecision(6) << r.residual_rms << " m/s^2\n";
  out.flush();
}

// Writes through "<path>.tmp.<pid>"; commit() renames into place. Nothing remains on failure.
class PendingFile {
 public:
  explicit PendingFile(std::string path)
      : path_(std::move(path)), temp_(path_ + ".tmp." + std::to_string(::getpid())) {}
  ~PendingFile() {
    if (!committed_) std::remove(temp_.c_str());
  }
  std::ostream& open() {
    stream_.open(temp_, std::ios::out | std::ios::trunc);
    if (!stream_) throw Failure{1, "cannot write '" + path_ + "'"};
    return stream_;
  }
  void close() {
    stream_.close();
    if (stream_.fail()) throw Failure{1, "cannot write '" + path_ + "' (disk full?)"};
  }
  void commit() {
    if (std::rename(temp_.c_str(), path_.c_str()) != 0)
      throw Failure{1, "cannot write '" + path_ + "'"};
    committed_ = true;
  }

 private:
  std::string path_;
  std::string temp_;
  std::ofstream stream_;
  bool committed_ = false;
};

int run(const Arguments& args) {
  if (args.bag.empty() == args.csv.empty())
    throw Failure{2, "give exactly one of --bag FILE or --csv FILE"};
  if (!args.csv.empty() && (args.imu_topic_given || args.command_topic_given)) {
    throw Failure{2, "--imu-topic and --command-topic apply to --bag only"};
  }
  if (!args.csv.empty() && args.settle_discard_given) {
    throw Failure{
        2,
        "--settle-discard applies to --bag only (a position table's dwells are already averaged)"};
  }
  if (!std::isfinite(args.settle_discard_s) || args.settle_discard_s < 0.0) {
    std::ostringstream s;
    s << "--settle-discard " << args.settle_discard_s << " must be a number of seconds >= 0";
    throw Failure{2, s.str()};
  }
  if (!std::isfinite(args.gravity) || args.gravity <= kMinGravity || args.gravity >= kMaxGravity) {
    std::ostringstream s;
    s << "--gravity " << args.gravity << " is not a local gravity in m/s^2 (must be in ("
      << kMinGravity << ", " << kMaxGravity << "))";
    throw Failure{2, s.str()};
  }
  core::FitOptions fit_options;
  try {
    fit_options.model = core::parse_model(args.model);
  } catch (const std::exception& e) {
    throw Failure{2, "--model: " + one_line(e.what())};
  }
  fit_options.local_gravity = args.gravity;
  if (!args.json_out.empty() && args.json_out == args.csv_out) {
    throw Failure{2, "--json and --csv-out name the same file"};
  }

  const Input input = args.bag.empty() ? read_csv_input(args) : read_bag_input(args);
  check_phases(input.table, fit_options.min_positions_per_phase);

  core::FitResult result;
  try {
    result = core::fit(input.table, fit_options);
  } catch (const core::FitError& e) {
    throw Failure{1, "fit failed: " + one_line(e.what())};
  } catch (const std::invalid_argument& e) {
    throw Failure{1, "fit failed: " + one_line(e.what())};
  }

  nlohmann::json json = core::to_json(result);
  json["input"] = input.description;
  json["complete"] = input.from_bag ? nlohmann::json(input.complete) : nlohmann::json(nullptr);
  json["warnings"] = input.warnings;
  std::ostringstream analysis_text;
  if (args.analyze) run_analysis(input, fit_options, json, analysis_text);

  // Outputs: files first (all or nothing), then the report.
  const bool json_to_stdout = args.json_out == "-";
  PendingFile* csv_file = nullptr;
  PendingFile* json_file = nullptr;
  std::unique_ptr<PendingFile> csv_holder, json_holder;
  if (!args.csv_out.empty()) {
    csv_holder.reset(new PendingFile(args.csv_out));
    csv_file = csv_holder.get();
    core::write_position_table(csv_file->open(), input.table);
    csv_file->close();
  }
  if (!args.json_out.empty() && !json_to_stdout) {
    json_holder.reset(new PendingFile(args.json_out));
    json_file = json_holder.get();
    json_file->open() << json.dump(2) << "\n";
    json_file->close();
  }
  if (csv_file) csv_file->commit();
  if (json_file) json_file->commit();

  std::ostream& report = json_to_stdout ? std::cerr : std::cout;
  print_report(report, input, result);
  if (!analysis_text.str().empty()) report << "\n" << analysis_text.str();
  if (json_to_stdout) std::cout << json.dump(2) << std::endl;
  if (!input.complete) {
    std::cerr << kProgram << ": warning: incomplete run, result from the dwells found: "
              << input.warnings.front() << std::endl;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Recalibrates a three-axis accelerometer offline from a recorded bag (read directly, no "
      "playback) or a CSV position table, and prints the intrinsic parameters with their "
      "standard uncertainties."};
  app.footer(
      "Exit status: 0 success; 1 bad input or failed fit; 2 bad command line. Failures print one "
      "line on stderr and write no output file.");
  Arguments args;
  app.add_option("--bag", args.bag, "recorded run (rosbag)");
  app.add_option("--csv", args.csv, "position table: " + std::string(core::kPositionTableHeader));
  auto* imu_opt =
      app.add_option("--imu-topic", args.imu_topic, "IMU topic in the bag (sensor_msgs/Imu)")
          ->capture_default_str();
  auto* cmd_opt = app.add_option("--command-topic", args.command_topic,
                                 "gimbal command topic in the bag (accel_intrinsics/GimbalCommand)")
                      ->capture_default_str();
  app.add_option("--gravity", args.gravity, "local gravity g in m/s^2")->capture_default_str();
  app.add_option("--model", args.model, "fit model: joint or eq4")->capture_default_str();
  app.add_flag("--analyze", args.analyze, "also run the discrepancy analysis (missing effects)");
  app.add_option("--json", args.json_out, "write the result as JSON to this file ('-': stdout)");
  app.add_option("--csv-out", args.csv_out, "write the position table (dwell means) as CSV");
  auto* settle_opt =
      app.add_option("--settle-discard", args.settle_discard_s,
                     "bag only: drop the samples of the first SECONDS of each dwell (after the "
                     "gimbal reports SETTLED), like the calibration node's settle_discard_s")
          ->type_name("SECONDS")
          ->capture_default_str();

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << kProgram << ": error: " << one_line(e.what()) << " (see --help)" << std::endl;
    return 2;
  }
  args.imu_topic_given = imu_opt->count() > 0;
  args.command_topic_given = cmd_opt->count() > 0;
  args.settle_discard_given = settle_opt->count() > 0;

  // rosbag and cpp_common log parse errors through console_bridge; the exception they throw
  // carries the same news and becomes our one line on stderr.
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  try {
    return run(args);
  } catch (const Failure& f) {
    std::cerr << kProgram << ": error: " << f.message << std::endl;
    return f.status;
  } catch (const std::exception& e) {
    std::cerr << kProgram << ": error: " << one_line(e.what()) << std::endl;
    return 1;
  }
}
