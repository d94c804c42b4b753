// calibration/dwell (accel_intrinsics/Dwell): each row the calibration node accepts into its
// position table, a completed dwell of the gimbal protocol or a rest of a hand tumble
// (docs/design.md section 17). The dashboard (scripts/dashboard) plots them as they land.
#pragma once

#include <ros/ros.h>

#include <cstddef>
#include <string>

#include "accel_intrinsics/Dwell.h"
#include "accel_intrinsics/core/dwells/dwell_record.h"

namespace accel_intrinsics {

constexpr char kDwellTopic[] = "calibration/dwell";

// The message of table row `index` (0-based); phase PHASE_UNKNOWN for a rest of unknown
// orientation or a row of a known direction (phase "-" in the table).
Dwell to_dwell_msg(const core::DwellRecord& row, std::size_t index, const std::string& frame_id);

// Advertises calibration/dwell on `nh` (not latched; queue for a burst of rows).
ros::Publisher advertise_dwells(ros::NodeHandle& nh);

}  // namespace accel_intrinsics
