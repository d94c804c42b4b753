// Numbers in messages and reports: one formatting helper for every layer (the core's messages,
// the drivers', the io writers').
#pragma once

#include <string>

namespace accel_intrinsics {
namespace core {

// `value` rounded to `decimals` decimal places (negative: to tens, hundreds...), printed with
// max(decimals, 0) decimals and never as "-0.0". fixed(2.345, 1) = "2.3", fixed(1234, -2) = "1200".
std::string fixed(double value, int decimals);

}  // namespace core
}  // namespace accel_intrinsics
