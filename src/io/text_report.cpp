#include "accel_intrinsics/io/text_report.h"

#include <cmath>
#include <iomanip>
#include <ostream>
#include <string>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/io/analysis_report.h"
#include "accel_intrinsics/io/rounding.h"

namespace accel_intrinsics {
namespace io {

std::string noise_axis_words(const std::string& axis, const core::AxisNoiseModel& a, double rate_hz,
                             const std::string& unit) {
  const std::string density_unit = unit == "m/s^2" ? "(m/s^2)" : unit;
  std::string words = axis + ":";
  std::string separator = " ";
  if (a.white_std > 0.0 && rate_hz > 0.0) {
    words += separator + "white " + two_significant(a.white_std / std::sqrt(rate_hz)) + " " +
             density_unit + "/sqrt(Hz)";
    separator = "; ";
  }
  if (a.gm_sigma > 0.0 && a.gm_tau_s > 0.0) {
    words += separator + "Gauss-Markov " + two_significant(a.gm_sigma) + " " + unit + " over " +
             two_significant(a.gm_tau_s) + " s";
    separator = "; ";
  }
  if (a.rw_density > 0.0) {
    words += separator + "random walk " + two_significant(a.rw_density) + " " + density_unit +
             "/sqrt(s)";
    separator = "; ";
  }
  if (!a.slow()) words += separator + "no slow part";
  if (a.slow() && a.slow_scale_rel_var > 0.0)  // as estimated from the data (noise.h)
    words +=
        " (relative std of its scale " + two_significant(std::sqrt(a.slow_scale_rel_var)) + ")";
  return words;
}

void write_fit_report(std::ostream& out, const core::FitResult& r, const ResultContext& context,
                      const std::string& output_unit) {
  const core::Intrinsics& in = r.intrinsics;
  out << "accel_intrinsics offline_fit\n";
  if (!context.device_serial.empty()) out << "device:        " << context.device_serial << "\n";
  if (context.input) {
    out << "input:         " << context.input->summary << "\n";
    if (!context.complete) {
      out << "INCOMPLETE RUN: the result below uses only the dwells found\n";
    }
  }
  for (const std::string& w : context.warnings) out << "warning:       " << w << "\n";
  out << "model:         " << r.model_label() << "\n";
  out << "local gravity: " << std::setprecision(9) << r.local_gravity << " m/s^2\n";
  if (r.model == core::FitModel::Tumble) {
    out << "method:        hand tumble, orientations unknown: intrinsics only (S in the sensor's "
           "own "
           "frame)\n\n";
  } else {
    out << "positions:     x " << r.positions[0] << ", y " << r.positions[1] << ", z "
        << r.positions[2] << "\n\n";
  }

  // Each value rounded to its uncertainty (io/rounding.h); the JSON keeps full precision.
  auto line = [&out](const std::string& name, double value, double std_value,
                     const std::string& unit) {
    const Rounded r = round_to_uncertainty(value, std_value);
    out << "  " << std::left << std::setw(18) << name << std::right << std::setw(20) << r.value
        << "  +- " << std::left << std::setw(12) << r.uncertainty << std::right << " " << unit
        << "\n";
  };
  out << "  " << std::left << std::setw(18) << "parameter" << std::right << std::setw(20) << "value"
      << "     std (k=1)\n";
  static const char* const kAngles[] = {"theta_uv", "theta_vw", "theta_wu"};
  for (int s = 0; s < 3; ++s) {
    line(std::string("|") + core::accelerometer_name(s) + "|", in.responsivity(s),
         in.responsivity_std(s), "");
  }
  for (int a = 0; a < 3; ++a) {
    line(kAngles[a], core::rad_to_deg(in.angles_rad(a)), core::rad_to_deg(in.angles_std_rad(a)),
         "deg");
  }
  for (int s = 0; s < 3; ++s) {
    line(std::string("O_") + core::accelerometer_name(s), r.O(s), r.O_std(s), output_unit);
  }
  if (r.model == core::FitModel::Eq4) {
    for (int s = 0; s < 3; ++s) {
      for (core::Phase p : core::kPhases) {
        line(std::string("O_") + core::accelerometer_name(s) + core::phase_name(p),
             r.offset_per_phase(s, core::index(p)), r.offset_per_phase_std(s, core::index(p)),
             "m/s^2");
      }
    }
  }
  for (std::size_t i = 0; i < r.effects.size(); ++i) {
    line(r.effects[i].label(), r.effects[i].value,
         i < r.effects_std.size() ? r.effects_std[i] : NAN, "");
  }
  // Rows rounded to their standard uncertainties (the JSON has every digit).
  out << (r.model == core::FitModel::Tumble
              ? "\n  vectors (rows of S, sensor frame: u along x, v in the x-y plane), +- std:\n"
              : "\n  vectors (rows of S, DUT frame x y z), +- std:\n");
  for (int s = 0; s < 3; ++s) {
    out << "    " << core::accelerometer_name(s) << " = [";
    for (int c = 0; c < 3; ++c) {
      const double var = r.covariance.rows() > 3 * s + c ? r.covariance(3 * s + c, 3 * s + c) : NAN;
      out << (c ? ", " : "") << std::setw(22)
          << with_uncertainty(r.S(s, c), var >= 0.0 ? std::sqrt(var) : NAN);
    }
    out << "]\n";
  }
  out << "  cross-sensitivity P = S^-1 (row-major), +- std:\n";
  for (int s = 0; s < 3; ++s) {
    out << "    [";
    for (int c = 0; c < 3; ++c) {
      out << (c ? ", " : "") << std::setw(22)
          << with_uncertainty(r.cross_sensitivity(s, c), r.cross_sensitivity_std(s, c));
    }
    out << "]\n";
  }
  out << "\n  reduced chi2:  " << std::setprecision(3) << r.reduced_chi2 << " (chi2 "
      << std::setprecision(4) << r.chi2 << ", dof " << r.dof << ")\n";
  out << "  residual rms:  " << two_significant(r.residual_rms) << " " << output_unit << "\n";
  // The noise the weights assumed (docs/design.md section 12): white, or the model of the long
  // rest.
  out << "  noise model:   " << r.noise_model.kind();
  if (!r.noise_model.white()) {
    // How the fit used it (fit.cpp): the joint and the tumble fits by generalized least squares
    // (the covariance between dwells, or rests); eq4 adds the slow part to each dwell's variance.
    out << " ("
        << (r.model == core::FitModel::Eq4      ? "slow part added to each dwell's variance"
            : r.model == core::FitModel::Tumble ? "generalized least squares across the rests"
                                                : "generalized least squares across the dwells")
        << ")";
    if (!r.noise_model.source.empty()) out << "\n    from " << r.noise_model.source;
    for (int s = 0; s < 3; ++s) {
      out << "\n    "
          << noise_axis_words(core::accelerometer_name(s), r.noise_model.axes[s],
                              r.noise_model.rate_hz, output_unit);
    }
  }
  out << "\n";
  out.flush();
}

namespace {

// The expanded uncertainties of the budget (the JSON has every source).
void write_budget_report(std::ostream& out, const core::UncertaintyBudget& b,
                         const std::string& output_unit) {
  out << "\n  uncertainty budget: " << b.sources.size() << " sources (type A";
  for (std::size_t i = 1; i < b.sources.size(); ++i) out << ", " << b.sources[i].name;
  out << "), expanded with k = " << b.coverage_factor << "\n";
  static const char* const kAngles[] = {"theta_uv", "theta_vw", "theta_wu"};
  for (int s = 0; s < 3; ++s)
    out << "    U |" << core::accelerometer_name(s) << "|      " << std::setprecision(2)
        << b.expanded.responsivity(s) << "\n";
  for (int i = 0; i < 3; ++i)
    out << "    U " << kAngles[i] << "  " << std::setprecision(2)
        << core::rad_to_deg(b.expanded.angles_rad(i)) << " deg\n";
  for (int s = 0; s < 3; ++s)
    out << "    U O_" << core::accelerometer_name(s) << "       " << std::setprecision(2)
        << b.expanded.offset(s) << " " << output_unit << "\n";
}

}  // namespace

void write_text_report(std::ostream& out, const core::CalibrationReport& report,
                       const ResultContext& context) {
  write_fit_report(out, report.certificate, context, report.output_unit);
  if (report.output_unit != "m/s^2") {
    out << "  output unit:   " << report.output_unit << " (responsivities in " << report.output_unit
        << " per m/s^2, offsets in " << report.output_unit << ")\n";
  }
  if (report.temperature) {
    const core::RunTemperature& t = *report.temperature;
    const auto precision = out.precision(4);
    out << "  temperature:   S and O at T_ref = " << t.reference_c << " C (dwells " << t.min_c
        << " to " << t.max_c << " C; " << t.dwells_with_temperature << " of " << t.dwells
        << " dwells with a reading)\n";
    out.precision(precision);
  }
  out << "  quality gate:  " << (report.quality.pass ? "passed" : "FAILED") << "\n";
  for (const std::string& reason : report.quality.reasons) out << "    - " << reason << "\n";
  if (report.budget) write_budget_report(out, *report.budget, report.output_unit);
  if (context.rest_detection) {
    const core::RestDetection& d = *context.rest_detection;
    out << "  rests:         " << d.rests.size() << " fitted";
    if (!d.rejected.empty())
      out << ", " << d.rejected.size() << " spans rejected (JSON rejected_spans)";
    out << "\n";
  }
  if (report.coverage) {
    out << "  coverage:      "
        << (report.coverage->complete() ? "every axis up and down within 45 deg" : "INCOMPLETE")
        << "\n";
    for (const std::string& m : report.coverage->missing) out << "    - " << m << "\n";
  }
  if (report.next_pose) {
    const auto precision = out.precision(2);
    out << "  next pose:     " << report.next_pose->words << " (largest relative uncertainty "
        << report.next_pose->target << " " << report.next_pose->relative_std_now
        << ", one more rest there: largest " << report.next_pose->largest_after << ")\n";
    out.precision(precision);
  }
  if (report.tumble_analysis) {
    const core::TumbleAnalysis& a = *report.tumble_analysis;
    const auto precision = out.precision(4);
    out << "\n  analysis (tumble): reduced chi2 " << a.before.reduced_chi2 << " -> "
        << a.after.reduced_chi2;
    if (!a.noise_model.white())
      out << " (each rest weighted with the slow part of the noise model, " << a.noise_model.kind()
          << ")";
    if (a.named.empty()) out << "; no sensor effect named (" << a.stop_reason << ")";
    out << "\n";
    for (std::size_t i = 0; i < a.named.size(); ++i)
      out << "    named: " << a.after.effects[i].label() << " = " << a.after.effects[i].value
          << " +- " << a.after.effects_std[i] << " (p " << a.named[i].p_holm << ")\n";
    for (const std::string& n : a.not_screened) out << "    not screened: " << n << "\n";
    out.precision(precision);
  }
  if (!report.analysis) return;
  out << "\n";
  write_analysis_report(out, *report.analysis);
  if (report.timing_lag) {
    out << "  timing lag (raw streams): " << (report.timing_lag->ok ? "" : "no estimate: ")
        << report.timing_lag->message << "\n";
  }
  out.flush();
}

}  // namespace io
}  // namespace accel_intrinsics
