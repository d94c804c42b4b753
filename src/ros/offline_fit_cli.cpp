// offline_fit's command line (include/accel_intrinsics/ros/offline_fit.h): one parser for the
// program (src/nodes/offline_fit.cpp) and the tests.
#include <CLI/CLI.hpp>
#include <ostream>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/io/exporters.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace accel_intrinsics {

bool parse_offline_fit_arguments(const std::vector<std::string>& arguments,
                                 OfflineFitArguments* args, int* exit_status, std::ostream& out,
                                 std::ostream& err) {
  CLI::App app{
      "Recalibrates a three-axis accelerometer offline from a recorded bag (read directly, no "
      "playback), a CSV position table or the raw samples of a hand tumble, and prints the "
      "intrinsic parameters with their "
      "standard uncertainties."};
  app.name(kOfflineFitProgram);
  app.footer(
      "Exit status: 0 success; 1 bad input (also IMU and gimbal on different clocks) or failed "
      "fit; 2 bad command line; 3 the result fails the quality gate (reduced chi-square far "
      "above its band, implausible responsivities or angles, starved dwells): the outputs are "
      "written, with \"quality\": {\"pass\": false, \"reasons\": [...]}. Failures 1 and 2 "
      "print one line on stderr and write no output file.");
  app.add_option("--bag", args->bags,
                 "recorded run (rosbag); repeat it, or name a directory, for a run split over "
                 "several bags")
      ->type_name("FILE|DIR");
  std::string channel_columns;
  for (const core::ChannelSpec& spec : core::kChannels)
    channel_columns +=
        std::string("; optionally ,") + spec.column + ": dwell " + spec.name + " in " + spec.unit;
  app.add_option("--csv", args->csv,
                 "position table: " + std::string(core::kPositionTableHeader) + " (optionally" +
                     core::kDirectionColumns + ": known orientations, phase '-'" + channel_columns +
                     ")");
  app.add_option("--samples", args->samples,
                 "raw samples of a hand tumble: t,x,y,z a line (seconds, then the three outputs in "
                 "any unit), comma or whitespace, header optional; rests are found in the stream")
      ->type_name("FILE");
  app.add_flag("--unknown-orientations", args->unknown_orientations,
               "fit a gimbal run's dwells (--bag or --csv) as rests of unknown orientation, as a "
               "hand tumble is fitted; compare with the gimbal fit to tell a gimbal angle error "
               "from a device property");
  auto* rest_min = app.add_option("--rest-min-s", args->rest_min_s,
                                  "shortest rest kept when rests are found in a stream (--samples, "
                                  "or a bag without gimbal commands)")
                       ->type_name("SECONDS")
                       ->capture_default_str();
  auto* imu =
      app.add_option("--imu-topic", args->imu_topic, "IMU topic in the bag (sensor_msgs/Imu)")
          ->capture_default_str();
  auto* command = app.add_option("--command-topic", args->command_topic,
                                 "gimbal command topic in the bag (accel_intrinsics/GimbalCommand)")
                      ->capture_default_str();
  core::PerChannel<CLI::Option*> channel_topic;
  for (const core::ChannelSpec& spec : core::kChannels) {
    const std::size_t c = core::channel_index(spec.id);
    channel_topic[c] =
        app.add_option(channel_topic_option(c), args->channel_topics[c],
                       std::string("DUT ") + spec.name + " topic in the bag (" + spec.message_type +
                           ", " + spec.unit + "; used when present, required when given)")
            ->capture_default_str();
  }
  auto* gravity =
      app.add_option("--gravity", args->gravity, "local gravity g in m/s^2")->capture_default_str();
  app.add_option("--model", args->model, "fit model: joint or eq4")->capture_default_str();
  app.add_flag("--analyze", args->analyze, "also run the discrepancy analysis (missing effects)");
  app.add_option("--json", args->json_out, "write the result as JSON to this file ('-': stdout)");
  app.add_option("--csv-out", args->csv_out, "write the position table (dwell means) as CSV");
  auto* settle = app.add_option("--settle-discard", args->settle_discard_s,
                                "bag only: drop the samples of the first SECONDS of each dwell "
                                "(after the gimbal reports SETTLED), like the calibration node's "
                                "settle_discard_s")
                     ->type_name("SECONDS")
                     ->capture_default_str();
  auto* offset =
      app.add_option("--imu-time-offset", args->imu_time_offset_s,
                     "bag only: add SECONDS to every IMU stamp (an IMU clock offset from the "
                     "gimbal's; the clock check names the value)")
          ->type_name("SECONDS");
  app.add_option("--output-unit", args->output_unit,
                 "unit of the raw outputs (m/s^2, or counts, V, ...: responsivities are then in "
                 "that unit per m/s^2)")
      ->capture_default_str();
  app.add_flag("--skip-clock-check", args->skip_clock_check,
               "bag only: do not check that IMU and gimbal stamps share one clock");
  app.add_option("--export", args->exports,
                 "write the calibration for another tool (repeatable): NAME=FILE, NAME one of " +
                     io::export_format_list())
      ->type_name("NAME=FILE")
      ->take_all();
  app.add_option("--budget", args->budget,
                 "uncertainty budget (YAML, config/uncertainty_budget.yaml): adds the type-B "
                 "budget and expanded uncertainties (k = 2) to the result");
  app.add_option("--report", args->report_pdf,
                 "write a calibration certificate (PDF) from the result");
  app.add_option("--residuals-csv", args->residuals_csv,
                 "write the residuals of the fit (and, with --analyze, of the refit with the "
                 "named effects) per dwell and accelerometer as CSV, for scripts/plot_residuals")
      ->type_name("FILE");
  app.add_flag("--draft", args->report_draft,
               "--report: make the PDF even when a certificate is refused (standard g with a "
               "small g uncertainty, the template's certificate block), DRAFT on every page");
  auto* archive = app.add_option("--archive", args->archive,
                                 "add the result to the lab archive (sqlite:///PATH or "
                                 "postgresql://...; scripts/archive)")
                      ->type_name("URL");
  app.add_option("--device", args->device,
                 "device serial for --archive (default: the budget file's certificate serial)")
      ->needs(archive);
  app.add_option("--rig", args->rig,
                 "rig name for --archive (default: the budget file's certificate rig)")
      ->needs(archive);
  try {
    std::vector<std::string> reversed(arguments.rbegin(), arguments.rend());
    app.parse(reversed);
  } catch (const CLI::CallForHelp& e) {
    *exit_status = app.exit(e, out, err);
    return false;
  } catch (const CLI::CallForAllHelp& e) {
    *exit_status = app.exit(e, out, err);
    return false;
  } catch (const CLI::ParseError& e) {
    err << kOfflineFitProgram << ": error: " << as_one_line(e.what()) << " (see --help)"
        << std::endl;
    *exit_status = kOfflineFitBadCommandLine;
    return false;
  }
  args->imu_topic_given = imu->count() > 0;
  args->command_topic_given = command->count() > 0;
  for (std::size_t c = 0; c < core::kChannelCount; ++c)
    args->channel_topic_given[c] = channel_topic[c]->count() > 0;
  args->settle_discard_given = settle->count() > 0;
  args->imu_time_offset_given = offset->count() > 0;
  args->gravity_given = gravity->count() > 0;
  args->rest_min_s_given = rest_min->count() > 0;

  return true;
}

}  // namespace accel_intrinsics
