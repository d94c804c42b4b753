// Joins IMU samples to dwells by header stamp (docs/design.md section 2). One implementation for
// the calibration node and offline_fit, so online and offline agree to the last digit.
//
// Commands and samples may arrive out of stamp order (separate topics, transport delays, bag
// receive order). Events wait in a reorder buffer of `reorder_window_s` and are processed in
// stamp order once older than the newest stamp seen minus that window; memory is bounded by the
// window, not the dwell length. At equal stamps a command goes before a sample, so a dwell is the
// half-open interval [SETTLED, next MOVING or DONE). Samples may arrive in any order inside the
// window; a sample that repeats the stamp of the one before it (in stamp order) is counted as a
// duplicate when its values are the same and dropped as conflicting when they are not.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <functional>
#include <queue>
#include <string>
#include <variant>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {

enum class GimbalState : std::uint8_t { Moving = 0, Settled = 1, Done = 2 };

// A GimbalCommand message, ROS-free.
struct GimbalEvent {
  double stamp_s = 0.0;
  Phase phase = Phase::X;
  std::uint32_t step = 0;
  std::uint32_t steps = 0;
  double angle_rad = 0.0;
  GimbalState state = GimbalState::Moving;
};

struct ImuSample {
  double stamp_s = 0.0;
  Eigen::Vector3d outputs = Eigen::Vector3d::Zero();  // R_u, R_v, R_w in m/s^2
};

// A sensor_msgs/Temperature reading (imu/temperature), ROS-free: degrees C at a stamp (what the
// simulators record); the assembler takes it as a ChannelSample.
struct TemperatureSample {
  double stamp_s = 0.0;
  double temperature_c = 0.0;
};
inline ChannelSample channel_sample(const TemperatureSample& reading) {
  return ChannelSample{Channel::Temperature, reading.stamp_s, reading.temperature_c};
}

struct AssemblerOptions {
  double settle_discard_s = 0.0;   // samples in the first part of each dwell are dropped
  double reorder_window_s = 0.25;  // how late (in stamp time) a message may arrive
};

// What was dropped and why; all counts since the last reset.
struct AssemblerCounters {
  std::uint64_t samples_used = 0;
  std::uint64_t dropped_outside_dwell = 0;  // MOVING, before the first command, after DONE
  std::uint64_t dropped_settle_discard = 0;
  std::uint64_t dropped_non_finite = 0;
  // The stamp of an earlier sample with other values (a device clock that went back).
  std::uint64_t dropped_backwards = 0;
  std::uint64_t duplicates = 0;    // the same stamp and values again (a duplicated message)
  std::uint64_t dropped_late = 0;  // arrived after the reorder window had passed its stamp
  // Channel readings (core::kChannels, by channel_index) averaged into a dwell, and those dropped
  // (outside every dwell, in the settle discard, late, or not finite).
  PerChannel<std::uint64_t> channel_used{};
  PerChannel<std::uint64_t> channel_dropped{};
  std::uint64_t commands = 0;
  std::uint64_t commands_out_of_order = 0;  // SETTLED that does not follow its MOVING, etc.
  std::string last_warning;                 // the latest out-of-protocol event, for logs
};

// The dwells a call completed, in stamp order (each also appended to table()). Returned, not
// called back: the caller acts on them after the assembler has returned (a fault may then
// reset the assembler).
using CompletedRows = std::vector<DwellRecord>;

class DwellAssembler {
 public:
  explicit DwellAssembler(const AssemblerOptions& options = {});

  // Called for every command and every finite, in-order sample as it is released in stamp order
  // (before it is assigned to a dwell): what a raw-stream analysis needs (MoveSampleRecorder).
  using CommandObserver = std::function<void(const GimbalEvent&)>;
  using SampleObserver = std::function<void(const ImuSample&)>;
  void set_release_observers(CommandObserver on_command, SampleObserver on_sample) {
    observe_command_ = std::move(on_command);
    observe_sample_ = std::move(on_sample);
  }
  // Called for every channel reading as it is released in stamp order (before it is assigned to
  // a dwell): with the two above, the whole release order.
  using ChannelObserver = std::function<void(const ChannelSample&)>;
  void set_channel_observer(ChannelObserver on_channel) {
    observe_channel_ = std::move(on_channel);
  }

  // Each input returns the dwells it completed (most calls: none).
  CompletedRows add_command(const GimbalEvent& event);
  CompletedRows add_sample(const ImuSample& sample);
  // Channel readings join dwells by stamp like samples; a dwell's value of the channel is their
  // aggregate (ChannelSpec::aggregate; NaN when it got none).
  CompletedRows add_channel_sample(const ChannelSample& reading);
  // Processes everything buffered (end of a bag, or DONE plus the reorder window online).
  CompletedRows flush();
  // Processes buffered events with stamps up to `stamp_s` (a node's timer).
  CompletedRows flush_until(double stamp_s);
  void reset();

  const PositionTable& table() const { return table_; }
  const AssemblerCounters& counters() const { return counters_; }
  bool done() const { return done_; }
  // Stamp of the first gimbal command seen (NaN before any).
  double time_origin_s() const { return table_.time_origin_s; }
  // The dwell being accumulated (phase, step) and how many samples so far; false if none.
  bool current_dwell(Phase* phase, std::uint32_t* step, std::uint64_t* samples) const;
  // Events waiting in the reorder buffer (at most reorder window x message rate) and the bytes
  // it and the table hold: the test of memory that does not grow with a dwell's length.
  std::size_t buffered_events() const {
    return in_order_samples_.size() + in_order_events_.size() + pending_.size();
  }
  std::size_t memory_bytes() const;

 private:
  struct Event {
    double stamp_s;
    std::uint64_t sequence;  // arrival order, breaks ties
    std::variant<GimbalEvent, ImuSample, ChannelSample> payload;
    bool is_command() const { return std::holds_alternative<GimbalEvent>(payload); }
  };
  // A channel's readings of the current dwell.
  struct ChannelAccumulator {
    double sum = 0.0;
    std::uint64_t count = 0;
    double value(Aggregate aggregate) const;
  };
  // Where an event goes in the release order: stamp, then commands first, then arrival.
  struct Key {
    double stamp_s;
    bool command;
    std::uint64_t sequence;
  };
  static bool later(const Key& a, const Key& b);
  static Key key(const Event& e) { return Key{e.stamp_s, e.is_command(), e.sequence}; }
  struct Later {
    bool operator()(const Event& a, const Event& b) const { return later(key(a), key(b)); }
  };
  // A stretch of the in-order buffer: one command or channel reading (the front of
  // in_order_events_), or `samples` IMU samples (in_order_samples_) whose arrival sequences are
  // first_sequence, first_sequence + 1, ...: a sample's sequence without storing it.
  struct Run {
    std::uint64_t first_sequence;
    std::uint64_t samples;  // 0: one event of in_order_events_
  };

  // Completed dwells are appended to `out`.
  void push(Event event, CompletedRows* out);
  void push_sample(const ImuSample& sample, CompletedRows* out);
  Key in_order_front() const;
  Key in_order_back() const;
  void release_until(double stamp_s, CompletedRows* out);
  void note_released(double stamp_s);  // released_until_s_ up to an event just released
  void process(const Event& event, CompletedRows* out);
  void process_released_sample(const ImuSample& sample);
  void process_command(const GimbalEvent& command, CompletedRows* out);
  void process_sample(const ImuSample& sample);
  void process_channel(const ChannelSample& reading);
  void close_dwell(double end_stamp_s, CompletedRows* out);

  AssemblerOptions options_;
  CommandObserver observe_command_;
  SampleObserver observe_sample_;
  ChannelObserver observe_channel_;
  // The reorder buffer. Events that arrive in order (the common case: every message of a
  // driver) are appended to the in-order part, already sorted; only those that arrive before an
  // earlier one go to the heap. Released: the earlier of the two fronts, so the order is the
  // heap's alone (stamp, commands first, arrival), at O(1) per in-order event instead of
  // O(log n). The in-order part holds its IMU samples as they are (32 bytes: stamp and outputs,
  // no sequence, no variant) and, in runs_, the order of samples and other events; a run of
  // samples gives each its sequence back. The heap (rare) holds whole events.
  std::deque<Run> runs_;
  std::deque<ImuSample> in_order_samples_;
  std::deque<Event> in_order_events_;
  std::priority_queue<Event, std::vector<Event>, Later> pending_;
  bool pending_empty() const { return runs_.empty() && pending_.empty(); }
  std::uint64_t next_sequence_ = 0;
  double newest_stamp_s_;
  double released_until_s_;
  double last_sample_stamp_s_;  // of the newest sample released
  Eigen::Vector3d last_sample_outputs_ = Eigen::Vector3d::Zero();

  // Dwell state (in stamp order).
  bool have_moving_ = false;
  GimbalEvent last_moving_;
  bool in_dwell_ = false;
  GimbalEvent dwell_command_;
  DwellAccumulator accumulator_;
  PerChannel<ChannelAccumulator> channel_accumulators_{};
  bool done_ = false;

  PositionTable table_;
  AssemblerCounters counters_;
};

}  // namespace core
}  // namespace accel_intrinsics
