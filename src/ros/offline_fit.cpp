#include "accel_intrinsics/ros/offline_fit.h"

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
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/budget_file.h"
#include "accel_intrinsics/io/exporters.h"
#include "accel_intrinsics/io/residuals_csv.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/io/text_report.h"
#include "accel_intrinsics/ros/bag_input.h"
#include "accel_intrinsics/ros/offline_fit_residuals.h"
#include "accel_intrinsics/ros/scripts.h"
#include "offline_fit_internal.h"

namespace accel_intrinsics {
std::string channel_topic_option(std::size_t channel) {
  return std::string("--") + core::kChannels[channel].name + "-topic";
}

using namespace offline_fit_detail;

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
      throw Failure{kOfflineFitBadInput, std::string("too few dwells in phase ") +
                                             core::phase_name(p) + ": " + std::to_string(count) +
                                             ", at least " + std::to_string(min_positions) +
                                             " needed (" + tally.str() + ")"};
    }
  }
}

void check_command_line(const OfflineFitArguments& args) {
  const int inputs =
      (args.bags.empty() ? 0 : 1) + (args.csv.empty() ? 0 : 1) + (args.samples.empty() ? 0 : 1);
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
        throw Failure{kOfflineFitBadCommandLine,
                      "--export " + spec + ": '" + path + "' is already an output of this run"};
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
  std::vector<std::string> report_args = {
      "--out", pdf, "--residuals", residuals, "--result-name", result_name, tmp};
  // the device's history page, from the archive this result just went into
  if (!history_archive.empty())
    report_args.insert(report_args.begin(), {"--history-archive", history_archive});
  if (draft) report_args.insert(report_args.begin(), "--draft");
  const int status = run_package_script("certificate_report", report_args);
  std::remove(tmp.c_str());
  std::remove(residuals.c_str());
  if (status == 3) {  // refused; the script named why and how to fix it
    throw Failure{kOfflineFitBadInput,
                  "--report: no certificate (see above; --draft makes one "
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
  const std::string tmp =
      (std::filesystem::temp_directory_path() / "offline_fit_archive.").string() +
      std::to_string(::getpid());
  const bool json_file = !args.json_out.empty() && args.json_out != "-";
  const std::string result_path = json_file ? args.json_out : tmp + ".json";
  const std::string table_path = args.csv_out.empty() ? tmp + ".csv" : args.csv_out;
  std::vector<std::string> command = {"--archive",  args.archive,  "add",
                                      result_path,  "--positions", table_path,
                                      "--added-by", "offline_fit", "--input"};
  const std::string single_input = args.csv.empty() ? args.samples : args.csv;
  for (const std::string& input :
       args.bags.empty() ? std::vector<std::string>{single_input} : args.bags)
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
                : args.bags.empty()   ? read_csv_input(args)
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
      report,
      std::string(kOfflineFitProgram) + " result of " + source +
          (args.json_out.empty() || args.json_out == "-" ? "" : " (" + args.json_out + ")"));
  std::vector<std::pair<std::string, io::ExportText>> exports;
  // A result that fails the quality gate is not a calibration: nothing for a robot to apply.
  if (!report.quality.pass && !args.exports.empty()) {
    err << kOfflineFitProgram << ": warning: no --export written: the result fails the quality gate"
        << std::endl;
  }
  for (const std::string& spec : report.quality.pass ? args.exports : std::vector<std::string>()) {
    const auto parsed = io::parse_export_spec(spec);
    try {
      exports.emplace_back(parsed.second, io::export_text(parsed.first, calibration));
    } catch (const io::IoError& e) {
      throw Failure{kOfflineFitBadInput, "--export " + spec + ": " + as_one_line(e.what())};
    }
  }

  if (!args.residuals_csv.empty()) {
    const std::string why = residuals_csv_refusal(report);
    if (!why.empty()) throw Failure{kOfflineFitBadCommandLine, "--residuals-csv: " + why};
    write_offline_residuals_csv(args.residuals_csv, input.table, report);
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
    if (!e.second.notice.empty())
      err << kOfflineFitProgram << ": note: " << e.second.notice << std::endl;
  }
  const bool archived = !args.archive.empty() && archive_result(args, json, input.table, err);
  if (!args.report_pdf.empty())
    write_certificate(
        json, input.table, report.certificate, args.report_pdf,
        args.json_out.empty() || json_to_stdout ? "(not saved: offline_fit --json)" : args.json_out,
        archived ? args.archive : "", args.report_draft);

  io::write_text_report(json_to_stdout ? err : out, report, input.context);
  if (json_to_stdout) out << json << std::flush;
  if (!input.context.complete) {
    err << kOfflineFitProgram << ": warning: incomplete run, result from the dwells found: "
        << input.context.warnings.front() << std::endl;
  }
  if (!report.quality.pass) {
    err << kOfflineFitProgram
        << ": error: the result fails the quality gate: " << report.quality.summary() << std::endl;
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
