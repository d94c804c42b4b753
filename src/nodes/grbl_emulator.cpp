// grbl_emulator: a GRBL 1.1 controller on a pseudo-terminal (emulators/emulators.h).
#include "accel_intrinsics/emulators/emulator_main.h"

int main(int argc, char** argv) {
  return accel_intrinsics::emulator_main("grbl", argc, argv);
}
