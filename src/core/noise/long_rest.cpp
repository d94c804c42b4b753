// The long rest: found in a run's table and turned into a noise model (noise.h); accumulated by
// rest_accumulator.cpp, live and offline alike.
#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/noise/rest_accumulator.h"

namespace accel_intrinsics {
namespace core {

std::optional<LongRest> find_long_rest(const PositionTable& table, double initial_rest_s) {
  if (table.rows.empty()) return std::nullopt;
  std::vector<std::size_t> order(table.rows.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return table.rows[a].t_start_s < table.rows[b].t_start_s;
  });
  auto length = [&](std::size_t i) { return table.rows[i].t_end_s - table.rows[i].t_start_s; };
  auto make = [&](std::size_t i, const std::string& reason) {
    LongRest r;
    r.row = i;
    r.t_start_s = table.rows[i].t_start_s;
    r.t_end_s = table.rows[i].t_end_s;
    r.reason = reason;
    return r;
  };
  const bool tumble = table.rows.front().orientation_unknown;
  if (tumble) {
    for (std::size_t i : order)
      if (length(i) >= 30.0) return make(i, "the first rest of at least 30 s");
    return std::nullopt;
  }
  if (initial_rest_s > 0.0) {
    const std::size_t first = order.front();
    const DwellRecord& r = table.rows[first];
    // 95 %: the dwell ends at the next MOVING, the settle time and stamp rounding shave a little.
    if (!r.has_direction && r.phase == Phase::X && r.step == 0 &&
        length(first) >= 0.95 * initial_rest_s)
      return make(first, "the initial rest (phase x, step 0)");
  }
  if (table.rows.size() < 3) return std::nullopt;
  std::vector<double> lengths;
  for (std::size_t i = 0; i < table.rows.size(); ++i) lengths.push_back(length(i));
  std::nth_element(lengths.begin(), lengths.begin() + static_cast<long>(lengths.size() / 2),
                   lengths.end());
  const double median = lengths[lengths.size() / 2];
  if (!(median > 0.0)) return std::nullopt;
  for (std::size_t i : order)
    if (length(i) >= 10.0 * median) return make(i, "a dwell at least 10 times the median dwell");
  return std::nullopt;
}

std::optional<NoiseModel> noise_model_of_run(const PositionTable& table,
                                             const std::vector<double>& stamps_s,
                                             const std::vector<Eigen::Vector3d>& outputs,
                                             double initial_rest_s) {
  const std::optional<LongRest> rest = find_long_rest(table, initial_rest_s);
  if (!rest || stamps_s.size() != outputs.size()) return std::nullopt;
  std::vector<std::size_t> inside;
  for (std::size_t i = 0; i < stamps_s.size(); ++i)
    if (stamps_s[i] >= rest->t_start_s && stamps_s[i] <= rest->t_end_s) inside.push_back(i);
  // In stamp order, as the live run's samples come (a recorded stream may hold some out of it).
  std::stable_sort(inside.begin(), inside.end(),
                   [&](std::size_t a, std::size_t b) { return stamps_s[a] < stamps_s[b]; });
  RestAccumulator accumulated;
  for (std::size_t i : inside) accumulated.add(stamps_s[i], outputs[i]);
  return noise_model_of_rest(accumulated, *rest);
}

}  // namespace core
}  // namespace accel_intrinsics
