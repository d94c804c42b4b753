// accel_intrinsics_fit's inputs: a position table CSV, a samples file (rests detected in the
// stream), or recorded bags (offline_fit.h).
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <memory>
#include <optional>
#include <ostream>
#include <sstream>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/dwells/rest_detection.h"
#include "accel_intrinsics/core/dwells/samples_file.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/fit/tumble.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/noise/rest_accumulator.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/budget_file.h"
#include "accel_intrinsics/io/exporters.h"
#include "accel_intrinsics/io/residuals_csv.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/io/text_report.h"
#include "accel_intrinsics/ros/bag_input.h"
#include "accel_intrinsics/ros/offline_fit.h"
#include "accel_intrinsics/ros/scripts.h"
#include "offline_fit_internal.h"

namespace accel_intrinsics {
namespace offline_fit_detail {

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
  // The noise model of the first rest of at least 30 s, when there is one (docs/design.md section
  // 12): the tumble fit and its analysis are then generalized least squares across the rests.
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
          << " s): " << input.table.rows.size() << " rests found, "
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
  // The run's first dwell accumulated in the one read, as the live run does (its long rest).
  core::LongRestRecorder long_rest(args.settle_discard_s);
  options.long_rest = &long_rest;
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
    throw Failure{kOfflineFitBadInput, "--unknown-orientations: " + st.path +
                                           " has no gimbal commands (a tumble already)"};
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
      again.long_rest = nullptr;
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
  } else if (long_rest.holds_long_rest(input.table, 0.0)) {
    // The long rest is the run's first dwell (a gimbal protocol's initial rest): its statistics
    // came with the one read, as the live run's, and nothing was kept per sample.
    try {
      input.noise_model = long_rest.noise_model(input.table, 0.0);
    } catch (const std::invalid_argument& e) {
      err << kOfflineFitProgram << ": note: no noise model from the long rest: " << e.what()
          << std::endl;
    }
  } else if (core::find_long_rest(input.table)) {
    // A long rest after the first dwell (a dwell 10 times the median, later in the run) was not
    // accumulated while reading: the noise model needs its raw samples, not only its mean and
    // std. With --analyze they were kept, otherwise the bags are read once more for them (only
    // such runs pay for it).
    std::vector<core::ImuSample> kept;
    const std::vector<core::ImuSample>* samples = &input.raw.samples;
    if (!args.analyze) {
      BagInputOptions again = options;
      again.raw_samples = &kept;
      again.raw_commands = nullptr;
      again.clock_check = nullptr;
      again.long_rest = nullptr;
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
  summary << (st.files > 1 ? "bags " : "bag ") << st.path << " (" << st.imu_messages
          << " IMU messages on " << st.imu_topic << ", ";
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

}  // namespace offline_fit_detail
}  // namespace accel_intrinsics
