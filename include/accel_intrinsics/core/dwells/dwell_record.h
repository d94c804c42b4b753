// One dwell's record (a row of the position table) and its per-dwell channels: inputs besides the
// accelerometer's outputs that each dwell records (the DUT temperature, ...), declared once here.
// The position table's reader and writer, the checkpoint, the dwell assembler, the bag topics and
// the calibration node's subscriptions all iterate over kChannels; a new channel is an enum
// entry, a DwellRecord field and a row of kChannels here, its message in ros/channel_messages.cpp
// and its use in the model (docs/architecture.md, "Extending").
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <limits>
#include <string>

#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {

// One row of the position table: the statistics of one dwell.
struct DwellRecord {
  Phase phase = Phase::X;
  std::uint32_t step = 0;
  double angle_rad = 0.0;
  double t_start_s = 0.0;
  double t_end_s = 0.0;
  std::uint64_t n = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();  // R_u, R_v, R_w, m/s^2
  Eigen::Vector3d std = Eigen::Vector3d::Zero();   // sample standard deviation, m/s^2
  // A known orientation instead of (phase, angle) (docs/design.md section 6: position table columns
  // f_x,f_y,f_z, phase "-"): the unit specific force in the DUT frame. phase, step and angle are
  // then labels without meaning; only the joint fit takes such rows.
  bool has_direction = false;
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();
  // A rest of unknown orientation (docs/design.md section 11: a hand tumble, or a gimbal run fitted
  // with --unknown-orientations): phase "-" without f_x,f_y,f_z. Only the tumble fit takes such
  // rows; phase, step and angle are labels without meaning.
  bool orientation_unknown = false;
  // Mean temperature of the dwell in degrees C (imu/temperature, column temperature_c); NaN when
  // none was recorded.
  double temperature_c = std::numeric_limits<double>::quiet_NaN();
  bool has_temperature() const { return std::isfinite(temperature_c); }
};

enum class Channel : std::uint8_t { Temperature };

// How a dwell turns its readings into the row's value.
enum class Aggregate : std::uint8_t {
  Mean,  // the mean of the readings inside the dwell (after the settle discard)
};

struct ChannelSpec {
  Channel id;
  const char* name;          // for messages and counters: "temperature"
  const char* column;        // position table column: "temperature_c"
  const char* topic;         // default topic, relative: "imu/temperature"
  const char* message_type;  // ROS type of the topic: "sensor_msgs/Temperature"
  const char* unit;          // of the value: "degC"
  Aggregate aggregate;
  // A row may lack a value (an empty field): no reading fell into that dwell. Not optional: when
  // the column is there, every row must have a value.
  bool optional_per_row;
  double DwellRecord::*value;  // the row's field; NaN = no value
};

// One row per channel, in the order of enum Channel.
inline constexpr ChannelSpec kChannels[] = {
    {Channel::Temperature, "temperature", "temperature_c", "imu/temperature",
     "sensor_msgs/Temperature", "degC", Aggregate::Mean, true, &DwellRecord::temperature_c},
};
inline constexpr std::size_t kChannelCount = std::size(kChannels);

inline constexpr std::size_t channel_index(Channel c) {
  return static_cast<std::size_t>(c);
}
inline const ChannelSpec& channel_spec(Channel c) {
  return kChannels[channel_index(c)];
}
// kChannels is indexed by the enum: each row stands at its id's place.
constexpr bool channels_in_enum_order() {
  for (std::size_t i = 0; i < kChannelCount; ++i)
    if (channel_index(kChannels[i].id) != i) return false;
  return true;
}
static_assert(channels_in_enum_order(), "kChannels rows must follow the order of enum Channel");

// The channel whose column is `column`; nullptr for none.
inline const ChannelSpec* channel_by_column(const std::string& column) {
  for (const ChannelSpec& spec : kChannels)
    if (column == spec.column) return &spec;
  return nullptr;
}

inline bool has_value(const DwellRecord& row, const ChannelSpec& spec) {
  return std::isfinite(row.*spec.value);
}

// One reading of a channel at a stamp (a sensor_msgs/Temperature message, ROS-free).
struct ChannelSample {
  Channel channel = Channel::Temperature;
  double stamp_s = 0.0;
  double value = 0.0;
};

// One value per channel (topics, counts), indexed by channel_index().
template <class T>
using PerChannel = std::array<T, kChannelCount>;

}  // namespace core
}  // namespace accel_intrinsics
