// Setup mistakes (docs/design.md section 15): the one judgement behind the mount check and the
// finished run's analysis and quality gate (setup_mistakes.h).
#include "accel_intrinsics/core/analysis/setup_mistakes.h"

#include <Eigen/Dense>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "accel_intrinsics/core/model/protocol.h"

namespace accel_intrinsics {
namespace core {

const char* const kUnknownOrientationsAdvice =
    "second opinion without gimbal angles: offline_fit --unknown-orientations fits the same rests "
    "as a hand tumble (docs/design.md section 11)";

std::string SetupMistake::label() const {
  return target.empty() ? name : name + "[" + target + "]";
}

std::string SetupMistake::text() const {
  return label() + ": " + finding + "; fix: " + fix;
}

namespace {

const char* const kAxisLetters[3] = {"x", "y", "z"};

// The nearest signed DUT axis of a vector, when within the tolerance.
struct Snap {
  bool ok = false;
  int axis = 0;
  int sign = 1;
  Eigen::Vector3d unit() const { return sign * Eigen::Vector3d::Unit(axis); }
  std::string name() const { return std::string(sign > 0 ? "+" : "-") + kAxisLetters[axis]; }
};

Snap snap(const Eigen::Vector3d& v, double tolerance_deg) {
  Snap s;
  const double norm = v.norm();
  if (!(norm > 0.0) || !std::isfinite(norm)) return s;
  const Eigen::Vector3d d = v / norm;
  d.cwiseAbs().maxCoeff(&s.axis);
  s.sign = d(s.axis) >= 0.0 ? 1 : -1;
  s.ok = std::abs(d(s.axis)) >= std::cos(deg_to_rad(tolerance_deg));
  return s;
}

Snap exact(const Eigen::Vector3d& unit_axis) {
  return snap(unit_axis, 1.0);
}

std::string fmt(double v, int digits = 3) {
  std::ostringstream s;
  s << std::setprecision(digits) << v;
  return s.str();
}

std::string vec(const Eigen::Vector3d& v) {
  return "(" + fmt(v(0)) + ", " + fmt(v(1)) + ", " + fmt(v(2)) + ")";
}

// What one phase's response says. `corrected`: the response snapped to DUT axes, when it is a
// quarter turn between them (for the finished run's confirmation).
struct PhaseVerdict {
  std::vector<SetupMistake> mistakes;
  bool judged = false;  // the response is a quarter turn between DUT axes
  Eigen::Vector3d dir_0 = Eigen::Vector3d::Zero();
  Eigen::Vector3d dir_90 = Eigen::Vector3d::Zero();
};

PhaseVerdict judge_phase(Phase p, const PhaseResponse& r, const SetupOptions& o) {
  PhaseVerdict v;
  const std::string name = phase_name(p);
  const Snap s0 = snap(r.at_0, o.axis_tolerance_deg);
  const Snap s90 = snap(r.at_90, o.axis_tolerance_deg);
  const Snap e0 = exact(in_plane_direction(p, 0.0));
  const Snap e90 = exact(in_plane_direction(p, kPi / 2.0));
  const std::string seen = "at alpha = 0 deg gravity reads along " +
                           (s0.ok ? s0.name() : vec(r.at_0)) + ", at 90 deg along " +
                           (s90.ok ? s90.name() : vec(r.at_90)) + " (section 1: " + e0.name() +
                           " and " + e90.name() + ")";
  if (!s0.ok || !s90.ok || s0.axis == s90.axis) {
    SetupMistake m{"pose_unclear", name,
                   "phase " + name + " is not a quarter turn between DUT axes: " + seen,
                   "check phases." + name + ".hold in the gimbal's axis map (the DUT's " + name +
                       " axis must lie on the turning axis, held horizontal) and that the IMU's "
                       "axes lie along the fixture's"};
    v.mistakes.push_back(m);
    return v;
  }
  v.judged = true;
  v.dir_0 = s0.unit();
  v.dir_90 = s90.unit();
  const Eigen::Vector3d n_seen = v.dir_0.cross(v.dir_90);
  const Eigen::Vector3d n_expected = e0.unit().cross(e90.unit());
  const Snap turn = exact(n_seen);
  const bool zero_right = s0.axis == e0.axis && s0.sign == e0.sign;
  if (n_seen.isApprox(n_expected)) {
    if (!zero_right)
      v.mistakes.push_back({"zero_offset", name,
                            "phase " + name + " turns the right way but starts elsewhere: " + seen,
                            "set phases." + name +
                                ".zero_deg in the gimbal's axis map so that alpha = 0 puts "
                                "gravity along " +
                                e0.name() + " of the DUT"});
  } else if (n_seen.isApprox(-n_expected)) {
    v.mistakes.push_back(
        {"axis_sign", name,
         "phase " + name + " turns the DUT the wrong way about its " + name + " axis: " + seen,
         "negate phases." + name + ".sign in the gimbal's axis map (grbl/phases, smc100/phases)"});
    if (!(s0.axis == e0.axis && s0.sign == e0.sign))
      v.mistakes.push_back({"zero_offset", name, "and it starts elsewhere: " + seen,
                            "set phases." + name +
                                ".zero_deg so that alpha = 0 puts gravity "
                                "along " +
                                e0.name()});
  } else {
    const std::string about = kAxisLetters[turn.axis];
    v.mistakes.push_back({"axes_swapped", name,
                          "phase " + name + " turns the DUT about its " + about +
                              " axis, not its " + name + " axis: " + seen,
                          "the axis map's phases." + name + " (axis and hold) turns what phases." +
                              about + " should: swap the two entries, or change phases." + name +
                              ".hold so that the DUT's " + name +
                              " axis lies on the turning axis"});
  }
  return v;
}

struct Judgement {
  std::vector<SetupMistake> stand;  // silent, motionless, unit
  std::array<PhaseVerdict, 3> phases;
  bool motionless = false;
};

Judgement judge(const SetupObservation& obs, const SetupOptions& o) {
  Judgement j;
  if (obs.all_silent) {
    j.stand.push_back({"imu_silent", "", "no IMU sample arrived at any pose",
                       "start the IMU's driver and check the imu_topic the calibration listens "
                       "to (rig.launch imu_topic:=...; rostopic hz on it)"});
    j.motionless = true;  // nothing to judge
    return j;
  }
  if (!obs.silent.empty()) {
    std::string where;
    for (const std::string& s : obs.silent) where += (where.empty() ? "" : ", ") + s;
    j.stand.push_back({"imu_silent", "", "no IMU sample at " + where,
                       "check that the IMU publishes steadily (rostopic hz), its cable and its "
                       "driver's rate"});
  }
  // Motionless: no phase turns the readings.
  int present = 0;
  int still = 0;
  double level_sum = 0.0;
  double turning_sum = 0.0;
  for (const PhaseResponse& r : obs.phases) {
    if (!r.present) continue;
    ++present;
    const double turning = (r.at_90 - r.at_0).norm() / std::sqrt(2.0);
    const double level = r.level.norm();
    level_sum += level;
    turning_sum += 0.5 * (r.at_0.norm() + r.at_90.norm());
    if (turning <= o.motionless_fraction * std::max(level, turning)) ++still;
  }
  if (present == 0) return j;
  j.motionless = still == present;
  if (j.motionless) {
    j.stand.push_back({"imu_motionless", "",
                       "the IMU reads the same at every pose (" + std::to_string(present) +
                           " phases turned, readings changed by less than " +
                           fmt(100.0 * o.motionless_fraction) + " % of |g|)",
                       "the gimbal is simulated or the IMU is not on it: launch the real gimbal "
                       "(rig.launch driver:=grbl|smc100|..., port:=...) and fix the IMU to the "
                       "gimbal's DUT mount"});
  }
  // Output unit, from |g| as the outputs show it.
  const double g_out = (j.motionless ? level_sum : turning_sum) / present;
  if (o.output_unit == "m/s^2") {
    const double ratio = g_out / o.local_gravity;
    if (!(ratio >= o.min_gravity_ratio && ratio <= o.max_gravity_ratio)) {
      SetupMistake m{"output_unit", "", "", ""};
      const std::string seen = "gravity reads " + fmt(g_out, 4) + " in the outputs (" +
                               fmt(o.local_gravity, 6) + " in m/s^2)";
      if (g_out >= 0.5 && g_out <= 2.0) {
        m.finding = seen + ": the outputs are in g, not m/s^2";
        m.fix =
            "convert to m/s^2 in the IMU's driver (REP 145), or set output_unit: g "
            "(rig.launch output_unit:=g)";
      } else if (g_out > 20.0) {
        m.finding = seen + ": the outputs are counts (or another unit), not m/s^2";
        m.fix =
            "set output_unit: counts (rig.launch output_unit:=counts; responsivities in "
            "counts per m/s^2), or convert to m/s^2 in the IMU's driver";
      } else {
        m.finding = seen + ": the outputs are neither m/s^2 nor g";
        m.fix =
            "set output_unit to the outputs' unit (rig.launch output_unit:=...), or convert "
            "to m/s^2 in the IMU's driver";
      }
      j.stand.push_back(m);
    }
  }
  if (j.motionless) return j;
  for (Phase p : kPhases) {
    const PhaseResponse& r = obs.phases[index(p)];
    if (r.present) j.phases[index(p)] = judge_phase(p, r, o);
  }
  return j;
}

// Weighted least squares of outputs = S f + O over `rows` (f the unit direction each row is read
// as); the chi-square (or the sum of squares without standard deviations).
double linear_chi2(const PositionTable& table, const std::vector<std::size_t>& rows,
                   const std::vector<Eigen::Vector3d>& directions) {
  bool weighted = false;
  for (std::size_t i : rows)
    if ((table.rows[i].std.array() > 0.0).all() && table.rows[i].n > 0) weighted = true;
  const Eigen::Index n = static_cast<Eigen::Index>(rows.size());
  double chi2 = 0.0;
  for (int s = 0; s < 3; ++s) {
    Eigen::MatrixXd a(n, 4);
    Eigen::VectorXd b(n);
    for (Eigen::Index k = 0; k < n; ++k) {
      const DwellRecord& row = table.rows[rows[static_cast<std::size_t>(k)]];
      double w = 1.0;
      if (weighted && row.std(s) > 0.0 && row.n > 0)
        w = std::sqrt(static_cast<double>(row.n)) / row.std(s);
      a.row(k) << w * directions[static_cast<std::size_t>(k)].transpose(), w;
      b(k) = w * row.mean(s);
    }
    const Eigen::VectorXd x = a.colPivHouseholderQr().solve(b);
    chi2 += (a * x - b).squaredNorm();
  }
  return chi2;
}

}  // namespace

std::vector<SetupMistake> judge_setup(const SetupObservation& observation,
                                      const SetupOptions& options) {
  const Judgement j = judge(observation, options);
  std::vector<SetupMistake> out = j.stand;
  for (const PhaseVerdict& v : j.phases)
    out.insert(out.end(), v.mistakes.begin(), v.mistakes.end());
  return out;
}

SetupObservation observe_run(const PositionTable& table) {
  SetupObservation obs;
  std::size_t silent = 0;
  std::size_t judged_rows = 0;
  for (Phase p : kPhases) {
    std::vector<const DwellRecord*> rows;
    for (const DwellRecord& row : table.rows) {
      if (row.has_direction || row.orientation_unknown || row.phase != p) continue;
      ++judged_rows;
      if (row.n == 0) {
        ++silent;
        obs.silent.push_back(std::string("phase ") + phase_name(p) + " step " +
                             std::to_string(row.step));
        continue;
      }
      rows.push_back(&row);
    }
    if (rows.size() < 3) continue;
    Eigen::MatrixXd a(static_cast<Eigen::Index>(rows.size()), 3);
    Eigen::MatrixXd b(static_cast<Eigen::Index>(rows.size()), 3);
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const Eigen::Index i = static_cast<Eigen::Index>(k);
      a.row(i) << 1.0, std::cos(rows[k]->angle_rad), std::sin(rows[k]->angle_rad);
      b.row(i) = rows[k]->mean.transpose();
    }
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
    if (qr.rank() < 3) continue;  // fewer than 3 distinct angles
    const Eigen::MatrixXd x = qr.solve(b);
    PhaseResponse& r = obs.phases[index(p)];
    r.present = true;
    r.level = x.row(0).transpose();
    r.at_0 = x.row(1).transpose();
    r.at_90 = x.row(2).transpose();
  }
  obs.all_silent = judged_rows > 0 && silent == judged_rows;
  return obs;
}

std::vector<SetupMistake> detect_setup_mistakes(const PositionTable& table,
                                                const SetupOptions& options) {
  const SetupObservation obs = observe_run(table);
  Judgement j = judge(obs, options);
  std::vector<SetupMistake> out = j.stand;
  // Geometry: confirmed by the fit of the table read as the mistakes say, over the phases whose
  // response is a quarter turn between DUT axes (a pose_unclear phase cannot be read otherwise:
  // on a finished run it is left to the fit and the analysis).
  bool any = false;
  for (const PhaseVerdict& v : j.phases) {
    for (const SetupMistake& m : v.mistakes)
      if (m.name != "pose_unclear") any = true;
  }
  if (!any) return out;
  std::vector<std::size_t> rows;
  std::vector<Eigen::Vector3d> as_labelled;
  std::vector<Eigen::Vector3d> as_seen;
  for (std::size_t i = 0; i < table.rows.size(); ++i) {
    const DwellRecord& row = table.rows[i];
    if (row.has_direction || row.orientation_unknown || row.n == 0) continue;
    const PhaseVerdict& v = j.phases[index(row.phase)];
    if (!v.judged) continue;
    rows.push_back(i);
    as_labelled.push_back(in_plane_direction(row.phase, row.angle_rad));
    as_seen.push_back(v.dir_0 * std::cos(row.angle_rad) + v.dir_90 * std::sin(row.angle_rad));
  }
  if (rows.size() < 8) return out;
  const double chi2_labelled = linear_chi2(table, rows, as_labelled);
  const double chi2_seen = linear_chi2(table, rows, as_seen);
  if (!(chi2_labelled > options.confirm_ratio * chi2_seen)) return out;
  const std::string confirmed = " (read so, the run fits " +
                                fmt(chi2_labelled / std::max(chi2_seen, 1e-300), 3) +
                                " times better than as labelled)";
  for (const PhaseVerdict& v : j.phases) {
    for (SetupMistake m : v.mistakes) {
      if (m.name == "pose_unclear") continue;
      m.finding += confirmed;
      out.push_back(m);
    }
  }
  return out;
}

}  // namespace core
}  // namespace accel_intrinsics
