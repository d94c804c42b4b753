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

bool DwellAssembler::Later::operator()(const Event& a, const Event& b) const {
  // Min-heap on stamp; at equal stamps a command before a sample, then arrival order.
  if (a.stamp_s != b.stamp_s) return a.stamp_s > b.stamp_s;
  if (a.is_command() != b.is_command()) return !a.is_command();
  return a.sequence > b.sequence;
}

DwellAssembler::DwellAssembler(const AssemblerOptions& options) : options_(options) {
  reset();
}

void DwellAssembler::reset() {
  pending_ = decltype(pending_)();
  in_order_.clear();
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
  push(Event{sample.stamp_s, next_sequence_++, sample}, &out);
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
  if (in_order_.empty() || !Later()(in_order_.back(), event)) {
    in_order_.push_back(std::move(event));
  } else {
    pending_.push(std::move(event));
  }
  release_until(newest_stamp_s_ - options_.reorder_window_s, out);
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
    // The earlier of the two fronts (Later: a strict total order, sequences are unique).
    const bool from_heap =
        in_order_.empty() || (!pending_.empty() && Later()(in_order_.front(), pending_.top()));
    if ((from_heap ? pending_.top() : in_order_.front()).stamp_s > stamp_s) break;
    const Event event = from_heap ? pending_.top() : std::move(in_order_.front());
    if (from_heap) {
      pending_.pop();
    } else {
      in_order_.pop_front();
    }
    if (event.stamp_s > released_until_s_) released_until_s_ = event.stamp_s;
    process(event, out);
  }
  if (stamp_s > released_until_s_ && pending_empty() && std::isfinite(stamp_s))
    released_until_s_ = stamp_s;
}

void DwellAssembler::process(const Event& event, CompletedRows* out) {
  if (const auto* command = std::get_if<GimbalEvent>(&event.payload)) {
    if (observe_command_) observe_command_(*command);
    process_command(*command, out);
  } else if (const auto* reading = std::get_if<ChannelSample>(&event.payload)) {
    process_channel(*reading);
  } else {
    const ImuSample& sample = std::get<ImuSample>(event.payload);
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
  return sizeof(*this) + buffered_events() * sizeof(Event) +
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
