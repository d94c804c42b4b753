// offline_fit as a library: recalibrates from a recorded bag or a CSV position table, without
// playback (docs/design.md section 2, "Offline tool"). src/nodes/offline_fit.cpp is its command
// line; tests call run_offline_fit() in process.
//
//   offline_fit (--bag FILE|DIR [--bag ...] | --csv FILE | --samples FILE) [--unknown-orientations]
//               [--rest-min-s SECONDS] [--imu-topic T] [--command-topic T]
//               [--gravity G] [--model joint|eq4] [--analyze] [--json OUT] [--csv-out FILE]
//               [--settle-discard SECONDS] [--imu-time-offset SECONDS] [--skip-clock-check]
//               [--output-unit UNIT] [--export NAME=FILE]... [--budget FILE]
//               [--report FILE.pdf] [--archive URL [--device SERIAL] [--rig NAME]]
//
// The joint model takes any set of known orientations (position table rows with f_x,f_y,f_z)
// that determines S and O, and a gimbal run missing a phase when the others determine S: the
// result is then marked incomplete, naming the phase. eq4 needs the three phases.
//
// A hand tumble (docs/design.md section 11): --samples FILE (t,x,y,z), or a bag with the IMU topic
// and no gimbal commands: rests are found in the stream (core/rest_detection.h) and fitted by |P
// (mean - O)| = g (core/tumble.h); the result says "method": "tumble", its "frame", every rest and
// rejected span, the coverage (an incomplete one names the missing direction) and the next pose to
// try. --unknown-orientations fits a gimbal run's dwells the same way.
//
// A run split over several bags (rosbag record --split) is read as one: --bag repeated, or a
// directory of bags. Before fitting a bag, the clock check (core/clock_check.h) makes sure the
// IMU and the gimbal stamp on one clock; --imu-time-offset shifts the IMU stamps. Every result
// passes through the quality gate (core/quality.h): a failing one is written, with
// "quality": {"pass": false, ...}, and the exit status is 3.
//
// The bag goes through core::DwellAssembler (bag_input.h), the dwell assignment of the
// calibration node, and the table through core::calibrate(), the node's pipeline, so the result
// equals the online one for the same messages. The JSON is io::result_json_text (the keys of the
// node's intrinsics.yaml) with offline_fit's `input`, `complete` and `warnings`; --analyze adds the
// discrepancy analysis (base model always joint plus the effects it names, whatever --model says)
// and, on a bag, the timing lag from the raw streams. The certificate is the --model fit.
//
// --settle-discard (default 0) drops the samples of the first SECONDS of each dwell (after
// SETTLED), as the calibration node's settle_discard_s does: for a gimbal that still rings when
// it reports settled. Bags only.
//
// --export NAME=FILE (repeatable) writes the certificate for another tool (io/exporters.h:
// imu_calib, imucal, kalibr, imu_tk, px4, ardupilot), with the result files, all or nothing;
// what a format leaves out (px4/ardupilot: the largest error over all orientations) goes to
// stderr as "offline_fit: note: ...".
// --budget FILE (io/budget_file.h, config/uncertainty_budget.yaml) adds the type-B budget of the
// certificate (core/uncertainty_budget.h) as `uncertainty_budget`, and the file's certificate
// block as `certificate`. --report FILE.pdf writes the calibration certificate with
// scripts/certificate_report (/usr/bin/python3, matplotlib), from the same JSON.
// --archive URL adds the result, its position table and the input's sha256 to the lab archive
// (scripts/archive add) after the files are written; a failure to archive is a warning.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/ros/channel_messages.h"
#include "accel_intrinsics/ros/names.h"

namespace accel_intrinsics {

constexpr char kOfflineFitProgram[] = "offline_fit";

// Exit status of run_offline_fit.
enum OfflineFitStatus : int {
  kOfflineFitOk = 0,
  kOfflineFitBadInput = 1,  // unreadable or insufficient input, failed fit or analysis, I/O
  kOfflineFitBadCommandLine = 2,
  kOfflineFitQualityFailed = 3,  // outputs written; the result is not a calibration
};

// The command line, parsed (src/nodes/offline_fit.cpp); defaults as the tool's.
struct OfflineFitArguments {
  // Exactly one input: bags (and directories of bags), a CSV position table, or raw samples.
  std::vector<std::string> bags;
  std::string csv;
  // Raw samples t,x,y,z (core/samples_file.h): a hand tumble, rests found in the stream.
  std::string samples;
  // Fit the dwells of a gimbal bag or table as rests of unknown orientation (docs/design.md section
  // 11): with compare_results, tells a gimbal angle error from a device property.
  bool unknown_orientations = false;
  double rest_min_s = 2.0;  // shortest rest kept (samples, or a bag without gimbal commands)
  bool rest_min_s_given = false;
  std::string imu_topic = names::kImuTopic;
  std::string command_topic = names::kGimbalCommandTopic;
  // The per-dwell channels' topics (core::kChannels; --<name>-topic, e.g. --temperature-topic):
  // each used when the bag has it.
  core::PerChannel<std::string> channel_topics = default_channel_topics();
  double gravity = core::kStandardGravity;  // m/s^2
  std::string model = "joint";
  bool analyze = false;
  std::string json_out;  // "-": standard output (the text report then goes to `err`)
  std::string csv_out;
  double settle_discard_s = 0.0;
  double imu_time_offset_s = 0.0;     // added to every IMU stamp
  std::string output_unit = "m/s^2";  // unit of the raw outputs (counts, V, ...)
  bool skip_clock_check = false;
  std::vector<std::string> exports;  // "NAME=FILE", each parsed by io::parse_export_spec
  std::string budget;                // uncertainty budget file (YAML); empty: type A only
  std::string report_pdf;            // certificate PDF; empty: none
  // Residual CSV for scripts/plot_residuals (offline_fit_residuals.h); empty: none.
  std::string residuals_csv;
  bool report_draft = false;  // --draft: the PDF even when refused, DRAFT on every page
  // Lab archive URL (scripts/archive, docs/design.md section 13); empty: none. device and rig name
  // the record when the budget file's certificate block has no serial or rig.
  std::string archive;
  std::string device;
  std::string rig;
  // Given explicitly (they apply to --bag only, and are refused with --csv).
  bool imu_topic_given = false;
  bool command_topic_given = false;
  core::PerChannel<bool> channel_topic_given{};
  bool settle_discard_given = false;
  bool imu_time_offset_given = false;
  bool gravity_given = false;
};

// The command-line option of a channel's topic: "--temperature-topic" (core::kChannels).
std::string channel_topic_option(std::size_t channel);

// Parses the command line (arguments without the program name) into `args`. Returns false when
// the tool should exit at once with *exit_status: --help (0, the help on `out`) or a malformed
// command line (kOfflineFitBadCommandLine, one line on `err`). Values are checked by
// run_offline_fit.
bool parse_offline_fit_arguments(const std::vector<std::string>& arguments,
                                 OfflineFitArguments* args, int* exit_status, std::ostream& out,
                                 std::ostream& err);

// Runs the tool: the text report on `out` (on `err` when json_out is "-"), progress, warnings
// and errors on `err`. Returns the exit status; every failure prints exactly one line
// "offline_fit: error: ..." on `err` and writes no output file. Output files (json_out, csv_out)
// appear only on success, each atomically (io/atomic_file.h).
int run_offline_fit(const OfflineFitArguments& args, std::ostream& out, std::ostream& err);

// `text` with line breaks replaced by spaces (one-line error messages).
std::string as_one_line(std::string text);

}  // namespace accel_intrinsics
