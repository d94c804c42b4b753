// Reads a recorded run from a bag (no playback) and feeds the gimbal commands and IMU samples, in
// bag (receive) order, to core::DwellAssembler: the same dwell assignment the calibration node
// runs online, so offline and online agree to the last digit. The parts: bag_format.h (the file
// format, the chunk scan, the structure check), bag_topics.h (which topics hold the run), and
// this feed loop (messages to the assembler, through the chunk scan or rosbag::View).
#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "accel_intrinsics/core/analysis/clock_check.h"
#include "accel_intrinsics/core/dwells/dwell_assembler.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/noise/rest_accumulator.h"
#include "accel_intrinsics/ros/bag_topics.h"
#include "accel_intrinsics/ros/channel_messages.h"
#include "accel_intrinsics/ros/names.h"

namespace accel_intrinsics {

struct BagInputOptions {
  // Topic names as requested: "imu/data_raw" matches "/imu/data_raw" and a single namespaced
  // "/<ns>/imu/data_raw"; a leading '/' asks for that exact topic. See resolve_topic().
  std::string imu_topic = names::kImuTopic;
  std::string command_topic = names::kGimbalCommandTopic;
  // The per-dwell channels' topics (core::kChannels; the DUT temperature, docs/design.md section
  // 10): each read when the bag has it (each dwell then records its value); "" never reads one.
  core::PerChannel<std::string> channel_topics = default_channel_topics();
  // Dwell assembly. The reorder window defaults to 10 s, wider than any shipped configuration
  // (node 0.25 s, simulated stand 5 s): in a bag it costs only memory (window x rate events) and
  // a little time, and it keeps messages that a recorder received late (a sim-time recording
  // stretches transport delays). The result equals the node's whenever neither dropped a message
  // as late (counters.dropped_late; offline_fit warns when it is not 0).
  core::AssemblerOptions assembler = default_assembler_options();
  static core::AssemblerOptions default_assembler_options() {
    core::AssemblerOptions o;
    o.reorder_window_s = 10.0;
    return o;
  }
  // Read uncompressed, unencrypted, indexed 2.0 bags (rosbag record's default) straight from a
  // memory map instead of through rosbag::Bag and rosbag::View: several times faster, the same
  // messages (in file order = write order). Any other bag, or one whose records look odd, goes
  // through rosbag. false: always rosbag (tests compare the two).
  bool allow_chunk_scan = true;
  // Progress on `progress_stream` (stderr by default) once per `progress_interval_s` of wall time
  // when reading takes longer than that; nullptr for none.
  std::ostream* progress_stream = nullptr;
  double progress_interval_s = 1.0;
  std::string progress_label = "reading bag";
  // When set, every accepted command and IMU sample is also appended here, in bag order, for
  // the raw-stream analyses (timing lag). Memory then grows with the bag.
  std::vector<core::GimbalEvent>* raw_commands = nullptr;
  std::vector<core::ImuSample>* raw_samples = nullptr;
  // Added to every IMU stamp (a device clock offset from the gimbal's; docs/design.md section 5).
  double imu_time_offset_s = 0.0;
  // When set, sees every accepted command and (shifted) IMU sample: the clock check.
  core::ClockCheck* clock_check = nullptr;
  // When set, fed the commands and samples the assembler releases in stamp order (as the live
  // run's, calibration_run.cpp): the run's first dwell accumulated as it comes, in constant
  // memory, for the noise model (docs/noise.md). Set its settle discard to the assembler's.
  core::LongRestRecorder* long_rest = nullptr;
  // The IMU topic was not named: a bag whose only sensor_msgs/Imu topic has another name uses it.
  bool imu_by_type = false;
  // Flush the assembler after the last message (false: more bags of the same run follow).
  bool flush_at_end = true;
  // A bag without any gimbal command topic is read (IMU, and channels, only; command_topic in
  // the statistics empty) instead of refused: a hand tumble.
  bool command_topic_optional = false;
};

struct BagInputStats {
  std::string path;
  std::string imu_topic;                         // as resolved in the bag
  std::string command_topic;                     // as resolved in the bag
  core::PerChannel<std::string> channel_topics;  // as resolved in the bag; "" when it has none
  std::uint64_t imu_messages = 0;
  core::PerChannel<std::uint64_t> channel_messages{};
  std::uint64_t command_messages = 0;
  // Rejected as the calibration node rejects them: phase or state outside the constants, angle
  // not finite, steps 0 or step >= steps, zero stamp.
  std::uint64_t invalid_commands = 0;
  double bag_start_s = 0.0;  // bag (receive) time of the first and last message read
  double bag_end_s = 0.0;
  double read_wall_s = 0.0;  // wall time spent reading and assembling
  bool done_seen = false;    // the controller's DONE was in the bag
  // The dwell that was still open when the bag ended (no DONE): it is not in the table.
  bool open_dwell = false;
  core::Phase open_dwell_phase = core::Phase::X;
  std::uint32_t open_dwell_step = 0;
  std::uint64_t open_dwell_samples = 0;
  // Positions per phase the controller announced (GimbalCommand::steps; 0 = none seen).
  std::uint32_t steps_announced[3] = {0, 0, 0};
  core::AssemblerCounters counters;
  std::string reader;       // "chunk scan" or "rosbag::View"
  std::string topic_note;   // the IMU topic was found by its type (RunTopics::note)
  std::uint32_t files = 1;  // bags read for this run
};

struct BagRun {
  core::PositionTable table;
  BagInputStats stats;
};

// Opens `path`, resolves both topics and feeds every message of them, in bag order, to
// `assembler`, then flushes it. The assembler's dwell callback and table are the caller's.
// Throws BagInputError.
BagInputStats feed_bag(const std::string& path, const BagInputOptions& options,
                       core::DwellAssembler& assembler);

// feed_bag into a fresh assembler with options.assembler; returns its table and the statistics.
BagRun read_bag(const std::string& path, const BagInputOptions& options = {});

// One run recorded into several bags (rosbag record --split, or restarted recorders): `paths`
// may name bags and directories (their *.bag files). The bags are fed in the order of their
// first message into one assembler, flushed once at the end, so messages reordered across a
// file boundary still land in their dwells. Statistics are summed; topics must resolve to the
// same names in every bag.
BagRun read_bags(const std::vector<std::string>& paths, const BagInputOptions& options = {});

// `paths` with directories replaced by their *.bag files (sorted); throws BagInputError for a
// directory without bags or a path that does not exist.
std::vector<std::string> expand_bag_paths(const std::vector<std::string>& paths);

}  // namespace accel_intrinsics
