// Raw sample files (docs/design.md section 11, offline_fit --samples): one sample a line, four
// columns t,x,y,z (seconds, then the three raw outputs in any unit), separated by commas or
// whitespace. A first line that is not four numbers is a header; lines starting with '#' and blank
// lines are skipped. Other tools' four-column text files (imu_tk's, for one) read as they are.
#pragma once

#include <iosfwd>
#include <stdexcept>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/dwell_assembler.h"

namespace accel_intrinsics {
namespace core {

class SamplesFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Throws SamplesFileError naming the source, the line and the field: a line without four fields,
// a field that is not a finite number, a stamp that goes back, no samples at all.
std::vector<ImuSample> read_samples(std::istream& in, const std::string& source_name = "samples");
std::vector<ImuSample> read_samples_file(const std::string& path);

// Writes "t,x,y,z" then one line a sample, full precision (the one writer of this format).
void write_samples(std::ostream& out, const std::vector<ImuSample>& samples);

}  // namespace core
}  // namespace accel_intrinsics
