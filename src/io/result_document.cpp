#include "accel_intrinsics/io/result_document.h"

#include <yaml-cpp/yaml.h>

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <limits>

#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/io/analysis_report.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "json_documents.h"

namespace accel_intrinsics {
namespace io {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// nlohmann writes NaN/inf as null already; being explicit keeps the intent visible.
nlohmann::json number(double value) {
  if (!std::isfinite(value)) return nullptr;
  return value;
}

nlohmann::json row_list(const Eigen::Vector3d& values) {
  return nlohmann::json::array({number(values(0)), number(values(1)), number(values(2))});
}

nlohmann::json matrix_rows(const Eigen::Matrix3d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) rows.push_back(row_list(m.row(r).transpose()));
  return rows;
}

nlohmann::json angle_object(const Eigen::Vector3d& values) {
  return {{"uv", number(values(0))}, {"vw", number(values(1))}, {"wu", number(values(2))}};
}

// {"u": v(0), "v": v(1), "w": v(2)} and {"x": ..., "y": ..., "z": ...}.
nlohmann::json accelerometer_object(const Eigen::Vector3d& values) {
  nlohmann::json out = nlohmann::json::object();
  for (int s = 0; s < 3; ++s) out[core::accelerometer_name(s)] = number(values(s));
  return out;
}

nlohmann::json phase_object(const Eigen::Vector3d& values) {
  nlohmann::json out = nlohmann::json::object();
  for (core::Phase p : core::kPhases) out[core::phase_name(p)] = number(values(core::index(p)));
  return out;
}

// {u: {x, y, z}, v: ..., w: ...} from a matrix with rows u, v, w and columns x, y, z.
nlohmann::json accelerometer_by_phase(const Eigen::Matrix3d& m) {
  nlohmann::json out = nlohmann::json::object();
  for (int s = 0; s < 3; ++s) {
    out[core::accelerometer_name(s)] = phase_object(m.row(s).transpose());
  }
  return out;
}

nlohmann::json counters_json(const core::AssemblerCounters& c) {
  return {{"used", c.samples_used},
          {"dropped_outside_dwell", c.dropped_outside_dwell},
          {"dropped_settle_discard", c.dropped_settle_discard},
          {"dropped_non_finite", c.dropped_non_finite},
          {"dropped_backwards", c.dropped_backwards},
          {"duplicates", c.duplicates},
          {"dropped_late", c.dropped_late}};
}

nlohmann::json input_json(const InputDescription& in) {
  if (!in.bag)
    return {{"type", in.type.empty() ? "csv" : in.type}, {"path", in.path}, {"rows", in.dwells}};
  const BagInputDescription& b = *in.bag;
  const core::AssemblerCounters& c = b.counters;
  return {
      {"type", "bag"},
      {"path", in.path},
      {"imu_topic", b.imu_topic},
      {"command_topic", b.command_topic},
      {"imu_messages", b.imu_messages},
      {"command_messages", b.command_messages},
      {"invalid_commands", b.invalid_commands},
      {"duration_s", b.duration_s},
      {"read_wall_s", b.read_wall_s},
      {"dwells", in.dwells},
      {"samples_used", c.samples_used},
      {"dropped_outside_dwell", c.dropped_outside_dwell},
      {"settle_discard_s", b.settle_discard_s},
      {"dropped_settle_discard", c.dropped_settle_discard},
      {"dropped_non_finite", c.dropped_non_finite},
      {"dropped_backwards", c.dropped_backwards},
      {"duplicates", c.duplicates},
      {"dropped_late", c.dropped_late},
      {"commands_out_of_order", c.commands_out_of_order},
      {"imu_time_offset_s", b.imu_time_offset_s},
      {"files", b.files},
      {"done_seen", b.done_seen},
      {"time_origin_s", b.time_origin_s},
  };
}

// ---- YAML from the JSON tree --------------------------------------------------------------------

// A string that a YAML reader would take for a number, a bool or null must be quoted.
bool reads_as_non_string(const std::string& s) {
  if (s.empty()) return true;
  std::string lower;
  for (char c : s) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const char* word : {"~", "null", "true", "false", "yes", "no", "on", "off", "y", "n", ".nan",
                           ".inf", "-.inf", "+.inf"}) {
    if (lower == word) return true;
  }
  // YAML 1.1 readers (PyYAML's safe_load among them) turn "2026-11-27..." into a date.
  const auto digits = [&s](std::size_t from, std::size_t n) {
    for (std::size_t i = from; i < from + n; ++i) {
      if (i >= s.size() || !std::isdigit(static_cast<unsigned char>(s[i]))) return false;
    }
    return true;
  };
  if (digits(0, 4) && s.size() > 4 && s[4] == '-' && digits(5, 1)) return true;
  char* end = nullptr;
  std::strtod(s.c_str(), &end);
  return end != s.c_str() && *end == '\0';
}

bool is_scalar(const nlohmann::json& j) {
  return !j.is_object() && !j.is_array();
}

void emit_yaml(YAML::Emitter& y, const nlohmann::json& j) {
  if (j.is_object()) {
    y << YAML::BeginMap;
    for (auto it = j.begin(); it != j.end(); ++it) {
      y << YAML::Key << it.key() << YAML::Value;
      emit_yaml(y, it.value());
    }
    y << YAML::EndMap;
  } else if (j.is_array()) {
    // Lists of numbers (vectors, rows of a matrix) on one line; anything else as a block.
    bool flat = true;
    for (const nlohmann::json& e : j) flat = flat && is_scalar(e);
    if (flat && !j.empty()) y << YAML::Flow;
    y << YAML::BeginSeq;
    for (const nlohmann::json& e : j) emit_yaml(y, e);
    y << YAML::EndSeq;
  } else if (j.is_null() || (j.is_number_float() && !std::isfinite(j.get<double>()))) {
    y << YAML::Null;  // as JSON writes a non-finite number
  } else if (j.is_boolean()) {
    y << j.get<bool>();
  } else if (j.is_number()) {
    // nlohmann's shortest representation that reads back to the same double.
    y << j.dump();
  } else {
    const std::string s = j.get<std::string>();
    if (reads_as_non_string(s)) y << YAML::DoubleQuoted;
    y << s;
  }
}

constexpr char kYamlHeader[] =
    "# accel_intrinsics calibration result: the keys and meanings of offline_fit's JSON "
    "(include/accel_intrinsics/io/result_document.h, docs/design.md section 2)\n";

// ---- reading ------------------------------------------------------------------------------------

class Reader {
 public:
  Reader(std::string path, YAML::Node root) : path_(std::move(path)), root_(std::move(root)) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw IoError("cannot read the result in '" + path_ + "': " + what);
  }
  YAML::Node child(const YAML::Node& node, const std::string& key, const std::string& where) const {
    if (!node.IsMap() || !node[key]) fail("missing key '" + where + key + "'");
    return node[key];
  }
  double scalar(const YAML::Node& node, const std::string& where) const {
    if (node.IsNull()) return kNaN;
    try {
      return node.as<double>();
    } catch (const YAML::Exception&) {
      fail("'" + where + "' is not a number");
    }
  }
  Eigen::Vector3d triple(const std::string& key, const char* const names[3]) const {
    const YAML::Node node = child(root_, key, "");
    Eigen::Vector3d out;
    for (int i = 0; i < 3; ++i) {
      out(i) = scalar(child(node, names[i], key + "."), key + "." + names[i]);
    }
    return out;
  }
  Eigen::Vector3d list3(const YAML::Node& node, const std::string& where) const {
    if (!node.IsSequence() || node.size() != 3) fail("'" + where + "' is not a list of 3");
    Eigen::Vector3d out;
    for (int i = 0; i < 3; ++i) out(i) = scalar(node[i], where);
    return out;
  }
  const YAML::Node& root() const { return root_; }

 private:
  std::string path_;
  YAML::Node root_;
};

const char* const kAccelerometers[3] = {"u", "v", "w"};
const char* const kAngles[3] = {"uv", "vw", "wu"};

// A hand tumble's keys (docs/design.md section 11): the frame of S, the rests and rejected spans,
// the detector's levels, the coverage and the pose to try next.
void add_tumble_keys(const core::CalibrationReport& report, const ResultContext& context,
                     nlohmann::json* j) {
  if (report.certificate.model == core::FitModel::Tumble) (*j)["frame"] = core::kTumbleFrame;
  if (context.rest_detection) {
    const core::RestDetection& d = *context.rest_detection;
    nlohmann::json rests = nlohmann::json::array();
    for (const core::DwellRecord& r : d.rests) {
      rests.push_back({{"t_start", number(r.t_start_s)},
                       {"t_end", number(r.t_end_s)},
                       {"n", r.n},
                       {"mean", accelerometer_object(r.mean)},
                       {"std", accelerometer_object(r.std)}});
    }
    (*j)["rests"] = rests;
    nlohmann::json rejected = nlohmann::json::array();
    for (const core::RejectedSpan& r : d.rejected) {
      rejected.push_back(
          {{"t_start", number(r.t_start_s)}, {"t_end", number(r.t_end_s)}, {"reason", r.reason}});
    }
    (*j)["rejected_spans"] = rejected;
    if (d.samples > 0) {
      (*j)["rest_detection"] = {{"quiet_std", accelerometer_object(d.quiet_std)},
                                {"rate_hz", number(d.rate_hz)},
                                {"block_samples", d.block_samples},
                                {"samples", d.samples},
                                {"rest_min_s", number(context.rest_min_s)}};
    }
  }
  if (report.coverage) {
    const core::TumbleCoverage& c = *report.coverage;
    nlohmann::json closest = nlohmann::json::object();
    for (int s = 0; s < 3; ++s)
      closest[core::accelerometer_name(s)] = {{"up", number(c.closest_deg[s][0])},
                                              {"down", number(c.closest_deg[s][1])}};
    (*j)["coverage"] = {{"cone_deg", number(c.cone_deg)},
                        {"complete", c.complete()},
                        {"missing", c.missing},
                        {"closest_deg", closest}};
  }
  if (report.tumble_analysis) {
    // The contract's analysis keys (docs/design.md section 2) for a tumble's screen.
    const core::TumbleAnalysis& a = *report.tumble_analysis;
    nlohmann::json effects = nlohmann::json::array();
    for (std::size_t i = 0; i < a.named.size(); ++i) {
      const core::Effect& e = a.after.effects[i];
      effects.push_back({{"name", e.name()},
                         {"target", e.target_name()},
                         {"value", number(e.value)},
                         {"std", number(a.after.effects_std[i])},
                         {"p_value", number(a.named[i].p_holm)},
                         {"delta_chi2", number(a.named[i].delta_chi2)}});
    }
    (*j)["effects"] = effects;
    (*j)["ambiguous"] = nlohmann::json::array();
    auto gap = [](const core::FitResult& f) {
      return nlohmann::json{{"reduced_chi2", number(f.reduced_chi2)},
                            {"rms", number(f.residual_rms)},
                            {"chi2", number(f.chi2)},
                            {"dof", f.dof}};
    };
    (*j)["gap"] = {{"before", gap(a.before)}, {"after", gap(a.after)}};
    (*j)["not_screened"] = a.not_screened;
    nlohmann::json steps = nlohmann::json::array();
    for (const auto& step : a.steps) {
      nlohmann::json tests = nlohmann::json::array();
      for (const core::TumbleEffectTest& t : step)
        tests.push_back({{"effect", t.effect.label()},
                         {"value", number(t.effect.value)},
                         {"std", number(t.std)},
                         {"delta_chi2", number(t.delta_chi2)},
                         {"p_raw", number(t.p_raw)},
                         {"p_holm", number(t.p_holm)}});
      steps.push_back(tests);
    }
    (*j)["screening"] = {{"method", "tumble: refit per candidate, F test, Holm"},
                         {"steps", steps},
                         {"stop_reason", a.stop_reason}};
  }
  if (report.next_pose) {
    const core::PoseSuggestion& p = *report.next_pose;
    (*j)["next_pose"] = {{"up", row_list(p.up)},
                         {"words", p.words},
                         {"target", p.target},
                         {"relative_std_now", number(p.relative_std_now)},
                         {"relative_std_after", number(p.relative_std_after)},
                         {"largest_relative_std_after", number(p.largest_after)}};
  }
}

// The unit of each number of the document (output_unit: the device's output, e.g. m/s^2, g,
// counts). Every std key has its value's unit.
nlohmann::json units_json(const std::string& output_unit) {
  const std::string out = output_unit.empty() ? "m/s^2" : output_unit;
  return {{"responsivity", out + "/(m/s^2)"},
          {"vectors", out + "/(m/s^2)"},
          {"offset", out},
          {"offset_per_phase", out},
          {"cross_sensitivity", "(m/s^2)/" + out},
          {"angles_deg", "deg"},
          {"local_gravity", "m/s^2"},
          {"residual_rms", out},
          {"noise_density", out + "/sqrt(Hz)"},
          {"sample_rate_hz", "Hz"},
          {"stamp", "s (ROS time)"},
          {"time_utc", "ISO 8601, UTC"}};
}

}  // namespace

namespace detail {

nlohmann::json fit_json(const core::FitResult& result) {
  nlohmann::json j = nlohmann::json::object();
  j["model"] = core::model_name(result.model);
  j["model_label"] = result.model_label();
  j["local_gravity"] = number(result.local_gravity);

  const core::Intrinsics& in = result.intrinsics;
  j["responsivity"] = accelerometer_object(in.responsivity);
  j["responsivity_std"] = accelerometer_object(in.responsivity_std);
  Eigen::Vector3d angles_deg, angles_std_deg;
  for (int i = 0; i < 3; ++i) {
    angles_deg(i) = core::rad_to_deg(in.angles_rad(i));
    angles_std_deg(i) = core::rad_to_deg(in.angles_std_rad(i));
  }
  j["angles_deg"] = angle_object(angles_deg);
  j["angles_std_deg"] = angle_object(angles_std_deg);

  // Rows of S are the vectors; covariance is over (S row-major, O).
  nlohmann::json vectors = nlohmann::json::object();
  nlohmann::json vectors_std = nlohmann::json::object();
  for (int s = 0; s < 3; ++s) {
    Eigen::Vector3d std_row;
    for (int c = 0; c < 3; ++c) {
      const double var = result.covariance(3 * s + c, 3 * s + c);
      std_row(c) = var >= 0.0 ? std::sqrt(var) : kNaN;
    }
    vectors[core::accelerometer_name(s)] = row_list(result.S.row(s).transpose());
    vectors_std[core::accelerometer_name(s)] = row_list(std_row);
  }
  j["vectors"] = vectors;
  j["vectors_std"] = vectors_std;

  j["offset"] = accelerometer_object(result.O);
  j["offset_std"] = accelerometer_object(result.O_std);
  j["offset_per_phase"] = accelerometer_by_phase(result.offset_per_phase);
  j["offset_per_phase_std"] = accelerometer_by_phase(result.offset_per_phase_std);

  j["cross_sensitivity"] = matrix_rows(result.cross_sensitivity);
  j["cross_sensitivity_std"] = matrix_rows(result.cross_sensitivity_std);

  j["reduced_chi2"] = number(result.reduced_chi2);
  j["chi2"] = number(result.chi2);
  j["dof"] = result.dof;
  j["residual_rms"] = number(result.residual_rms);
  j["positions"] = {
      {"x", result.positions[0]}, {"y", result.positions[1]}, {"z", result.positions[2]}};

  nlohmann::json fitted = nlohmann::json::array();
  for (std::size_t i = 0; i < result.effects.size(); ++i) {
    const core::Effect& e = result.effects[i];
    const double std_value = i < result.effects_std.size() ? result.effects_std[i] : kNaN;
    fitted.push_back({{"name", e.name()},
                      {"target", e.target_name()},
                      {"value", number(e.value)},
                      {"std", number(std_value)}});
  }
  j["fitted_effects"] = fitted;
  j["noise_model"] = noise_model_json(result.noise_model);
  return j;
}

nlohmann::json result_document(const core::CalibrationReport& report,
                               const ResultContext& context) {
  nlohmann::json j = fit_json(report.certificate);
  j["certificate_model"] = report.certificate.model_label();
  j["certificate_policy"] = report.certificate_refit_policy ? "refit" : "base";
  j["quality"] = {{"pass", report.quality.pass}, {"reasons", report.quality.reasons}};
  j["output_unit"] = report.output_unit;
  if (report.noise) {
    j["noise_density"] = accelerometer_object(report.noise->density);
    j["noise_density_std"] = accelerometer_object(report.noise->density_std);
    j["sample_rate_hz"] = number(report.noise->rate_hz);
  }
  if (report.temperature) {
    const core::RunTemperature& t = *report.temperature;
    j["temperature"] = {{"reference_c", number(t.reference_c)},
                        {"min_c", number(t.min_c)},
                        {"max_c", number(t.max_c)},
                        {"dwells_with_temperature", t.dwells_with_temperature},
                        {"dwells", t.dwells}};
  }
  if (report.analysis) {
    // The analysis' keys beside the result's, never replacing one (local_gravity is the same).
    nlohmann::json extra = analysis_json(*report.analysis);
    if (report.timing_lag) add_timing_lag(*report.timing_lag, &extra);
    for (auto it = extra.begin(); it != extra.end(); ++it) {
      if (!j.contains(it.key())) j[it.key()] = it.value();
    }
  }
  if (!report.analysis_error.empty()) j["analysis_error"] = report.analysis_error;
  j["method"] = report.method;
  add_tumble_keys(report, context, &j);
  if (report.budget) j["uncertainty_budget"] = budget_json(*report.budget);
  if (!context.certificate.empty()) {
    nlohmann::json fields = nlohmann::json::object();
    for (const auto& f : context.certificate) fields[f.first] = f.second;
    j["certificate"] = fields;
  }
  if (!context.gravity_source.empty()) j["local_gravity_source"] = context.gravity_source;
  j["units"] = units_json(report.output_unit);
  for (const auto& [key, value] :
       {std::pair<const char*, const std::string*>{"device_serial", &context.device_serial},
        {"imu_topic", &context.imu_topic},
        {"gimbal_driver", &context.gimbal_driver},
        {"time_utc", &context.time_utc}}) {
    if (!value->empty()) j[key] = *value;
  }
  if (std::isfinite(context.stamp_s)) j["stamp"] = context.stamp_s;
  if (context.samples) j["samples"] = counters_json(*context.samples);
  if (context.input) {
    j["input"] = input_json(*context.input);
    // A CSV position table cannot tell whether its run was complete; a bag, a stream can.
    j["complete"] = context.input->bag || context.rest_detection ? nlohmann::json(context.complete)
                                                                 : nlohmann::json(nullptr);
    j["warnings"] = context.warnings;
  }
  return j;
}

}  // namespace detail

std::string result_json_text(const core::CalibrationReport& report, const ResultContext& context) {
  return detail::result_document(report, context).dump(2) + "\n";
}

std::string result_yaml_text(const core::CalibrationReport& report, const ResultContext& context) {
  YAML::Emitter y;
  emit_yaml(y, detail::result_document(report, context));
  return std::string(kYamlHeader) + y.c_str() + "\n";
}

void write_result_json(const std::string& path, const core::CalibrationReport& report,
                       const ResultContext& context) {
  write_file_atomically(path, result_json_text(report, context));
}

void write_result_yaml(const std::string& path, const core::CalibrationReport& report,
                       const ResultContext& context) {
  write_file_atomically(path, result_yaml_text(report, context));
}

StoredResult read_result_file(const std::string& path) {
  // JSON is YAML: one parser reads both writers' files.
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw IoError("cannot read '" + path + "'");
  } catch (const YAML::Exception& e) {
    throw IoError("cannot parse '" + path + "': " + e.what());
  }
  const Reader r(path, root);
  if (!root.IsMap()) r.fail("not a map of keys");
  StoredResult out;

  // `model` is the family (joint|eq4); an old node YAML held the label there instead.
  const std::string model = r.child(root, "model", "").as<std::string>("");
  out.model_label = root["model_label"] ? root["model_label"].as<std::string>("") : model;
  try {
    const std::string family = model.substr(0, model.find('+'));
    out.model = family == "tumble" ? core::FitModel::Tumble : core::parse_model(family);
  } catch (const std::invalid_argument& e) {
    r.fail(std::string("key 'model': ") + e.what());
  }

  out.intrinsics.responsivity = r.triple("responsivity", kAccelerometers);
  out.intrinsics.responsivity_std = r.triple("responsivity_std", kAccelerometers);
  const Eigen::Vector3d angles = r.triple("angles_deg", kAngles);
  const Eigen::Vector3d angles_std = r.triple("angles_std_deg", kAngles);
  for (int i = 0; i < 3; ++i) {
    out.intrinsics.angles_rad(i) = core::deg_to_rad(angles(i));
    out.intrinsics.angles_std_rad(i) = core::deg_to_rad(angles_std(i));
  }
  const YAML::Node vectors = r.child(root, "vectors", "");
  for (int s = 0; s < 3; ++s) {
    const std::string key = std::string("vectors.") + kAccelerometers[s];
    out.S.row(s) = r.list3(r.child(vectors, kAccelerometers[s], "vectors."), key).transpose();
  }
  out.O = r.triple("offset", kAccelerometers);
  const YAML::Node rows = r.child(root, "cross_sensitivity", "");
  if (!rows.IsSequence() || rows.size() != 3) r.fail("'cross_sensitivity' is not 3 rows");
  for (int i = 0; i < 3; ++i) {
    out.cross_sensitivity.row(i) = r.list3(rows[i], "cross_sensitivity").transpose();
  }
  out.local_gravity = r.scalar(r.child(root, "local_gravity", ""), "local_gravity");
  if (root["offset_std"]) out.O_std = r.triple("offset_std", kAccelerometers);
  if (const YAML::Node budget = root["uncertainty_budget"]) {
    const YAML::Node e = r.child(budget, "expanded", "uncertainty_budget.");
    core::IntrinsicValues x;
    for (int i = 0; i < 3; ++i) {
      const std::string w = "uncertainty_budget.expanded.";
      x.responsivity(i) = r.scalar(
          r.child(r.child(e, "responsivity", w), kAccelerometers[i], w + "responsivity."), w);
      x.angles_rad(i) = core::deg_to_rad(
          r.scalar(r.child(r.child(e, "angles_deg", w), kAngles[i], w + "angles_deg."), w));
      x.offset(i) =
          r.scalar(r.child(r.child(e, "offset", w), kAccelerometers[i], w + "offset."), w);
    }
    out.expanded = x;
    out.coverage_factor = r.scalar(r.child(e, "k", "uncertainty_budget.expanded."), "k");
  }

  if (root["noise_density"]) out.noise_density = r.triple("noise_density", kAccelerometers);
  if (const YAML::Node quality = root["quality"]) {
    out.quality_pass = r.child(quality, "pass", "quality.").as<bool>(false);
    if (const YAML::Node reasons = quality["reasons"]) {
      for (const YAML::Node& reason : reasons)
        out.quality_reasons.push_back(reason.as<std::string>(""));
    }
  }
  if (root["sample_rate_hz"]) {
    out.sample_rate_hz = r.scalar(root["sample_rate_hz"], "sample_rate_hz");
  }

  // The fitted terms: `fitted_effects`; a node YAML before it named them `effects`.
  const char* fitted_key = root["fitted_effects"] ? "fitted_effects" : "effects";
  const YAML::Node fitted = root[fitted_key];
  if (fitted && fitted.IsSequence()) {
    for (const YAML::Node& e : fitted) {
      StoredEffect effect;
      effect.name = r.child(e, "name", std::string(fitted_key) + "[].").as<std::string>("");
      effect.target = r.child(e, "target", std::string(fitted_key) + "[].").as<std::string>("");
      effect.value = r.scalar(r.child(e, "value", std::string(fitted_key) + "[]."), "value");
      effect.std = e["std"] ? r.scalar(e["std"], "std") : kNaN;
      out.fitted_effects.push_back(effect);
    }
  }
  return out;
}

}  // namespace io
}  // namespace accel_intrinsics
