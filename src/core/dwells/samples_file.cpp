#include "accel_intrinsics/core/dwells/samples_file.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <istream>
#include <limits>
#include <ostream>
#include <sstream>

namespace accel_intrinsics {
namespace core {
namespace {

const char* const kColumns[4] = {"t", "x", "y", "z"};

// Splits on commas, semicolons and whitespace (empty fields between two commas are kept, so
// "1,,2" reports a missing field rather than shifting columns).
std::vector<std::string> split_fields(const std::string& line) {
  std::vector<std::string> fields;
  std::string current;
  bool in_field = false;
  bool comma_separated = line.find(',') != std::string::npos;
  for (char c : line) {
    const bool space = c == ' ' || c == '\t' || c == '\r';
    if (c == ',' || (!comma_separated && c == ';')) {
      fields.push_back(current);
      current.clear();
      in_field = false;
    } else if (space) {
      if (!comma_separated && in_field) {
        fields.push_back(current);
        current.clear();
        in_field = false;
      }
    } else {
      current.push_back(c);
      in_field = true;
    }
  }
  if (in_field || comma_separated) fields.push_back(current);
  return fields;
}

bool parse_number(const std::string& text, double* value) {
  if (text.empty()) return false;
  errno = 0;
  char* end = nullptr;
  *value = std::strtod(text.c_str(), &end);
  return end == text.c_str() + text.size() && errno != ERANGE;
}

}  // namespace

std::vector<ImuSample> read_samples(std::istream& in, const std::string& source_name) {
  std::vector<ImuSample> samples;
  std::string line;
  std::size_t line_number = 0;
  bool first_content = true;
  auto fail = [&](const std::string& what) {
    throw SamplesFileError(source_name + ":" + std::to_string(line_number) + ": " + what);
  };
  while (std::getline(in, line)) {
    ++line_number;
    const std::size_t start = line.find_first_not_of(" \t\r");
    if (start == std::string::npos || line[start] == '#') continue;
    const std::vector<std::string> fields = split_fields(line);
    double values[4];
    bool numeric = fields.size() == 4;
    for (std::size_t k = 0; numeric && k < 4; ++k) numeric = parse_number(fields[k], &values[k]);
    if (first_content) {
      first_content = false;
      if (!numeric) continue;  // a header line
    }
    if (fields.size() != 4)
      fail("expected 4 fields (t,x,y,z), found " + std::to_string(fields.size()));
    for (std::size_t k = 0; k < 4; ++k) {
      if (!parse_number(fields[k], &values[k]) || !std::isfinite(values[k]))
        fail(std::string("field ") + kColumns[k] + " is not a finite number: '" + fields[k] + "'");
    }
    if (!samples.empty() && values[0] < samples.back().stamp_s) {
      std::ostringstream m;
      m.precision(12);
      m << "t goes back (" << values[0] << " s after " << samples.back().stamp_s
        << " s): the samples must be in time order";
      fail(m.str());
    }
    samples.push_back(ImuSample{values[0], Eigen::Vector3d(values[1], values[2], values[3])});
  }
  if (samples.empty())
    throw SamplesFileError(source_name + ": no samples (expected t,x,y,z lines)");
  return samples;
}

std::vector<ImuSample> read_samples_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw SamplesFileError("cannot open samples file '" + path + "'");
  return read_samples(in, path);
}

void write_samples(std::ostream& out, const std::vector<ImuSample>& samples) {
  const auto precision = out.precision(std::numeric_limits<double>::max_digits10);
  out << "t,x,y,z\n";
  for (const ImuSample& s : samples)
    out << s.stamp_s << ',' << s.outputs(0) << ',' << s.outputs(1) << ',' << s.outputs(2) << '\n';
  out.precision(precision);
}

}  // namespace core
}  // namespace accel_intrinsics
