#include "accel_intrinsics/ros/offline_fit.h"

#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <memory>
#include <ostream>
#include <optional>
#include <sstream>
#include <vector>

#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/dwells/rest_detection.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/dwells/samples_file.h"
#include "accel_intrinsics/core/fit/tumble.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/exporters.h"
#include "accel_intrinsics/io/budget_file.h"
#include "accel_intrinsics/io/residuals_csv.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/io/text_report.h"
#include "accel_intrinsics/ros/bag_input.h"
#include "accel_intrinsics/ros/scripts.h"

namespace accel_intrinsics {
std::string channel_topic_option(std::size_t channel) {
  return std::string("--") + core::kChannels[channel].name + "-topic";
}

namespace {

bool any_channel_topic_given(const OfflineFitArguments& args) {
  for (bool given : args.channel_topic_given)
    if (given) return true;
  return false;
}

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

// What was read, whatever the source.
struct Input {
  core::PositionTable table;
  io::ResultContext context;  // input description, complete, warnings
  bool from_bag = false;
  core::RawStreams raw;  // bag with --analyze: for the timing-lag estimate
  // From the run's long rest (docs/design.md section 12: a dwell at least 10 times the median), when
  // the input has raw samples (a bag): what the fit and the analysis weight the dwells with.
  std::optional<core::NoiseModel> noise_model;
  std::string read_as;   // how the input was taken, when not obvious (prefixes a fit failure)
};

Input read_csv_input(const OfflineFitArguments& args) {
  Input input;
  try {
    input.table = core::read_position_table_file(args.csv);
  } catch (const core::PositionTableError& e) {
    throw Failure{kOfflineFitBadInput, as_one_line(e.what())};
  }
  io::InputDescription description;
  description.path = args.csv;
  description.dwells = input.table.rows.size();
  description.summary =
      "position table " + args.csv + " (" + std::to_string(input.table.rows.size()) + " dwells)";
  input.context.input = description;
  return input;
}

// A hand tumble: rests found in a raw stream become the table (rows of unknown orientation).
void rests_from_stream(std::vector<core::ImuSample> samples, const OfflineFitArguments& args,
                       Input* input) {
  // A bag gives its messages in receive order: put them in stamp order first.
  const core::StreamCleanup cleanup = core::put_in_time_order(&samples);
  if (cleanup.duplicates > 0)
    input->context.warnings.push_back(std::to_string(cleanup.duplicates) +
                                      " duplicated IMU messages (same stamp and values) used once");
  if (cleanup.conflicting > 0)
    input->context.warnings.push_back(
        std::to_string(cleanup.conflicting) +
        " IMU samples repeat an earlier stamp with other values (device clock went back?) and "
        "were dropped");
  core::RestDetectionOptions options;
  options.min_rest_s = args.rest_min_s;
  core::RestDetection found;
  try {
    found = core::detect_rests(samples, options);
  } catch (const std::invalid_argument& e) {
    throw Failure{kOfflineFitBadInput, as_one_line(e.what())};
  }
  if (found.rests.size() < core::TumbleFitOptions().min_rests) {
    std::ostringstream m;
    m << found.rests.size() << " rests found in the stream (" << found.rejected.size()
      << " still spans rejected), at least " << core::TumbleFitOptions().min_rests
      << " needed: hold the device still for " << args.rest_min_s
      << " s or more in more orientations, every axis up and down";
    input->context.rest_detection = found;
    throw Failure{kOfflineFitBadInput, input->read_as + m.str()};
  }
  input->table.rows = found.rests;
  input->table.time_origin_s = samples.front().stamp_s;
  input->context.rest_detection = found;
  input->context.rest_min_s = args.rest_min_s;
  // The noise model of the first rest of at least 30 s, when there is one (docs/design.md section 12):
  // the tumble fit and its analysis are then generalized least squares across the rests.
  if (core::find_long_rest(input->table)) {
    std::vector<double> stamps;
    std::vector<Eigen::Vector3d> outputs;
    stamps.reserve(samples.size());
    outputs.reserve(samples.size());
    for (const core::ImuSample& x : samples) {
      stamps.push_back(x.stamp_s);
      outputs.push_back(x.outputs);
    }
    try {
      input->noise_model = core::noise_model_of_run(input->table, stamps, outputs);
    } catch (const std::invalid_argument&) {
      // Too short a record for a model: white, as before.
    }
  }
}

Input read_samples_input(const OfflineFitArguments& args) {
  std::vector<core::ImuSample> samples;
  try {
    samples = core::read_samples_file(args.samples);
  } catch (const core::SamplesFileError& e) {
    throw Failure{kOfflineFitBadInput, as_one_line(e.what())};
  }
  Input input;
  const std::size_t count = samples.size();
  const double duration = samples.back().stamp_s - samples.front().stamp_s;
  rests_from_stream(std::move(samples), args, &input);
  io::InputDescription description;
  description.type = "samples";
  description.path = args.samples;
  description.dwells = input.table.rows.size();
  std::ostringstream summary;
  summary << "samples " << args.samples << " (" << count << " samples, " << std::fixed
          << std::setprecision(1) << input.context.rest_detection->rate_hz << " Hz, " << duration
          << " s): "
          << input.table.rows.size() << " rests found, "
          << input.context.rest_detection->rejected.size() << " spans rejected";
  description.summary = summary.str();
  input.context.input = description;
  return input;
}

// Why a bag run is incomplete, and anything else worth a look.
// A retried position holds the dwell the fault cut short and the one measured again; the node
// keeps the second only, and so does offline_fit (core::find_remeasured_rows), saying so.
void drop_remeasured_dwells(Input* input) {
  const core::SupersededRows superseded = core::find_remeasured_rows(input->table);
  if (superseded.rows.empty()) return;
  std::ostringstream s;
  s << superseded.rows.size() << (superseded.rows.size() == 1 ? " dwell" : " dwells")
    << " measured again right after at the same position (a retry: the earlier one was cut short) "
       "dropped, as the calibration node drops them:";
  for (std::size_t i : superseded.rows) {
    const core::DwellRecord& row = input->table.rows[i];
    s << " phase " << core::phase_name(row.phase) << " step " << row.step << " at t=" << std::fixed
      << std::setprecision(3) << row.t_start_s << ";";
  }
  if (superseded.by_samples > 0) {
    s << " " << superseded.by_samples
      << " of them at the turn of a two-way sweep, where the commands do not tell which visit "
         "was cut short: the one(s) with the fewest samples";
  }
  std::string text = s.str();
  if (text.back() == ';') text.pop_back();
  input->context.warnings.push_back(text);
  input->table = core::without_rows(std::move(input->table), superseded.rows);
}

void check_bag_run(const BagInputStats& st, const core::PositionTable& table, Input* input) {
  const core::AssemblerCounters& c = st.counters;
  std::vector<std::string>& warnings = input->context.warnings;
  bool& complete = input->context.complete;
  if (!st.done_seen) {
    complete = false;
    warnings.push_back("the recording ends before the controller's DONE");
  }
  if (st.open_dwell) {
    complete = false;
    warnings.push_back(std::string("the dwell (phase ") + core::phase_name(st.open_dwell_phase) +
                       ", step " + std::to_string(st.open_dwell_step) +
                       ") was still open at the end of the bag (" +
                       std::to_string(st.open_dwell_samples) + " samples not used)");
  }
  const std::array<int, 3> found = core::positions_per_phase(table);
  for (core::Phase p : core::kPhases) {
    const std::uint32_t announced = st.steps_announced[core::index(p)];
    if (announced > 0 && found[core::index(p)] < static_cast<int>(announced)) {
      complete = false;
      warnings.push_back(std::string("phase ") + core::phase_name(p) + ": " +
                         std::to_string(found[core::index(p)]) + " of " +
                         std::to_string(announced) + " positions have a dwell");
    }
  }
  if (c.duplicates > 0) {
    warnings.push_back(std::to_string(c.duplicates) +
                       " duplicated IMU messages (same stamp and values) used once");
  }
  if (c.dropped_backwards > 0) {
    warnings.push_back(std::to_string(c.dropped_backwards) +
                       " IMU samples repeat an earlier stamp with other values (device clock went "
                       "back?) and were dropped");
  }
  if (!st.topic_note.empty()) warnings.push_back(st.topic_note);
  if (c.dropped_non_finite > 0) {
    warnings.push_back(std::to_string(c.dropped_non_finite) +
                       " IMU samples with non-finite values dropped");
  }
  if (c.dropped_late > 0) {
    warnings.push_back(
        std::to_string(c.dropped_late) +
        " messages arrived (in bag order) later than the reorder window and were dropped");
  }
  if (st.invalid_commands > 0) {
    warnings.push_back(
        std::to_string(st.invalid_commands) +
        " malformed gimbal commands ignored (phase, state, step/steps, angle or stamp)");
  }
  if (c.commands_out_of_order > 0) {
    warnings.push_back(std::to_string(c.commands_out_of_order) +
                       " gimbal commands out of protocol order (last: " + c.last_warning + ")");
  }
}

Input read_bag_input(const OfflineFitArguments& args, std::ostream& err) {
  BagInputOptions options;
  options.imu_topic = args.imu_topic;
  options.command_topic = args.command_topic;
  options.channel_topics = args.channel_topics;
  options.assembler.settle_discard_s = args.settle_discard_s;
  options.progress_stream = &err;
  options.imu_time_offset_s = args.imu_time_offset_s;
  options.imu_by_type = !args.imu_topic_given;
  options.command_topic_optional = true;  // IMU alone: a hand tumble
  core::ClockCheck clock_check;
  if (!args.skip_clock_check) options.clock_check = &clock_check;
  std::string bags;
  for (const std::string& b : args.bags) bags += (bags.empty() ? "" : ", ") + b;
  options.progress_label = std::string(kOfflineFitProgram) + ": reading " + bags;

  Input input;
  if (args.analyze) {
    options.raw_commands = &input.raw.commands;
    options.raw_samples = &input.raw.samples;
  }
  BagRun run;
  try {
    run = read_bags(args.bags, options);
  } catch (const BagInputError& e) {
    throw Failure{kOfflineFitBadInput, as_one_line(e.what())};
  }
  const BagInputStats& st = run.stats;
  const bool tumble = st.command_topic.empty();
  if (st.command_messages == 0 && !tumble) {
    throw Failure{kOfflineFitBadInput,
                  "no gimbal commands on '" + st.command_topic + "' in " + st.path};
  }
  if (tumble && args.unknown_orientations) {
    throw Failure{kOfflineFitBadInput,
                  "--unknown-orientations: " + st.path + " has no gimbal commands (a tumble already)"};
  }
  if (st.imu_messages == 0) {
    throw Failure{kOfflineFitBadInput, "no IMU messages on '" + st.imu_topic + "' in " + st.path};
  }
  if (!st.topic_note.empty()) err << kOfflineFitProgram << ": note: " << st.topic_note << std::endl;
  for (const core::ChannelSpec& spec : core::kChannels) {
    const std::size_t c = core::channel_index(spec.id);
    if (args.channel_topic_given[c] && st.channel_topics[c].empty()) {
      throw Failure{kOfflineFitBadInput, std::string("no ") + spec.name + " topic '" +
                                             args.channel_topics[c] + "' in " + st.path};
    }
  }
  // One clock, before anything is fitted: dwells on a shifted clock are garbage.
  if (options.clock_check && !tumble) {
    const core::ClockCheckResult clock = clock_check.result();
    if (clock.offset_found) {
      std::ostringstream fix;
      fix << "--imu-time-offset";
      if (args.imu_time_offset_s != 0.0) {
        // The offset found is on top of the one given.
        core::ClockCheckResult total = clock;
        total.offset_s -= args.imu_time_offset_s;
        throw Failure{kOfflineFitBadInput, total.message(fix.str())};
      }
      throw Failure{kOfflineFitBadInput, clock.message(fix.str())};
    }
  }

  input.from_bag = true;
  input.table = std::move(run.table);
  if (!tumble) drop_remeasured_dwells(&input);
  if (tumble) {
    // A bag with the IMU topic alone: a hand tumble, rests found in the stream.
    std::vector<core::ImuSample> samples;
    if (args.analyze) {
      samples = std::move(input.raw.samples);
    } else {
      BagInputOptions again = options;
      again.raw_samples = &samples;
      again.clock_check = nullptr;
      try {
        read_bags(args.bags, again);
      } catch (const BagInputError& e) {
        throw Failure{kOfflineFitBadInput, as_one_line(e.what())};
      }
    }
    input.raw = core::RawStreams();
    if (samples.empty())
      throw Failure{kOfflineFitBadInput, "no IMU messages on '" + st.imu_topic + "' in " + st.path};
    input.read_as = "no gimbal commands in " + st.path + ", read as a hand tumble: ";
    rests_from_stream(std::move(samples), args, &input);
  } else if (core::find_long_rest(input.table)) {
    // The noise model needs the raw samples of the long rest, not only its mean and std: with
    // --analyze they were kept, otherwise the bags are read once more for them (only runs that
    // have a long rest pay for it).
    std::vector<core::ImuSample> kept;
    const std::vector<core::ImuSample>* samples = &input.raw.samples;
    if (!args.analyze) {
      BagInputOptions again = options;
      again.raw_samples = &kept;
      again.raw_commands = nullptr;
      again.clock_check = nullptr;
      try {
        read_bags(args.bags, again);
      } catch (const BagInputError& e) {
        throw Failure{kOfflineFitBadInput, as_one_line(e.what())};
      }
      samples = &kept;
    }
    std::vector<double> stamps;
    std::vector<Eigen::Vector3d> outputs;
    const std::optional<core::LongRest> rest = core::find_long_rest(input.table);
    for (const core::ImuSample& x : *samples) {
      if (x.stamp_s < rest->t_start_s || x.stamp_s > rest->t_end_s) continue;
      stamps.push_back(x.stamp_s);
      outputs.push_back(x.outputs);
    }
    try {
      input.noise_model = core::noise_model_of_run(input.table, stamps, outputs);
    } catch (const std::invalid_argument& e) {
      err << kOfflineFitProgram << ": note: no noise model from the long rest: " << e.what()
          << std::endl;
    }
  }
  io::BagInputDescription bag;
  bag.imu_topic = st.imu_topic;
  bag.command_topic = st.command_topic;
  bag.imu_messages = st.imu_messages;
  bag.command_messages = st.command_messages;
  bag.invalid_commands = st.invalid_commands;
  bag.duration_s = st.bag_end_s - st.bag_start_s;
  bag.read_wall_s = st.read_wall_s;
  bag.settle_discard_s = args.settle_discard_s;
  bag.imu_time_offset_s = args.imu_time_offset_s;
  bag.files = st.files;
  bag.counters = st.counters;
  bag.done_seen = st.done_seen;
  bag.time_origin_s = input.table.time_origin_s;
  io::InputDescription description;
  if (tumble) description.type = "bag";
  description.path = st.path;
  description.dwells = input.table.rows.size();
  description.bag = bag;
  std::ostringstream summary;
  summary << (st.files > 1 ? "bags " : "bag ") << st.path << " (" << st.imu_messages << " IMU messages on " << st.imu_topic
          << ", ";
  if (tumble)
    summary << "no gimbal commands: a hand tumble, " << input.table.rows.size() << " rests found, ";
  else
    summary << st.command_messages << " commands on " << st.command_topic << ", ";
  for (const core::ChannelSpec& spec : core::kChannels) {
    const std::size_t c = core::channel_index(spec.id);
    if (!st.channel_topics[c].empty())
      summary << st.channel_messages[c] << " " << spec.name << "s on " << st.channel_topics[c]
              << ", ";
  }
  summary << std::fixed << std::setprecision(1) << bag.duration_s << " s)";
  description.summary = summary.str();
  input.context.input = description;
  if (!tumble) check_bag_run(st, input.table, &input);
  return input;
}

// The phases the model needs, named in the message when missing. eq4 fits each phase: all
// three with enough dwells. joint takes what determines S and O (the fit checks that): a gimbal
// run missing a phase is fitted and marked incomplete, naming the phase.
void check_phases(const core::PositionTable& table, core::FitModel model, int min_positions,
                  io::ResultContext* context) {
  if (core::calibration_method(table) == "tumble") {
    if (model == core::FitModel::Eq4)
      throw Failure{kOfflineFitBadInput,
                    "eq4 needs the gimbal's three phases; rests of unknown orientation are fitted "
                    "by the tumble fit (leave --model at joint)"};
    return;
  }
  const std::array<int, 3> counts = core::positions_per_phase(table);
  std::ostringstream tally;
  tally << "dwells per phase: x=" << counts[0] << ", y=" << counts[1] << ", z=" << counts[2];
  const bool known_orientations = core::rows_with_direction(table) > 0;
  for (core::Phase p : core::kPhases) {
    if (counts[core::index(p)] != 0 || known_orientations) continue;
    if (model == core::FitModel::Eq4) {
      throw Failure{kOfflineFitBadInput, std::string("phase ") + core::phase_name(p) +
                                             " is missing (" + tally.str() +
                                             "); eq4 needs all three, joint fits without it"};
    }
    context->complete = false;
    context->warnings.push_back(std::string("phase ") + core::phase_name(p) +
                                " is missing: fitted by joint from the other phases (" +
                                tally.str() + ")");
  }
  for (core::Phase p : core::kPhases) {
    const int count = counts[core::index(p)];
    if (count > 0 && count < min_positions) {
      throw Failure{kOfflineFitBadInput,
                    std::string("too few dwells in phase ") + core::phase_name(p) + ": " +
                        std::to_string(count) + ", at least " + std::to_string(min_positions) +
                        " needed (" + tally.str() + ")"};
    }
  }
}

void check_command_line(const OfflineFitArguments& args) {
  const int inputs = (args.bags.empty() ? 0 : 1) + (args.csv.empty() ? 0 : 1) +
                     (args.samples.empty() ? 0 : 1);
  if (inputs != 1) {
    throw Failure{kOfflineFitBadCommandLine,
                  "give exactly one of --bag FILE, --csv FILE or --samples FILE"};
  }
  if (!std::isfinite(args.rest_min_s) || args.rest_min_s <= 0.0) {
    std::ostringstream s;
    s << "--rest-min-s " << args.rest_min_s << " must be a number of seconds > 0";
    throw Failure{kOfflineFitBadCommandLine, s.str()};
  }
  if (!args.csv.empty() && args.rest_min_s_given) {
    throw Failure{kOfflineFitBadCommandLine,
                  "--rest-min-s applies to raw streams (--samples, or a bag without gimbal "
                  "commands), not to a position table"};
  }
  if (!args.samples.empty() &&
      (args.imu_time_offset_given || args.skip_clock_check || args.imu_topic_given ||
       args.command_topic_given || any_channel_topic_given(args) || args.settle_discard_given)) {
    throw Failure{kOfflineFitBadCommandLine,
                  "--imu-time-offset, --skip-clock-check, --settle-discard and the topic options "
                  "apply to --bag only"};
  }
  if (!args.samples.empty() && args.unknown_orientations) {
    throw Failure{kOfflineFitBadCommandLine,
                  "--unknown-orientations applies to a gimbal run (--bag or --csv); --samples is "
                  "always fitted without orientations"};
  }
  if (!args.csv.empty() && (args.imu_time_offset_given || args.skip_clock_check)) {
    throw Failure{kOfflineFitBadCommandLine,
                  "--imu-time-offset and --skip-clock-check apply to --bag only"};
  }
  if (!std::isfinite(args.imu_time_offset_s)) {
    throw Failure{kOfflineFitBadCommandLine, "--imu-time-offset must be a number of seconds"};
  }
  if (!args.csv.empty() &&
      (args.imu_topic_given || args.command_topic_given || any_channel_topic_given(args))) {
    std::vector<std::string> names{"--imu-topic", "--command-topic"};
    for (std::size_t c = 0; c < core::kChannelCount; ++c) names.push_back(channel_topic_option(c));
    std::string list;
    for (std::size_t i = 0; i < names.size(); ++i)
      list += (i == 0 ? "" : i + 1 == names.size() ? " and " : ", ") + names[i];
    throw Failure{kOfflineFitBadCommandLine, list + " apply to --bag only"};
  }
  if (!args.csv.empty() && args.settle_discard_given) {
    throw Failure{
        kOfflineFitBadCommandLine,
        "--settle-discard applies to --bag only (a position table's dwells are already averaged)"};
  }
  if (!std::isfinite(args.settle_discard_s) || args.settle_discard_s < 0.0) {
    std::ostringstream s;
    s << "--settle-discard " << args.settle_discard_s << " must be a number of seconds >= 0";
    throw Failure{kOfflineFitBadCommandLine, s.str()};
  }
  if (!std::isfinite(args.gravity) || args.gravity <= kMinGravity || args.gravity >= kMaxGravity) {
    std::ostringstream s;
    s << "--gravity " << args.gravity << " is not a local gravity in m/s^2 (must be in ("
      << kMinGravity << ", " << kMaxGravity << "))";
    throw Failure{kOfflineFitBadCommandLine, s.str()};
  }
  if (!args.report_pdf.empty() &&
      (args.report_pdf == args.json_out || args.report_pdf == args.csv_out)) {
    throw Failure{kOfflineFitBadCommandLine, "--report names the same file as --json or --csv-out"};
  }
  if (!args.json_out.empty() && args.json_out == args.csv_out) {
    throw Failure{kOfflineFitBadCommandLine, "--json and --csv-out name the same file"};
  }
  std::vector<std::string> outputs = {args.json_out, args.csv_out};
  for (const std::string& spec : args.exports) {
    std::string path;
    try {
      path = io::parse_export_spec(spec).second;
    } catch (const io::IoError& e) {
      throw Failure{kOfflineFitBadCommandLine, e.what()};
    }
    for (const std::string& other : outputs) {
      if (!other.empty() && other == path) {
        throw Failure{kOfflineFitBadCommandLine, "--export " + spec + ": '" + path +
                                                     "' is already an output of this run"};
      }
    }
    outputs.push_back(path);
  }
}

// The certificate from the result: scripts/certificate_report --out PDF JSON on a temporary copy
// of the JSON; the script writes the PDF atomically and prints one line on failure.
void write_certificate(const std::string& json, const core::PositionTable& table,
                       const core::FitResult& certificate, const std::string& pdf,
                       const std::string& result_name, const std::string& history_archive,
                       bool draft) {
  const std::string tmp = pdf + ".json.tmp." + std::to_string(::getpid());
  const std::string residuals = pdf + ".residuals.tmp." + std::to_string(::getpid());
  io::write_file_atomically(tmp, json);
  io::write_residuals_csv(residuals, table, certificate, certificate);
  std::vector<std::string> report_args = {"--out", pdf, "--residuals", residuals,
                                          "--result-name", result_name, tmp};
  // the device's history page, from the archive this result just went into
  if (!history_archive.empty()) report_args.insert(report_args.begin(), {"--history-archive", history_archive});
  if (draft) report_args.insert(report_args.begin(), "--draft");
  const int status = run_package_script("certificate_report", report_args);
  std::remove(tmp.c_str());
  std::remove(residuals.c_str());
  if (status == 3) {  // refused; the script named why and how to fix it
    throw Failure{kOfflineFitBadInput, "--report: no certificate (see above; --draft makes one "
                                       "marked DRAFT)"};
  }
  if (status != 0) {
    throw Failure{kOfflineFitBadInput, "--report: " + package_script("certificate_report") +
                                           " failed (exit status " + std::to_string(status) +
                                           "); it needs /usr/bin/python3 with matplotlib"};
  }
}

// --archive: scripts/archive add on the written result (or a temporary copy), with the position
// table and the input files (their sha256 names the record). The result files are already
// written, so a failure to archive is a warning. The URL is never printed here: the script
// prints it without its password. Returns whether the result is in the archive.
bool archive_result(const OfflineFitArguments& args, const std::string& json,
                    const core::PositionTable& table, std::ostream& err) {
  const std::string tmp = (std::filesystem::temp_directory_path() / "offline_fit_archive.").string() +
                          std::to_string(::getpid());
  const bool json_file = !args.json_out.empty() && args.json_out != "-";
  const std::string result_path = json_file ? args.json_out : tmp + ".json";
  const std::string table_path = args.csv_out.empty() ? tmp + ".csv" : args.csv_out;
  std::vector<std::string> command = {"--archive", args.archive, "add", result_path,
                                      "--positions", table_path, "--added-by", "offline_fit",
                                      "--input"};
  const std::string single_input = args.csv.empty() ? args.samples : args.csv;
  for (const std::string& input : args.bags.empty() ? std::vector<std::string>{single_input} : args.bags)
    command.push_back(input);
  if (!args.device.empty()) command.insert(command.end(), {"--device", args.device});
  if (!args.rig.empty()) command.insert(command.end(), {"--rig", args.rig});
  if (!json_file && args.json_out == "-") command.push_back("--quiet");  // stdout holds the JSON
  int status = -1;
  try {
    if (!json_file) io::write_file_atomically(result_path, json);
    if (args.csv_out.empty()) {
      io::AtomicFile file(table_path);
      core::write_position_table(file.stream(), table);
      file.close();
      file.commit();
    }
    status = run_package_script("archive", command);
  } catch (const std::exception& e) {
    err << kOfflineFitProgram << ": warning: --archive: " << as_one_line(e.what()) << std::endl;
  }
  if (!json_file) std::remove(result_path.c_str());
  if (args.csv_out.empty()) std::remove(table_path.c_str());
  if (status != 0) {
    err << kOfflineFitProgram << ": warning: --archive: the result was not archived ("
        << package_script("archive") << " exit status " << status << ")" << std::endl;
  }
  return status == 0;
}

int run(const OfflineFitArguments& args, std::ostream& out, std::ostream& err) {
  check_command_line(args);
  core::CalibrateOptions options;
  try {
    options.fit.model = core::parse_model(args.model);
  } catch (const std::exception& e) {
    throw Failure{kOfflineFitBadCommandLine, "--model: " + as_one_line(e.what())};
  }
  options.fit.local_gravity = args.gravity;
  options.analyze = args.analyze;
  io::BudgetFile budget_file;
  if (!args.budget.empty()) {
    try {
      budget_file = io::read_budget_file(args.budget);
    } catch (const io::IoError& e) {
      throw Failure{kOfflineFitBadInput, as_one_line(e.what())};
    }
    options.budget = budget_file.spec;
  }

  options.output_unit = args.output_unit;
  Input input = !args.samples.empty() ? read_samples_input(args)
                : args.bags.empty()      ? read_csv_input(args)
                                         : read_bag_input(args, err);
  if (args.unknown_orientations) {
    // The gimbal's dwells as rests of unknown orientation: the same means, no angles.
    input.table = core::forget_orientations(std::move(input.table));
    core::RestDetection rests;
    rests.rests = input.table.rows;
    input.context.rest_detection = rests;
    input.raw = core::RawStreams();
  }
  check_phases(input.table, options.fit.model, options.fit.min_positions_per_phase, &input.context);
  input.context.certificate = budget_file.certificate;
  input.context.device_serial = args.device;  // --device (with --archive); "" = omitted
  input.context.gravity_source = args.gravity_given
                                     ? "offline_fit --gravity"
                                     : "standard gravity (offline_fit default; no --gravity given)";

  options = core::with_noise_model(std::move(options), input.noise_model);
  core::CalibrationReport report;
  try {
    const bool raw_usable = input.from_bag && !input.raw.commands.empty();
    report = core::calibrate(input.table, raw_usable ? &input.raw : nullptr, options);
  } catch (const core::FitError& e) {
    throw Failure{kOfflineFitBadInput, input.read_as + "fit failed: " + as_one_line(e.what())};
  } catch (const std::invalid_argument& e) {
    throw Failure{kOfflineFitBadInput, "fit failed: " + as_one_line(e.what())};
  }
  if (report.coverage && !report.coverage->complete()) {
    input.context.complete = false;
    for (const std::string& m : report.coverage->missing)
      input.context.warnings.push_back(m + ": add such a rest (the fit is weaker there)");
  }
  if (!report.analysis_error.empty()) {
    throw Failure{kOfflineFitBadInput,
                  "--analyze: discrepancy analysis failed: " + as_one_line(report.analysis_error)};
  }
  const std::string json = io::result_json_text(report, input.context);

  // Exports of the certificate, prepared before any file is written.
  std::string source = args.csv + args.samples;
  for (const std::string& b : args.bags) source += (source.empty() ? "" : ", ") + b;
  io::CalibrationToExport calibration = io::calibration_to_export(
      report, std::string(kOfflineFitProgram) + " result of " + source +
                              (args.json_out.empty() || args.json_out == "-" ? ""
                                                                            : " (" + args.json_out + ")"));
  std::vector<std::pair<std::string, io::ExportText>> exports;
  // A result that fails the quality gate is not a calibration: nothing for a robot to apply.
  if (!report.quality.pass && !args.exports.empty()) {
    err << kOfflineFitProgram
        << ": warning: no --export written: the result fails the quality gate" << std::endl;
  }
  for (const std::string& spec : report.quality.pass ? args.exports : std::vector<std::string>()) {
    const auto parsed = io::parse_export_spec(spec);
    try {
      exports.emplace_back(parsed.second, io::export_text(parsed.first, calibration));
    } catch (const io::IoError& e) {
      throw Failure{kOfflineFitBadInput, "--export " + spec + ": " + as_one_line(e.what())};
    }
  }

  // Outputs: files first (all or nothing), then the report.
  const bool json_to_stdout = args.json_out == "-";
  std::unique_ptr<io::AtomicFile> csv_file, json_file;
  if (!args.csv_out.empty()) {
    csv_file.reset(new io::AtomicFile(args.csv_out));
    core::write_position_table(csv_file->stream(), input.table);
    csv_file->close();
  }
  if (!args.json_out.empty() && !json_to_stdout) {
    json_file.reset(new io::AtomicFile(args.json_out));
    json_file->stream() << json;
    json_file->close();
  }
  std::vector<std::unique_ptr<io::AtomicFile>> export_files;
  for (const auto& e : exports) {
    export_files.emplace_back(new io::AtomicFile(e.first));
    export_files.back()->stream() << e.second.text;
    export_files.back()->close();
  }
  if (csv_file) csv_file->commit();
  if (json_file) json_file->commit();
  for (auto& f : export_files) f->commit();
  for (const auto& e : exports) {
    if (!e.second.notice.empty()) err << kOfflineFitProgram << ": note: " << e.second.notice << std::endl;
  }
  const bool archived = !args.archive.empty() && archive_result(args, json, input.table, err);
  if (!args.report_pdf.empty())
    write_certificate(json, input.table, report.certificate, args.report_pdf,
                      args.json_out.empty() || json_to_stdout ? "(not saved: offline_fit --json)"
                                                              : args.json_out,
                      archived ? args.archive : "", args.report_draft);

  io::write_text_report(json_to_stdout ? err : out, report, input.context);
  if (json_to_stdout) out << json << std::flush;
  if (!input.context.complete) {
    err << kOfflineFitProgram << ": warning: incomplete run, result from the dwells found: "
        << input.context.warnings.front() << std::endl;
  }
  if (!report.quality.pass) {
    err << kOfflineFitProgram << ": error: the result fails the quality gate: "
        << report.quality.summary() << std::endl;
    return kOfflineFitQualityFailed;
  }
  return kOfflineFitOk;
}

}  // namespace

std::string as_one_line(std::string text) {
  for (char& c : text) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return text;
}

int run_offline_fit(const OfflineFitArguments& args, std::ostream& out, std::ostream& err) {
  try {
    return run(args, out, err);
  } catch (const Failure& f) {
    err << kOfflineFitProgram << ": error: " << f.message << std::endl;
    return f.status;
  } catch (const std::exception& e) {
    err << kOfflineFitProgram << ": error: " << as_one_line(e.what()) << std::endl;
    return kOfflineFitBadInput;
  }
}

}  // namespace accel_intrinsics
