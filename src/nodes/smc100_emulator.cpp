// smc100_emulator: Newport SMC100 controllers on a pseudo-terminal (drivers/emulators.h).
#include "accel_intrinsics/drivers/emulator_main.h"

int main(int argc, char** argv) {
  return accel_intrinsics::emulator_main("smc100", argc, argv);
}
