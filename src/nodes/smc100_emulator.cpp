// smc100_emulator: Newport SMC100 controllers on a pseudo-terminal (emulators/emulators.h).
#include "accel_intrinsics/emulators/emulator_main.h"

int main(int argc, char** argv) {
  return accel_intrinsics::emulator_main("smc100", argc, argv);
}
