#include "accel_intrinsics/core/dwells/dwell_source.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace accel_intrinsics {
namespace core {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The first stamp after `t_s`: a command there ends a dwell after the sample at t_s.
double just_after(double t_s) {
  return std::nextafter(t_s, kInf);
}

void append(CompletedRows* to, const CompletedRows& from) {
  to->insert(to->end(), from.begin(), from.end());
}

// One row of the parts of a rest (the sides of a disturbance cut out): counts, means and sums of
// squares combined (Chan's update), each channel's value (core::kChannels, all Aggregate::Mean)
// as the samples' weighted mean over the parts that have one.
DwellRecord join_parts(const CompletedRows& parts) {
  DwellRecord row = parts.front();
  Eigen::Vector3d m2 = row.std.array().square().matrix() * static_cast<double>(row.n - 1);
  PerChannel<double> channel_sum{};
  PerChannel<std::uint64_t> channel_n{};
  auto add_channels = [&](const DwellRecord& part) {
    for (const ChannelSpec& spec : kChannels) {
      if (!has_value(part, spec)) continue;
      channel_sum[channel_index(spec.id)] += part.*spec.value * static_cast<double>(part.n);
      channel_n[channel_index(spec.id)] += part.n;
    }
  };
  add_channels(row);
  for (std::size_t i = 1; i < parts.size(); ++i) {
    const DwellRecord& b = parts[i];
    const double na = static_cast<double>(row.n), nb = static_cast<double>(b.n);
    const Eigen::Vector3d delta = b.mean - row.mean;
    m2 += b.std.array().square().matrix() * (nb - 1.0) +
          delta.array().square().matrix() * (na * nb / (na + nb));
    row.mean += delta * (nb / (na + nb));
    row.n += b.n;
    add_channels(b);
  }
  if (row.n > 1) row.std = (m2 / static_cast<double>(row.n - 1)).array().sqrt().matrix();
  for (const ChannelSpec& spec : kChannels) {
    const std::size_t c = channel_index(spec.id);
    row.*spec.value = channel_n[c] > 0 ? channel_sum[c] / static_cast<double>(channel_n[c])
                                       : std::numeric_limits<double>::quiet_NaN();
  }
  return row;
}

}  // namespace

// ---- Commanded ----------------------------------------------------------------------------------

CompletedRows CommandedDwellSource::add_command(const GimbalEvent& event) {
  return assembler_->add_command(event);
}
CompletedRows CommandedDwellSource::add_sample(const ImuSample& sample) {
  return assembler_->add_sample(sample);
}
CompletedRows CommandedDwellSource::add_channel_sample(const ChannelSample& reading) {
  return assembler_->add_channel_sample(reading);
}
CompletedRows CommandedDwellSource::finish() {
  return assembler_->flush();
}

// ---- Detected -----------------------------------------------------------------------------------

DetectedDwellSource::DetectedDwellSource(DwellAssembler* assembler,
                                         const RestDetectionOptions& options, double rate_hz)
    : DwellSource(assembler), detector_(options, rate_hz) {}

CompletedRows DetectedDwellSource::add_command(const GimbalEvent&) {
  ++commands_ignored_;
  return {};
}

CompletedRows DetectedDwellSource::add_sample(const ImuSample& sample) {
  if (!std::isfinite(sample.stamp_s) || !sample.outputs.allFinite()) {
    return assembler_->add_sample(sample);  // counted there (dropped_non_finite)
  }
  detector_.add(sample.stamp_s, sample.outputs);
  held_.push_back(sample);
  return release_rests();
}

CompletedRows DetectedDwellSource::add_channel_sample(const ChannelSample& reading) {
  held_readings_.push_back(reading);
  return {};
}

CompletedRows DetectedDwellSource::finish() {
  detector_.finish();
  CompletedRows rows = release_rests();
  release_until(kInf, &rows);
  append(&rows, assembler_->flush());
  return rows;
}

void DetectedDwellSource::release_until(double stamp_s, CompletedRows* rows) {
  // Samples and channel readings in stamp order (a reading before a sample at equal stamps).
  while (true) {
    const bool sample = !held_.empty() && held_.front().stamp_s < stamp_s;
    const bool reading = !held_readings_.empty() && held_readings_.front().stamp_s < stamp_s;
    if (!sample && !reading) return;
    if (reading && (!sample || held_readings_.front().stamp_s <= held_.front().stamp_s)) {
      append(rows, assembler_->add_channel_sample(held_readings_.front()));
      held_readings_.pop_front();
    } else {
      append(rows, assembler_->add_sample(held_.front()));
      held_.pop_front();
    }
  }
}

void DetectedDwellSource::command(GimbalState state, double stamp_s, std::uint32_t step,
                                  CompletedRows* rows) {
  GimbalEvent e;
  e.stamp_s = stamp_s;
  e.step = step;
  e.state = state;
  append(rows, assembler_->add_command(e));
}

CompletedRows DetectedDwellSource::release_rests() {
  CompletedRows out;
  for (const DwellRecord& rest : detector_.take_rests()) {
    // The disturbances cut out of this rest: the rejected spans inside it.
    std::vector<RejectedSpan> cuts;
    for (const RejectedSpan& r : detector_.rejected()) {
      if (r.t_start_s >= rest.t_start_s && r.t_end_s <= rest.t_end_s) cuts.push_back(r);
    }
    std::sort(cuts.begin(), cuts.end(), [](const RejectedSpan& a, const RejectedSpan& b) {
      return a.t_start_s < b.t_start_s;
    });
    CompletedRows parts;
    release_until(rest.t_start_s, &parts);  // before the rest: outside every dwell
    command(GimbalState::Moving, rest.t_start_s, rest.step, &parts);
    command(GimbalState::Settled, rest.t_start_s, rest.step, &parts);
    for (const RejectedSpan& cut : cuts) {  // cut.t_start_s, t_end_s: the last and first kept
      release_until(just_after(cut.t_start_s), &parts);
      command(GimbalState::Moving, just_after(cut.t_start_s), rest.step, &parts);
      release_until(cut.t_end_s, &parts);
      command(GimbalState::Settled, cut.t_end_s, rest.step, &parts);
    }
    const double end = just_after(rest.t_end_s);
    release_until(end, &parts);
    command(GimbalState::Moving, end, rest.step, &parts);
    append(&parts, assembler_->flush_until(end));
    if (parts.empty()) continue;  // cannot happen: a rest has samples
    DwellRecord row = join_parts(parts);
    row.orientation_unknown = true;
    row.phase = rest.phase;
    row.angle_rad = rest.angle_rad;
    row.t_start_s = rest.t_start_s;
    row.t_end_s = rest.t_end_s;
    out.push_back(row);
  }
  return out;
}

}  // namespace core
}  // namespace accel_intrinsics
