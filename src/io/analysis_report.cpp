#include "accel_intrinsics/io/analysis_report.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <ostream>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/model/effects.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "json_documents.h"

namespace accel_intrinsics {
namespace io {
namespace {

using core::AnalysisResult;
using core::CandidateScore;
using core::CellGap;
using core::Gap;
using core::GapSummary;

nlohmann::json finite_or_null(double x) {
  return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr);
}

nlohmann::json gap_summary_json(const GapSummary& g) {
  return {{"reduced_chi2", g.reduced_chi2},
          {"rms", g.rms},
          {"chi2", g.chi2},
          {"dof", g.dof},
          {"p_value", g.p_value},
          {"band99", {g.band99_low, g.band99_high}},
          {"consistent_with_noise", g.consistent_with_noise}};
}

nlohmann::json gap_json(const Gap& gap) {
  nlohmann::json j = gap_summary_json(gap.summary);
  // Out of sample (docs/design.md section 12): null when not computed.
  j["cv_chi2_per_point"] = std::isfinite(gap.cv.cv_chi2_per_point)
                               ? nlohmann::json(gap.cv.cv_chi2_per_point)
                               : nlohmann::json(nullptr);
  j["cv_folds"] = gap.cv.folds;
  nlohmann::json cells = nlohmann::json::array();
  for (const CellGap& c : gap.cells) {
    cells.push_back({{"phase", core::phase_name(static_cast<core::Phase>(c.phase))},
                     {"accelerometer", core::accelerometer_name(c.accelerometer)},
                     {"n", c.n},
                     {"chi2", c.chi2},
                     {"rms", c.rms},
                     {"harmonic_power", c.harmonic_power}});
  }
  j["by_phase_accelerometer"] = cells;
  nlohmann::json bins = nlohmann::json::array();
  for (const core::TimeBinGap& b : gap.time_bins) {
    bins.push_back({{"t_begin_s", b.t_begin_s},
                    {"t_end_s", b.t_end_s},
                    {"n", b.n},
                    {"chi2", b.chi2},
                    {"rms", b.rms}});
  }
  j["by_time"] = bins;
  j["trend_z"] = {{"u", gap.trend_z[0]}, {"v", gap.trend_z[1]}, {"w", gap.trend_z[2]}};
  return j;
}

nlohmann::json candidate_json(const CandidateScore& c) {
  nlohmann::json j = {{"name", c.effect.name()},
                      {"target", c.effect.target_name()},
                      {"identifiable", c.identifiable},
                      {"information_ratio", c.information_ratio}};
  if (c.identifiable) {
    j["score_chi2"] = c.score_chi2;
    j["estimate"] = c.effect.value;
    j["estimate_std"] = c.estimate_std;
    j["p_raw"] = c.p_raw;
    j["p_holm"] = c.p_holm;
    j["p_value"] = c.p_adjusted;
    j["detection_threshold"] = c.detection_threshold;
    if (c.refit) j["delta_chi2"] = c.delta_chi2;
    if (c.refit && std::isfinite(c.cv_after)) {
      j["cv_chi2_per_point_before"] = finite_or_null(c.cv_before);
      j["cv_chi2_per_point_after"] = c.cv_after;
    }
  }
  j["unit"] = core::effect_info(c.effect.kind).unit;
  return j;
}

}  // namespace

namespace detail {

nlohmann::json noise_model_json(const core::NoiseModel& m) {
  if (m.white()) return "white";
  nlohmann::json axes = nlohmann::json::object();
  for (int s = 0; s < 3; ++s) {
    const core::AxisNoiseModel& a = m.axes[s];
    axes[core::accelerometer_name(s)] = {{"white_std", a.white_std},
                                         {"gm_sigma", a.gm_sigma},
                                         {"gm_tau_s", a.gm_tau_s},
                                         {"rw_density", a.rw_density},
                                         {"slow_scale_rel_var", a.slow_scale_rel_var}};
  }
  return {{"kind", m.kind()},
          {"source", m.source},
          {"rate_hz", m.rate_hz},
          {"rest",
           {{"t_start", m.rest_t_start_s}, {"t_end", m.rest_t_end_s}, {"samples", m.rest_samples}}},
          {"axes", axes}};
}

nlohmann::json analysis_json(const AnalysisResult& r) {
  nlohmann::json j;
  // Setup mistakes, tested before any physical effect (core/analysis/setup_mistakes.h).
  nlohmann::json mistakes = nlohmann::json::array();
  for (const core::SetupMistake& m : r.setup_mistakes)
    mistakes.push_back(
        {{"name", m.name}, {"target", m.target}, {"finding", m.finding}, {"fix", m.fix}});
  j["setup_mistakes"] = mistakes;
  nlohmann::json effects = nlohmann::json::array();
  for (const core::NamedEffect& e : r.effects) {
    effects.push_back({{"name", e.effect.name()},
                       {"target", e.effect.target_name()},
                       {"value", e.effect.value},
                       {"std", e.std},
                       {"p_value", e.p_value},
                       {"unit", core::effect_info(e.effect.kind).unit},
                       {"p_raw", e.p_raw},
                       {"score_chi2", e.score_chi2},
                       {"delta_chi2", e.delta_chi2},
                       {"step", e.step},
                       {"closest_alternative", e.closest_alternative},
                       {"closest_correlation", e.closest_correlation},
                       {"cv_chi2_per_point_before", finite_or_null(e.cv_before)},
                       {"cv_chi2_per_point_after", finite_or_null(e.cv_after)}});
  }
  j["effects"] = effects;
  nlohmann::json amb = nlohmann::json::array();
  for (const core::Ambiguity& a : r.ambiguous) {
    amb.push_back({{"named", a.named},
                   {"candidates", a.candidates},
                   {"correlation", a.correlation},
                   {"separating_experiment", a.separating_experiment}});
  }
  j["ambiguous"] = amb;
  j["gap"] = {{"before", gap_json(r.before)}, {"after", gap_json(r.after)}};
  j["noise_model"] = noise_model_json(r.noise_model);
  const core::NoiseEntry& cn = r.correlated_noise;
  j["noise_entries"] = nlohmann::json::array({{{"name", cn.name},
                                               {"named", cn.named},
                                               {"noise_model", cn.noise_model},
                                               {"white_reduced_chi2", cn.white_reduced_chi2},
                                               {"white_p_value", cn.white_p_value},
                                               {"model_reduced_chi2", cn.model_reduced_chi2},
                                               {"model_p_value", cn.model_p_value},
                                               {"reason", cn.reason}}});
  j["model_before"] = r.before_fit.model_label();
  j["model_after"] = r.after_fit.model_label();
  j["local_gravity"] = r.local_gravity;
  j["stop_reason"] = r.stop_reason;
  nlohmann::json steps = nlohmann::json::array();
  for (const core::ScreeningStep& s : r.steps) {
    nlohmann::json cands = nlohmann::json::array();
    for (const CandidateScore& c : s.candidates) cands.push_back(candidate_json(c));
    steps.push_back({{"model", s.model},
                     {"reduced_chi2", s.gap.reduced_chi2},
                     {"critical_chi2", s.critical_chi2},
                     {"chosen", s.chosen},
                     {"candidates", cands}});
  }
  j["screening"] = steps;
  nlohmann::json unid = nlohmann::json::array();
  for (const CandidateScore& c : r.unidentifiable) {
    unid.push_back({{"name", c.effect.name()},
                    {"target", c.effect.target_name()},
                    {"information_ratio", c.information_ratio},
                    {"reason", "absorbed by the base model parameters (S, O, fitted effects)"}});
  }
  j["unidentifiable"] = unid;
  j["not_screened"] = r.not_screened;
  j["unobservable"] = r.unobservable;
  return j;
}

void add_timing_lag(const core::TimingLagEstimate& lag, nlohmann::json* analysis) {
  nlohmann::json& j = *analysis;
  j["timing_lag"] = {{"ok", lag.ok},
                     {"message", lag.message},
                     {"value", lag.lag_s},
                     {"std", lag.std_s},
                     {"p_value", lag.p_value},
                     {"detected", lag.detected},
                     {"lr_chi2", lag.lr_chi2},
                     {"samples_used", lag.samples_used},
                     {"detection_threshold", lag.detection_threshold_s}};
  if (lag.detected) {
    j["effects"].push_back({{"name", "timing_lag"},
                            {"target", "all"},
                            {"value", lag.lag_s},
                            {"std", lag.std_s},
                            {"p_value", lag.p_value}});
  }
}

}  // namespace detail

std::string analysis_json_text(const AnalysisResult& analysis) {
  return detail::analysis_json(analysis).dump(2);
}

std::string analysis_json_text(const core::CalibrationReport& report,
                               const ResultContext& context) {
  if (!report.analysis) {
    throw std::invalid_argument(
        "analysis_json_text: the report has no analysis" +
        (report.analysis_error.empty() ? std::string() : " (" + report.analysis_error + ")"));
  }
  const AnalysisResult& analysis = *report.analysis;
  nlohmann::json j = detail::analysis_json(analysis);
  if (report.timing_lag) detail::add_timing_lag(*report.timing_lag, &j);
  // Which model is the certificate, and which models the analysis compared.
  j["certificate_model"] = report.certificate.model_label();
  j["certificate_policy"] = report.certificate_refit_policy ? "refit" : "base";
  j["base_model"] = analysis.before_fit.model_label();
  j["refit_model"] = analysis.after_fit.model_label();
  if (std::isfinite(context.stamp_s)) j["stamp"] = context.stamp_s;
  return j.dump(2);
}

void write_analysis_report(std::ostream& out, const AnalysisResult& r) {
  using core::accelerometer_name;
  using core::Phase;
  using core::phase_name;
  const std::ios::fmtflags flags = out.flags();
  const std::streamsize precision = out.precision();
  out << std::setprecision(4);
  auto gap_line = [&](const char* when, const std::string& model, const GapSummary& g) {
    out << "  " << when << " (" << model << "): reduced chi2 " << g.reduced_chi2 << " (99 % band "
        << g.band99_low << ".." << g.band99_high << ", p = " << g.p_value << "), RMS "
        << g.rms * 1e3 << " mm/s^2"
        << (g.consistent_with_noise ? "" : "  <- not consistent with noise") << "\n";
  };
  for (const core::SetupMistake& m : r.setup_mistakes)
    out << "  setup mistake " << m.text() << "\n";
  out << "discrepancy analysis (g = " << std::setprecision(8) << r.local_gravity
      << std::setprecision(4) << " m/s^2)\n";
  gap_line("gap before", r.before_fit.model_label(), r.before.summary);
  gap_line("gap after ", r.after_fit.model_label(), r.after.summary);
  if (std::isfinite(r.before.cv.cv_chi2_per_point))
    out << "  out of sample (" << r.before.cv.folds
        << " time-block folds): cross-validated chi2 per point before "
        << r.before.cv.cv_chi2_per_point << ", after " << r.after.cv.cv_chi2_per_point << "\n";
  out << "  noise model: " << r.noise_model.kind();
  if (!r.noise_model.white()) {
    out << " (from " << r.noise_model.source << "; per u v w: sigma";
    for (const core::AxisNoiseModel& a : r.noise_model.axes) out << " " << a.gm_sigma * 1e3;
    out << " mm/s^2, tau";
    for (const core::AxisNoiseModel& a : r.noise_model.axes) out << " " << a.gm_tau_s;
    out << " s, random walk";
    for (const core::AxisNoiseModel& a : r.noise_model.axes) out << " " << a.rw_density * 1e3;
    out << " (mm/s^2)/sqrt(s))";
  }
  out << "\n  correlated_noise (noise-model entry): "
      << (r.correlated_noise.named ? "named" : "not named") << " (white reduced chi2 "
      << r.correlated_noise.white_reduced_chi2 << "; " << r.correlated_noise.reason << ")\n";
  // Where the gap was: the three worst phase x accelerometer cells and their strongest harmonic.
  std::vector<CellGap> cells = r.before.cells;
  std::sort(cells.begin(), cells.end(),
            [](const CellGap& a, const CellGap& b) { return a.chi2 > b.chi2; });
  out << "  worst cells before (chi2/n, strongest harmonic of the angle):";
  for (std::size_t i = 0; i < std::min<std::size_t>(3, cells.size()); ++i) {
    const CellGap& c = cells[i];
    std::size_t k = 0;
    for (std::size_t h = 1; h < c.harmonic_power.size(); ++h) {
      if (c.harmonic_power[h] > c.harmonic_power[k]) k = h;
    }
    out << "  " << phase_name(static_cast<Phase>(c.phase)) << "/"
        << accelerometer_name(c.accelerometer) << " " << (c.n > 0 ? c.chi2 / c.n : 0.0);
    if (!c.harmonic_power.empty()) out << " (k=" << k << ")";
  }
  out << "\n  trend z vs time before (u v w): " << r.before.trend_z[0] << " " << r.before.trend_z[1]
      << " " << r.before.trend_z[2] << "\n";
  if (r.effects.empty()) out << "  named effects: none (" << r.stop_reason << ")\n";
  for (const core::NamedEffect& e : r.effects) {
    out << "  named: " << e.effect.label() << " = " << e.effect.value << " +- " << e.std << " "
        << core::effect_info(e.effect.kind).unit << "  (p = " << e.p_value
        << ", delta chi2 = " << e.delta_chi2 << ", step " << e.step << ")\n";
  }
  if (!r.effects.empty()) out << "  stopped: " << r.stop_reason << "\n";
  for (const core::Ambiguity& a : r.ambiguous) {
    out << "  ambiguous:";
    for (const std::string& c : a.candidates) out << " " << c;
    out << " (|corr| " << a.correlation << "): " << a.separating_experiment << "\n";
  }
  for (const CandidateScore& c : r.unidentifiable) {
    out << "  unidentifiable: " << c.effect.label()
        << " (absorbed by the base model, information ratio " << c.information_ratio << ")\n";
  }
  for (const std::string& n : r.not_screened) out << "  not screened: " << n << "\n";
  for (const std::string& n : r.unobservable) out << "  unobservable: " << n << "\n";
  out.flags(flags);
  out.precision(precision);
}

std::string analysis_summary_line(const core::CalibrationReport& report) {
  if (!report.analysis) throw std::invalid_argument("analysis_summary_line: no analysis");
  const core::AnalysisResult& analysis = *report.analysis;
  std::ostringstream s;
  s.precision(4);
  s << "reduced chi2 " << analysis.before.summary.reduced_chi2 << " ("
    << analysis.before_fit.model_label() << ") -> " << analysis.after.summary.reduced_chi2 << " ("
    << analysis.after_fit.model_label() << "); named:";
  if (analysis.effects.empty()) s << " none";
  for (const core::NamedEffect& e : analysis.effects) {
    s << " " << e.effect.label() << " = " << e.effect.value << " +- " << e.std << " (p "
      << e.p_value << ")";
  }
  s << "; certificate: " << report.certificate.model_label();
  if (report.timing_lag) {
    s << "; " << (report.timing_lag->ok ? "" : "timing lag: no estimate: ")
      << report.timing_lag->message;
  }
  return s.str();
}

}  // namespace io
}  // namespace accel_intrinsics
