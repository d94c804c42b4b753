// The preconditions, in one place: the fits' checks of the options, the rows, the geometry and
// the effects asked for (docs/design.md section 6), and what a run offers toward the effect
// catalog's preconditions (preconditions.h), which the discrepancy analysis screens by.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <set>
#include <sstream>
#include <utility>

#include "accel_intrinsics/core/fit/preconditions.h"
#include "accel_intrinsics/core/model/model.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "fit_internal.h"

namespace accel_intrinsics {
namespace core {

void validate_options(const FitOptions& options) {
  if (!std::isfinite(options.local_gravity) || options.local_gravity <= 0.0)
    throw FitError("local_gravity must be a positive finite number of m/s^2, got " +
                   format_number(options.local_gravity));
  if (options.min_positions_per_phase < 3)
    throw FitError("min_positions_per_phase is " + std::to_string(options.min_positions_per_phase) +
                   "; every model needs at least 3 dwells per phase");
}

void validate_rows(const PreparedTable& table) {
  static const char* const kMean[3] = {"mean_u", "mean_v", "mean_w"};
  static const char* const kStd[3] = {"std_u", "std_v", "std_w"};
  for (std::size_t i = 0; i < table.size(); ++i) {
    const DwellRecord& r = table.row(i);
    auto fail = [&](const std::string& field, const std::string& what) {
      throw FitError(row_name(table.table(), i) + ": " + field + " " + what);
    };
    if (!std::isfinite(r.angle_rad)) fail("angle_rad", "is " + format_number(r.angle_rad));
    if (!std::isfinite(r.t_start_s)) fail("t_start", "is " + format_number(r.t_start_s));
    if (!std::isfinite(r.t_end_s)) fail("t_end", "is " + format_number(r.t_end_s));
    if (r.n == 0) fail("n", "is 0 (a dwell without samples)");
    for (int s = 0; s < 3; ++s) {
      if (!std::isfinite(r.mean(s))) fail(kMean[s], "is " + format_number(r.mean(s)));
      if (!std::isfinite(r.std(s))) fail(kStd[s], "is " + format_number(r.std(s)));
      if (r.std(s) < 0.0) fail(kStd[s], "is negative (" + format_number(r.std(s)) + ")");
    }
  }
}

// Every phase needs min_positions dwells at >= 3 distinct angles: R = a g sin + b g cos + c has
// three unknowns per phase, and (sin a, cos a, 1) of points on one circle has rank 3 exactly
// when at least three of them are distinct.
void validate_geometry(const PreparedTable& table, int min_positions) {
  const std::array<int, 3>& counts = table.positions_per_phase();
  for (Phase p : kPhases) {
    const int count = counts[index(p)];
    if (count < min_positions)
      throw FitError("phase " + std::string(phase_name(p)) + " has " + std::to_string(count) +
                     " dwells, needs at least " + std::to_string(min_positions));
  }
  for (Phase p : kPhases) {
    Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
    std::vector<double> angles;
    for (std::size_t i : table.phase_rows(p)) {
      const DwellRecord& r = table.row(i);
      const Eigen::Vector3d h(std::sin(r.angle_rad), std::cos(r.angle_rad), 1.0);
      M += h * h.transpose();
      double a = std::fmod(r.angle_rad, 2.0 * kPi);
      if (a < 0.0) a += 2.0 * kPi;
      angles.push_back(a);
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(M);
    const Eigen::Vector3d ev = eig.eigenvalues();
    if (ev(0) > 1e-10 * ev(2)) continue;
    std::sort(angles.begin(), angles.end());
    int distinct = angles.empty() ? 0 : 1;
    for (std::size_t k = 1; k < angles.size(); ++k)
      if (angles[k] - angles[k - 1] > 1e-9) ++distinct;
    if (distinct > 1 && angles.back() - angles.front() > 2.0 * kPi - 1e-9) --distinct;
    throw FitError("phase " + std::string(phase_name(p)) + " has a degenerate geometry: its " +
                   std::to_string(angles.size()) + " dwells lie at " + std::to_string(distinct) +
                   " distinct angle(s) (or span too small an arc); at least 3 distinct angles "
                   "are needed to determine the vector components");
  }
}

// The joint fit takes any set of orientations that determines S and O (docs/design.md section 6):
// the gimbal phases present keep the per-phase checks (they are what the rows claim to be),
// and the whole set must give (f_x, f_y, f_z, 1) full rank, well conditioned. A complete gimbal
// run (three phases, no direction rows) is checked as before.
void validate_joint_geometry(const PreparedTable& table, int min_positions) {
  const std::array<int, 3>& counts = table.positions_per_phase();
  const bool three_phases = counts[0] > 0 && counts[1] > 0 && counts[2] > 0;
  if (three_phases && table.rows_with_direction() == 0) {
    validate_geometry(table, min_positions);
    return;
  }
  if (table.size() == 0) throw FitError("the position table has no dwells");
  for (Phase p : kPhases) {
    const int count = counts[index(p)];
    if (count > 0 && count < min_positions)
      throw FitError("phase " + std::string(phase_name(p)) + " has " + std::to_string(count) +
                     " dwells, needs at least " + std::to_string(min_positions));
  }
  Eigen::Matrix4d M = Eigen::Matrix4d::Zero();
  for (std::size_t i = 0; i < table.size(); ++i) {
    const Eigen::Vector3d& f = table.direction(i);
    const Eigen::Vector4d h(f(0), f(1), f(2), 1.0);
    M += h * h.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(M / static_cast<double>(table.size()));
  const Eigen::Vector4d ev = eig.eigenvalues();
  // Conditioning: 1e-6 leaves the weakest combination determined to about 1000x the noise of the
  // others; below it the fit is dominated by round-off and by how well the orientations are known.
  if (ev(0) > 1e-6 * ev(3)) return;
  Eigen::Vector4d c = eig.eigenvectors().col(0);
  c /= c.cwiseAbs().maxCoeff();
  std::ostringstream m;
  m.precision(3);
  m << "the orientations do not determine S and O (" << table.size()
    << " dwells): every one satisfies " << c(0) << " f_x + " << c(1) << " f_y + " << c(2)
    << " f_z + " << c(3)
    << " = 0 (f: unit specific force), so the same combination of the vector components and "
       "offsets is unobservable; add orientations off that plane";
  throw FitError(m.str());
}

void validate_effects(const std::vector<Effect>& effects, FitModel model,
                      const std::vector<DwellGeometry>& geoms) {
  if (effects.empty()) return;
  std::string names;
  for (const Effect& e : effects) names += (names.empty() ? "" : ", ") + e.name();
  if (model != FitModel::Joint)
    throw FitError(std::string("effects need the joint model: ") + model_name(model) +
                   " cannot fit " + names);
  std::set<std::pair<int, int>> seen;
  for (const Effect& e : effects) {
    const EffectInfo& info = effect_info(e.kind);
    if (e.kind == EffectKind::TimingLag)
      throw FitError(
          "timing_lag cannot be fitted from dwell means: it shifts the IMU stamps against the "
          "gimbal, and within a settled dwell the outputs do not depend on that shift; only the "
          "raw sample streams (samples taken while moving) reveal it");
    if (info.target_kind == TargetKind::All)
      throw FitError(std::string(info.name) +
                     " targets all accelerometers and phases at once, which the dwell means "
                     "cannot separate from S and O");
    if (e.target < 0 || e.target > 2)
      throw FitError(std::string(info.name) + " has target index " + std::to_string(e.target) +
                     "; expected 0..2 (" +
                     (info.target_kind == TargetKind::Accelerometer ? "u, v, w" : "x, y, z") + ")");
    if (!std::isfinite(e.value))
      throw FitError("starting value of " + e.label() + " is " + format_number(e.value));
    if (!seen.insert({static_cast<int>(e.kind), e.target}).second)
      throw FitError(e.label() + " is listed twice; each effect term can be fitted once");
    if (e.kind == EffectKind::Backlash) {
      bool up = false, down = false;
      for (const DwellGeometry& g : geoms) {
        if (index(g.phase) != e.target) continue;
        up = up || g.approach > 0;
        down = down || g.approach < 0;
      }
      if (!(up && down))
        throw FitError(e.label() + " needs a two-way sweep: every dwell of phase " +
                       e.target_name() +
                       " was approached from the same direction, so backlash cannot be told "
                       "from angle_offset[" +
                       e.target_name() + "]");
    }
    if (info.precondition == Precondition::TemperatureVaries) {
      std::size_t missing = 0;
      double lo = 0.0, hi = 0.0;
      bool first = true;
      for (const DwellGeometry& g : geoms) {
        if (!g.has_temperature) {
          ++missing;
          continue;
        }
        lo = first ? g.temperature_offset_k : std::min(lo, g.temperature_offset_k);
        hi = first ? g.temperature_offset_k : std::max(hi, g.temperature_offset_k);
        first = false;
      }
      if (missing > 0)
        throw FitError(e.label() + " needs the temperature of every dwell: " +
                       std::to_string(missing) + " of " + std::to_string(geoms.size()) +
                       " rows have none (record imu/temperature, or fill the position table's "
                       "temperature_c column)");
      if (!(hi > lo))
        throw FitError(e.label() +
                       " needs dwell temperatures that differ: every row has the same "
                       "temperature, so the coefficient cannot be told from the offset");
    }
    if (e.kind == EffectKind::OffsetDrift) {
      double lo = 0.0, hi = 0.0;
      for (std::size_t i = 0; i < geoms.size(); ++i) {
        lo = i == 0 ? geoms[i].time_s : std::min(lo, geoms[i].time_s);
        hi = i == 0 ? geoms[i].time_s : std::max(hi, geoms[i].time_s);
      }
      if (!(hi > lo))
        throw FitError(e.label() +
                       " needs dwell times: every row has the same mid-dwell time, so a drift "
                       "cannot be told from the offset");
    }
  }
}

// ---- what a run offers toward the effect catalog's preconditions ----------------------

namespace {

// Which phases have rows approached from both sides (a two-way sweep).
std::array<bool, 3> two_way_phases(const std::vector<DwellGeometry>& geoms) {
  std::array<bool, 3> up{{false, false, false}}, down{{false, false, false}};
  for (const DwellGeometry& g : geoms) {
    (g.approach > 0 ? up : down)[index(g.phase)] = true;
  }
  return {{up[0] && down[0], up[1] && down[1], up[2] && down[2]}};
}

}  // namespace

RunConditions run_conditions(const PositionTable& table, const std::vector<DwellGeometry>& geoms,
                             double min_temperature_span_k) {
  RunConditions c;
  c.two_way = two_way_phases(geoms);
  c.temperature = temperature_coverage(table, min_temperature_span_k);
  return c;
}

// Whether the dwell means of a run can show `effect` (its catalog precondition): raw-stream
// effects never, two-way effects only on a two-way phase, temperature effects only with varying
// dwell temperatures.
bool screenable(const Effect& effect, const RunConditions& run) {
  switch (effect_info(effect.kind).precondition) {
    case Precondition::None: return true;
    case Precondition::TwoWaySweep: return run.two_way[effect.target];
    case Precondition::RawStreams: return false;
    case Precondition::TemperatureVaries: return run.temperature.screenable;
  }
  return false;
}

// Why `effect` was not screened in this run: the catalog's note, with the run's reason.
std::string not_screened_note(const Effect& effect, const RunConditions& run) {
  std::string note = unmet_precondition_note(effect);
  if (effect_info(effect.kind).precondition == Precondition::TemperatureVaries)
    note += ": " + run.temperature.reason;
  return note;
}

// Whether an unscreened effect may be the look-alike of a named one. A temperature that was
// recorded in every dwell and stayed flat rules a temperature coefficient out as the cause of
// drift; unrecorded temperatures do not.
bool look_alike_possible(const Effect& unscreened, const RunConditions& run) {
  if (effect_info(unscreened.kind).precondition == Precondition::TemperatureVaries)
    return run.temperature.rows_with_temperature < run.temperature.rows;
  return true;
}

TemperatureCoverage temperature_coverage(const PositionTable& table,
                                         double min_temperature_span_k) {
  TemperatureCoverage c;
  c.rows = table.rows.size();
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const DwellRecord& row : table.rows) {
    if (!row.has_temperature()) continue;
    ++c.rows_with_temperature;
    lo = std::min(lo, row.temperature_c);
    hi = std::max(hi, row.temperature_c);
  }
  c.span_k = c.rows_with_temperature > 0 ? hi - lo : 0.0;
  std::ostringstream why;
  if (c.rows_with_temperature == 0) {
    why << "no temperature was recorded";
  } else if (c.rows_with_temperature < c.rows) {
    why << "only " << c.rows_with_temperature << " of " << c.rows
        << " dwells have a temperature (publish imu/temperature at least once per dwell)";
  } else if (!(c.span_k >= min_temperature_span_k)) {
    why << std::setprecision(3) << "the dwell temperatures span " << c.span_k
        << " K, less than the " << min_temperature_span_k
        << " K needed to see a coefficient (warm up or cool the DUT during the run)";
  }
  c.reason = why.str();
  c.screenable = c.reason.empty();
  return c;
}

}  // namespace core
}  // namespace accel_intrinsics
