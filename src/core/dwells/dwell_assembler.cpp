#include "accel_intrinsics/core/dwells/dwell_assembler.h"

#include <cmath>
#include <limits>
#include <sstream>

namespace accel_intrinsics {
namespace core {

namespace {
constexpr double kNegInf = -std::numeric_limits<double>::infinity();

std::string describe(const GimbalEvent& e) {
  static const char* const kStates[] = {"MOVING", "SETTLED", "DONE"};
  std::ostringstream s;
  s << kStates[static_cast<int>(e.state) % 3] << " (phase " << phase_name(e.phase) << ", step "
    << e.step << ") at t=" << e.stamp_s;
  return s.str();
}
}  // namespace

// The in-order buffer keeps a sample in 32 bytes (docs/noise.md "Where the calibration node's
// memory goes").
static_assert(sizeof(ImuSample) == 32, "ImuSample: a stamp and three doubles");

bool DwellAssembler::later(const Key& a, const Key& b) {
  // Min-heap on stamp; at equal stamps a command before a sample, then arrival order.
  if (a.stamp_s != b.stamp_s) return a.stamp_s > b.stamp_s;
  if (a.command != b.command) return !a.command;
  return a.sequence > b.sequence;
}

DwellAssembler::DwellAssembler(const AssemblerOptions& options) : options_(options) {
  reset();
}

void DwellAssembler::reset() {
  pending_ = decltype(pending_)();
  runs_.clear();
  in_order_samples_.clear();
  in_order_events_.clear();
  next_sequence_ = 0;
  newest_stamp_s_ = kNegInf;
  released_until_s_ = kNegInf;
  last_sample_stamp_s_ = kNegInf;
  have_moving_ = false;
  in_dwell_ = false;
  accumulator_.reset();
  channel_accumulators_ = {};
  done_ = false;
  table_ = PositionTable();
  counters_ = AssemblerCounters();
}

CompletedRows DwellAssembler::add_command(const GimbalEvent& event) {
  ++counters_.commands;
  CompletedRows out;
  if (!std::isfinite(event.stamp_s) || !std::isfinite(event.angle_rad)) {
    ++counters_.commands_out_of_order;
    counters_.last_warning = "gimbal command with a non-finite stamp or angle ignored";
    return out;
  }
  if (event.stamp_s < released_until_s_) {
    // Too late to put in order: the samples around it have been assigned already.
    ++counters_.commands_out_of_order;
    counters_.last_warning =
        "gimbal command " + describe(event) + " arrived after its stamp was processed";
  }
  push(Event{event.stamp_s, next_sequence_++, event}, &out);
  return out;
}

CompletedRows DwellAssembler::add_sample(const ImuSample& sample) {
  CompletedRows out;
  if (!std::isfinite(sample.stamp_s) || !sample.outputs.allFinite()) {
    ++counters_.dropped_non_finite;
    return out;
  }
  if (sample.stamp_s < released_until_s_) {
    ++counters_.dropped_late;
    return out;
  }
  push_sample(sample, &out);
  return out;
}

CompletedRows DwellAssembler::add_channel_sample(const ChannelSample& reading) {
  CompletedRows out;
  if (!std::isfinite(reading.stamp_s) || !std::isfinite(reading.value) ||
      reading.stamp_s < released_until_s_) {
    ++counters_.channel_dropped[channel_index(reading.channel)];
    return out;
  }
  push(Event{reading.stamp_s, next_sequence_++, reading}, &out);
  return out;
}

void DwellAssembler::push(Event event, CompletedRows* out) {
  if (event.stamp_s > newest_stamp_s_) newest_stamp_s_ = event.stamp_s;
  if (event.stamp_s < released_until_s_) {
    process(event, out);  // a late command: best effort, already counted
    return;
  }
  if (runs_.empty() || !later(in_order_back(), key(event))) {
    runs_.push_back(Run{event.sequence, 0});
    in_order_events_.push_back(std::move(event));
  } else {
    pending_.push(std::move(event));
  }
  release_until(newest_stamp_s_ - options_.reorder_window_s, out);
}

// push() for a sample (never late here: add_sample drops those), without making it an Event
// unless it goes to the heap.
void DwellAssembler::push_sample(const ImuSample& sample, CompletedRows* out) {
  const std::uint64_t sequence = next_sequence_++;
  if (sample.stamp_s > newest_stamp_s_) newest_stamp_s_ = sample.stamp_s;
  if (runs_.empty() || !later(in_order_back(), Key{sample.stamp_s, false, sequence})) {
    Run* run = runs_.empty() ? nullptr : &runs_.back();
    if (run && run->samples != 0 && run->first_sequence + run->samples == sequence) {
      ++run->samples;
    } else {
      runs_.push_back(Run{sequence, 1});
    }
    in_order_samples_.push_back(sample);
  } else {
    pending_.push(Event{sample.stamp_s, sequence, sample});
  }
  release_until(newest_stamp_s_ - options_.reorder_window_s, out);
}

void DwellAssembler::note_released(double stamp_s) {
  if (stamp_s > released_until_s_) released_until_s_ = stamp_s;
}

DwellAssembler::Key DwellAssembler::in_order_front() const {
  const Run& run = runs_.front();
  if (run.samples == 0) return key(in_order_events_.front());
  return Key{in_order_samples_.front().stamp_s, false, run.first_sequence};
}

DwellAssembler::Key DwellAssembler::in_order_back() const {
  const Run& run = runs_.back();
  if (run.samples == 0) return key(in_order_events_.back());
  return Key{in_order_samples_.back().stamp_s, false, run.first_sequence + run.samples - 1};
}

CompletedRows DwellAssembler::flush_until(double stamp_s) {
  CompletedRows out;
  release_until(stamp_s, &out);
  return out;
}

CompletedRows DwellAssembler::flush() {
  return flush_until(std::numeric_limits<double>::infinity());
}

void DwellAssembler::release_until(double stamp_s, CompletedRows* out) {
  while (!pending_empty()) {
    // The earlier of the two fronts (later(): a strict total order, sequences are unique).
    const bool from_heap =
        runs_.empty() || (!pending_.empty() && later(in_order_front(), key(pending_.top())));
    if (from_heap) {
      if (pending_.top().stamp_s > stamp_s) break;
      const Event event = pending_.top();
      pending_.pop();
      note_released(event.stamp_s);
      process(event, out);
    } else if (runs_.front().samples == 0) {
      if (in_order_events_.front().stamp_s > stamp_s) break;
      const Event event = std::move(in_order_events_.front());
      in_order_events_.pop_front();
      runs_.pop_front();
      note_released(event.stamp_s);
      process(event, out);
    } else {
      if (in_order_samples_.front().stamp_s > stamp_s) break;
      const ImuSample sample = in_order_samples_.front();
      in_order_samples_.pop_front();
      Run& run = runs_.front();
      if (--run.samples == 0) {
        runs_.pop_front();
      } else {
        ++run.first_sequence;
      }
      note_released(sample.stamp_s);
      process_released_sample(sample);
    }
  }
  if (stamp_s > released_until_s_ && pending_empty() && std::isfinite(stamp_s))
    released_until_s_ = stamp_s;
}

void DwellAssembler::process(const Event& event, CompletedRows* out) {
  if (const auto* command = std::get_if<GimbalEvent>(&event.payload)) {
    if (observe_command_) observe_command_(*command);
    process_command(*command, out);
  } else if (const auto* reading = std::get_if<ChannelSample>(&event.payload)) {
    if (observe_channel_) observe_channel_(*reading);
    process_channel(*reading);
  } else {
    process_released_sample(std::get<ImuSample>(event.payload));
  }
}

void DwellAssembler::process_released_sample(const ImuSample& sample) {
  // Released in stamp order, so a sample with the stamp of the previous one is a copy (the
  // same values: a duplicated message, used once) or a conflict (a clock that went back).
  if (sample.stamp_s == last_sample_stamp_s_) {
    if (sample.outputs == last_sample_outputs_) {
      ++counters_.duplicates;
    } else {
      ++counters_.dropped_backwards;
    }
    return;
  }
  if (sample.stamp_s > last_sample_stamp_s_) {
    last_sample_stamp_s_ = sample.stamp_s;
    last_sample_outputs_ = sample.outputs;
  }
  if (observe_sample_) observe_sample_(sample);
  process_sample(sample);
}

void DwellAssembler::process_command(const GimbalEvent& command, CompletedRows* out) {
  if (!std::isfinite(table_.time_origin_s)) table_.time_origin_s = command.stamp_s;
  if (done_) {
    ++counters_.commands_out_of_order;
    counters_.last_warning =
        "gimbal command " + describe(command) + " after DONE ignored (call reset first)";
    return;
  }
  switch (command.state) {
    case GimbalState::Moving:
      if (in_dwell_) close_dwell(command.stamp_s, out);
      have_moving_ = true;
      last_moving_ = command;
      break;
    case GimbalState::Settled:
      if (in_dwell_) {
        ++counters_.commands_out_of_order;
        counters_.last_warning =
            "gimbal command " + describe(command) + " while already settled: previous dwell closed";
        close_dwell(command.stamp_s, out);
      } else if (!have_moving_ || last_moving_.phase != command.phase ||
                 last_moving_.step != command.step) {
        ++counters_.commands_out_of_order;
        counters_.last_warning =
            "gimbal command " + describe(command) + " without a MOVING to the same position";
      }
      in_dwell_ = true;
      dwell_command_ = command;
      accumulator_.reset();
      channel_accumulators_ = {};
      have_moving_ = false;
      break;
    case GimbalState::Done:
      if (in_dwell_) close_dwell(command.stamp_s, out);
      done_ = true;
      break;
    default:
      ++counters_.commands_out_of_order;
      counters_.last_warning = "gimbal command with unknown state ignored";
      break;
  }
}

void DwellAssembler::process_sample(const ImuSample& sample) {
  if (!in_dwell_) {
    ++counters_.dropped_outside_dwell;
    return;
  }
  if (sample.stamp_s < dwell_command_.stamp_s + options_.settle_discard_s) {
    ++counters_.dropped_settle_discard;
    return;
  }
  accumulator_.add(sample.outputs);
  ++counters_.samples_used;
}

void DwellAssembler::process_channel(const ChannelSample& reading) {
  const std::size_t c = channel_index(reading.channel);
  if (!in_dwell_ || reading.stamp_s < dwell_command_.stamp_s + options_.settle_discard_s) {
    ++counters_.channel_dropped[c];
    return;
  }
  ChannelAccumulator& a = channel_accumulators_[c];
  a.sum += reading.value;
  ++a.count;
  ++counters_.channel_used[c];
}

double DwellAssembler::ChannelAccumulator::value(Aggregate aggregate) const {
  if (count == 0) return std::numeric_limits<double>::quiet_NaN();
  switch (aggregate) {
    case Aggregate::Mean: return sum / static_cast<double>(count);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

void DwellAssembler::close_dwell(double end_stamp_s, CompletedRows* out) {
  in_dwell_ = false;
  if (accumulator_.count() == 0) {
    std::ostringstream s;
    s << "dwell (phase " << phase_name(dwell_command_.phase) << ", step " << dwell_command_.step
      << ") ended with no samples; not recorded";
    counters_.last_warning = s.str();
    return;
  }
  DwellRecord row;
  row.phase = dwell_command_.phase;
  row.step = dwell_command_.step;
  row.angle_rad = dwell_command_.angle_rad;
  row.t_start_s = dwell_command_.stamp_s + options_.settle_discard_s;
  row.t_end_s = end_stamp_s;
  row.n = accumulator_.count();
  row.mean = accumulator_.mean();
  row.std = accumulator_.sample_std();
  for (const ChannelSpec& spec : kChannels)
    row.*spec.value = channel_accumulators_[channel_index(spec.id)].value(spec.aggregate);
  table_.rows.push_back(row);
  accumulator_.reset();
  out->push_back(row);
}

std::size_t DwellAssembler::memory_bytes() const {
  return sizeof(*this) + in_order_samples_.size() * sizeof(ImuSample) + runs_.size() * sizeof(Run) +
         (in_order_events_.size() + pending_.size()) * sizeof(Event) +
         table_.rows.capacity() * sizeof(DwellRecord);
}

bool DwellAssembler::current_dwell(Phase* phase, std::uint32_t* step,
                                   std::uint64_t* samples) const {
  if (!in_dwell_) return false;
  if (phase) *phase = dwell_command_.phase;
  if (step) *step = dwell_command_.step;
  if (samples) *samples = accumulator_.count();
  return true;
}

}  // namespace core
}  // namespace accel_intrinsics
