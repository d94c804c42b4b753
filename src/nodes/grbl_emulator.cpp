// grbl_emulator: a GRBL 1.1 controller on a pseudo-terminal (drivers/emulators.h).
#include "accel_intrinsics/drivers/emulator_main.h"

int main(int argc, char** argv) {
  return accel_intrinsics::emulator_main("grbl", argc, argv);
}
