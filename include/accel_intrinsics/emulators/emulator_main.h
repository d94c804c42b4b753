// The command line of the device emulators (src/nodes/grbl_emulator.cpp, smc100_emulator.cpp):
//   rosrun accel_intrinsics grbl_emulator --link /tmp/ttyGRBL [--log FILE] [--rate-deg-s R]
//       [--needs-homing] [--fault none|no_reply|garbage|error|alarm|vanish] [--fault-after N]
//   rosrun accel_intrinsics smc100_emulator --address 1 --address 2 --link /tmp/ttySMC ...
// Prints the pseudo-terminal's path, serves until SIGINT/SIGTERM (or until it vanished by an
// injected fault). ROS remapping arguments (name:=value) from roslaunch are ignored.
#pragma once

namespace accel_intrinsics {

// kind: "grbl" or "smc100". Returns the process exit status.
int emulator_main(const char* kind, int argc, char** argv);

}  // namespace accel_intrinsics
