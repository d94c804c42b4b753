// calibration/dwell: a position table row as a message (docs/design.md section 17).
#include "accel_intrinsics/ros/dwell_message.h"

namespace accel_intrinsics {

Dwell to_dwell_msg(const core::DwellRecord& row, std::size_t index, const std::string& frame_id) {
  Dwell msg;
  msg.header.stamp.fromSec(row.t_end_s > 0.0 ? row.t_end_s : 0.0);
  msg.header.frame_id = frame_id;
  msg.phase = row.orientation_unknown || row.has_direction ? Dwell::PHASE_UNKNOWN
                                                           : static_cast<std::uint8_t>(row.phase);
  msg.step = row.step;
  msg.angle = row.angle_rad;
  msg.index = static_cast<std::uint32_t>(index);
  msg.t_start = row.t_start_s;
  msg.t_end = row.t_end_s;
  msg.n = row.n;
  for (int i = 0; i < 3; ++i) {
    msg.mean[i] = row.mean[i];
    msg.std[i] = row.std[i];
  }
  msg.temperature = row.temperature_c;
  return msg;
}

ros::Publisher advertise_dwells(ros::NodeHandle& nh) {
  return nh.advertise<Dwell>(kDwellTopic, 100, false);
}

}  // namespace accel_intrinsics
