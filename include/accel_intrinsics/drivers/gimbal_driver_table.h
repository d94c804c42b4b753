// The gimbal drivers as one table (docs/design.md section 15, "Any gimbal without C++"): each row
// is a driver's name, its options reader (its own ~<name>/... parameters, through DriverParams),
// its factory and its emulator if it has one. gimbal_controller ~driver picks a row; adding a
// driver is adding a row here (and its options type).
#pragma once

#include <any>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "accel_intrinsics/drivers/driver_params.h"
#include "accel_intrinsics/drivers/gimbal_driver.h"
#include "accel_intrinsics/drivers/serial_gimbal.h"

namespace accel_intrinsics {

// The protocol's times, the defaults of a driver's own (move, settling).
struct GimbalDriverDefaults {
  double move_s = 1.0;
  double settle_s = 0.5;
  double phase_change_s = 5.0;
};

struct GimbalDriverRow {
  std::string name;      // the value of ~driver
  std::string summary;   // one line: what it drives
  std::string emulator;  // executable that answers as the device does ("" when none)
  // Reads and validates the driver's parameters (keys under "<name>/"); throws
  // std::invalid_argument whose text names the parameter.
  std::function<std::any(const DriverParams& params, const GimbalDriverDefaults& defaults)>
      read_options;
  // Builds the driver from what read_options returned; throws GimbalFault when the device does
  // not come up (port missing, no reply, alarm at start).
  std::function<std::unique_ptr<GimbalDriver>(const std::any& options)> make;
};

// Every row, the default ("simulated") first.
const std::vector<GimbalDriverRow>& gimbal_driver_table();
// The row named `name`, nullptr when none.
const GimbalDriverRow* find_gimbal_driver(const std::string& name);
// "simulated, grbl, smc100, ros_joint, manual": for the unknown driver's message.
std::string gimbal_driver_names();

// The per-phase axis map under `prefix` ("grbl/phases/x" ...): axis, sign, zero_deg, hold,
// manual_remount. Throws std::invalid_argument naming the parameter.
AxisMap read_axis_map(const DriverParams& params, const std::string& driver);

}  // namespace accel_intrinsics
