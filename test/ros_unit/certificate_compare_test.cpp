// offline_fit --budget/--report and compare_results end to end, in process: simulated position
// tables as CSV, the budget file shipped in config/, the certificate PDF read back with poppler's
// pdftotext (numbers compared with the JSON, rounded per GUM 7.2.6) and rendered with pdftoppm,
// comparisons of remounted and changed devices, refusals (different g, no uncertainties).
// KEEP_TEST_FILES=1 keeps the files (PDF, PNG pages) in /tmp/certificate_test_*.
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <utility>

#include "../support/source_dir.h"
#include "../support/test_files.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/run/calibrate.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/io/result_document.h"
#include "accel_intrinsics/ros/compare_results.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

const std::string kBudget =
    accel_intrinsics::test_support::source_dir() + "/config/uncertainty_budget.yaml";

core::Device device(std::uint64_t seed) {
  core::Device d;
  d.S << 1.021, 0.013, -0.009, -0.017, 0.987, 0.021, 0.008, -0.014, 1.012;
  d.O << 0.12, -0.31, 0.05;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  d.S = d.S * q.toRotationMatrix().transpose();  // a mounting
  return d;
}

std::string simulated_csv(const TempDir& dir, const std::string& name, const core::Device& truth,
                          std::uint64_t seed) {
  core::SimulationOptions sim;
  sim.truth = truth;
  sim.seed = seed;
  const std::string path = dir.file(name);
  core::write_position_table_file(path, core::simulate_position_table(sim));
  return path;
}

// The shipped budget with a lab's own certificate block in place of the template's (a
// certificate of the template's block is refused: certificate_guard_test.cpp).
std::string lab_budget(const TempDir& dir) {
  std::string text = read_file(kBudget);
  for (const auto& [from, to] : {std::pair<std::string, std::string>{
                                     "Example Metrology Lab, Inertial Sensors Group", "Test Lab"},
                                 {"1 Example Road, Example Town", "2 Test Street"},
                                 {"SN 000123", "SN T-0042"},
                                 {"A. N. Operator", "T. Operator"}}) {
    const std::size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
  }
  const std::string path = dir.file("lab_budget.yaml");
  std::ofstream(path) << text;
  return path;
}

// offline_fit --csv CSV --json OUT [--budget] [--report PDF] [--gravity G]; the JSON.
json offline(const std::string& csv, const std::string& out_json, bool budget,
             const std::string& pdf = "", double gravity = 0.0, std::string* err_text = nullptr,
             const std::string& budget_file = kBudget) {
  ai::OfflineFitArguments args;
  args.csv = csv;
  args.json_out = out_json;
  if (budget) args.budget = budget_file;
  args.report_pdf = pdf;
  if (gravity > 0.0) {
    args.gravity = gravity;
    args.gravity_given = true;
  }
  std::ostringstream out, err;
  const int status = ai::run_offline_fit(args, out, err);
  if (err_text) *err_text = err.str();
  EXPECT_EQ(status, 0) << err.str();
  if (status != 0) return json();
  return json::parse(read_file(out_json));
}

int shell(const std::string& command) {
  const int s = std::system(command.c_str());
  return WIFEXITED(s) ? WEXITSTATUS(s) : -1;
}

// Decimal places of U rounded to two significant digits (GUM 7.2.6).
int decimals_for(double U) {
  return 1 - static_cast<int>(std::floor(std::log10(U)));
}

TEST(OfflineFitBudget, JsonCarriesTheBudgetOfTheShippedFileAndItsCertificateBlock) {
  TempDir dir;
  const std::string csv = simulated_csv(dir, "run.csv", device(1), 1);
  const json j = offline(csv, dir.file("r.json"), true);
  const json& b = j.at("uncertainty_budget");
  // The shipped file sets all six sources: type_a plus six.
  ASSERT_EQ(b.at("sources").size(), 7u);
  EXPECT_EQ(b.at("sources")[0].at("name"), "type_a");
  EXPECT_EQ(b.at("expanded").at("k"), 2.0);
  for (const char* s : {"u", "v", "w"}) {
    EXPECT_GT(b.at("combined_std").at("responsivity").at(s).get<double>(),
              j.at("responsivity_std").at(s).get<double>());
  }
  EXPECT_FALSE(j.at("certificate").at("lab").get<std::string>().empty());
  EXPECT_EQ(j.at("local_gravity_source"),
            "standard gravity (offline_fit default; no --gravity given)");
  // A bad budget file: one line naming the key, exit 1, no JSON.
  const std::string bad = dir.file("bad.yaml");
  std::ofstream(bad) << "axis_tilt_std_deg: -3\n";
  ai::OfflineFitArguments args;
  args.csv = csv;
  args.budget = bad;
  args.json_out = dir.file("bad.json");
  std::ostringstream out, err;
  EXPECT_EQ(ai::run_offline_fit(args, out, err), ai::kOfflineFitBadInput);
  const std::string message = err.str();
  EXPECT_NE(message.find("axis_tilt_std_deg"), std::string::npos) << message;
  EXPECT_EQ(std::count(message.begin(), message.end(), '\n'), 1) << message;
  EXPECT_FALSE(fs::exists(args.json_out));
}

TEST(Certificate, PdfTextStatesTheJsonNumbersRoundedToTheirUncertainty) {
  ASSERT_EQ(shell("command -v pdftotext >/dev/null && command -v pdftoppm >/dev/null"), 0)
      << "poppler-utils missing (tools/install_deps.sh)";
  TempDir dir;
  const std::string csv = simulated_csv(dir, "run.csv", device(2), 2);
  const std::string pdf = dir.file("certificate.pdf");
  const json j = offline(csv, dir.file("r.json"), true, pdf, 9.80123, nullptr, lab_budget(dir));
  ASSERT_TRUE(fs::exists(pdf));
  ASSERT_EQ(shell("pdftotext -layout " + pdf + " " + dir.file("certificate.txt")), 0);
  const std::string text = read_file(dir.file("certificate.txt"));

  EXPECT_NE(text.find(j.at("certificate").at("lab").get<std::string>()), std::string::npos);
  EXPECT_NE(text.find(j.at("certificate").at("serial").get<std::string>()), std::string::npos);
  EXPECT_NE(text.find("g = 9.801230 m/s^2"), std::string::npos);
  EXPECT_NE(text.find("offline_fit --gravity"), std::string::npos);
  EXPECT_NE(text.find("reduced chi-square"), std::string::npos);
  EXPECT_NE(text.find("Uncertainty budget"), std::string::npos);

  // The nine parameters: "name   value ± U   unit", against the JSON.
  const json& e = j.at("uncertainty_budget").at("expanded");
  struct Row {
    std::string name, value_key, budget_key, sub;
  };
  std::vector<Row> rows;
  for (const char* s : {"u", "v", "w"})
    rows.push_back({std::string("responsivity_") + s, "responsivity", "responsivity", s});
  for (const char* a : {"uv", "vw", "wu"})
    rows.push_back({std::string("angle_") + a, "angles_deg", "angles_deg", a});
  for (const char* s : {"u", "v", "w"})
    rows.push_back({std::string("offset_") + s, "offset", "offset", s});
  for (const Row& r : rows) {
    const std::regex line(r.name + R"(\s+(-?[0-9.]+)\s+±\s+([0-9.]+))");
    std::smatch m;
    ASSERT_TRUE(std::regex_search(text, m, line)) << r.name << " not in the PDF text";
    const double x = j.at(r.value_key).at(r.sub).get<double>();
    const double U = e.at(r.budget_key).at(r.sub).get<double>();
    const std::string value_text = m[1], U_text = m[2];
    const int d = decimals_for(U);
    // Printed with exactly d decimals (both), U to two significant digits.
    const std::size_t dot = U_text.find('.');
    const int printed_decimals =
        dot == std::string::npos ? 0 : static_cast<int>(U_text.size() - dot - 1);
    EXPECT_EQ(printed_decimals, std::max(d, 0)) << r.name << " U " << U_text << " of " << U;
    const double step = std::pow(10.0, -d);
    EXPECT_LE(std::abs(std::stod(U_text) - U), 0.5 * step * (1 + 1e-9)) << r.name;
    EXPECT_LE(std::abs(std::stod(value_text) - x), 0.5 * step * (1 + 1e-9)) << r.name;
    const double significant = std::stod(U_text) / step;  // 10..99 (or 100 after rounding up)
    EXPECT_GE(significant, 9.5) << r.name;
    EXPECT_LE(significant, 100.5) << r.name;
  }

  // Pages render (looked at by eye with KEEP_TEST_FILES=1: /tmp/certificate_test_*/page-*.png).
  ASSERT_EQ(shell("pdftoppm -r 60 -png " + pdf + " " + dir.file("page")), 0);
  int pages = 0;
  for (const auto& f : fs::directory_iterator(dir.file(""))) {
    if (f.path().extension() == ".png") ++pages;
  }
  EXPECT_EQ(pages, 2);
}

TEST(Certificate, StandaloneScriptOnASavedResultWithoutBudgetSaysTypeAOnly) {
  TempDir dir;
  const std::string csv = simulated_csv(dir, "run.csv", device(3), 3);
  // The site's g: with the standard g and no budget the certificate is refused.
  const json j = offline(csv, dir.file("r.json"), false, "", 9.80123);
  const std::string pdf = dir.file("c.pdf");
  ASSERT_EQ(shell("/usr/bin/python3 " + accel_intrinsics::test_support::source_dir() +
                  "/scripts/certificate_report --out " + pdf + " " + dir.file("r.json")),
            0);
  ASSERT_EQ(shell("pdftotext -layout " + pdf + " " + dir.file("c.txt")), 0);
  const std::string text = read_file(dir.file("c.txt"));
  EXPECT_NE(text.find("TYPE A ONLY"), std::string::npos);
  EXPECT_NE(text.find("no residuals given"), std::string::npos);
  // U = 2 x type A for responsivity_u, two significant digits.
  const double U = 2.0 * j.at("responsivity_std").at("u").get<double>();
  std::smatch m;
  ASSERT_TRUE(
      std::regex_search(text, m, std::regex(R"(responsivity_u\s+([0-9.]+)\s+±\s+([0-9.]+))")));
  EXPECT_LE(std::abs(std::stod(m[2]) - U), 0.5 * std::pow(10.0, -decimals_for(U)) * (1 + 1e-9));
  // A missing result: exit 1, one line.
  EXPECT_EQ(shell("/usr/bin/python3 " + accel_intrinsics::test_support::source_dir() +
                  "/scripts/certificate_report --out " + pdf + " /nonexistent.json 2>/dev/null"),
            1);
}

int compare(const std::vector<std::string>& files, const std::string& json_out, bool type_a_only,
            std::string* err_text, const std::string& plot = "") {
  ai::CompareResultsArguments args;
  args.files = files;
  args.json_out = json_out;
  args.type_a_only = type_a_only;
  args.plot_out = plot;
  std::ostringstream out, err;
  const int status = ai::run_compare_results(args, out, err);
  *err_text = err.str();
  return status;
}

TEST(CompareResults, RemountedDeviceIsConsistentChangedDeviceIsNot) {
  TempDir dir;
  const core::Device d = device(4);
  offline(simulated_csv(dir, "a.csv", d, 40), dir.file("a.json"), true);
  core::Device other = d;  // the same triad in another mounting
  other.S =
      d.S *
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix().transpose();
  offline(simulated_csv(dir, "b.csv", other, 41), dir.file("b.json"), true);
  std::string err;
  EXPECT_EQ(compare({dir.file("a.json"), dir.file("b.json")}, dir.file("ab.json"), false, &err,
                    dir.file("ab.png")),
            ai::kCompareConsistent)
      << err;
  const json c = json::parse(read_file(dir.file("ab.json")));
  EXPECT_TRUE(c.at("consistent").get<bool>());
  for (const char* p : {"responsivity_u", "responsivity_v", "responsivity_w", "angle_uv",
                        "angle_vw", "angle_wu", "offset_u", "offset_v", "offset_w"}) {
    EXPECT_EQ(c.at("parameters").at(p).at("values").size(), 2u) << p;
    EXPECT_EQ(c.at("parameters").at(p).at("E_n").size(), 1u) << p;
  }
  EXPECT_TRUE(fs::exists(dir.file("ab.png")));

  // |u| changed by 5 expanded uncertainties of the first result.
  const json a = json::parse(read_file(dir.file("a.json")));
  const double U = a.at("uncertainty_budget").at("expanded").at("responsivity").at("u");
  core::Device changed = d;
  changed.S.row(0) *= 1.0 + 5.0 * U / d.S.row(0).norm();
  offline(simulated_csv(dir, "c.csv", changed, 42), dir.file("c.json"), true);
  EXPECT_EQ(compare({dir.file("a.json"), dir.file("c.json")}, dir.file("ac.json"), false, &err),
            ai::kCompareInconsistent)
      << err;
  const json ac = json::parse(read_file(dir.file("ac.json")));
  EXPECT_GT(std::abs(ac.at("parameters").at("responsivity_u").at("E_n")[0].get<double>()), 1.0);

  // Three results: reference value and degrees of equivalence.
  EXPECT_EQ(compare({dir.file("a.json"), dir.file("b.json"), dir.file("c.json")},
                    dir.file("abc.json"), false, &err),
            ai::kCompareInconsistent);
  const json abc = json::parse(read_file(dir.file("abc.json")));
  EXPECT_EQ(abc.at("parameters").at("angle_uv").at("degrees_of_equivalence").size(), 3u);
  EXPECT_TRUE(abc.at("parameters").at("angle_uv").contains("reference_value"));
}

TEST(CompareResults, RefusesDifferentGravityAndResultsWithoutUncertaintiesInOneLine) {
  TempDir dir;
  const core::Device d = device(6);
  offline(simulated_csv(dir, "a.csv", d, 60), dir.file("a.json"), true);
  offline(simulated_csv(dir, "b.csv", d, 61), dir.file("b.json"), true, "", 9.8012);
  offline(simulated_csv(dir, "c.csv", d, 62), dir.file("c.json"), false);
  std::string err;
  EXPECT_EQ(compare({dir.file("a.json"), dir.file("b.json")}, "", false, &err),
            ai::kCompareBadInput);
  EXPECT_NE(err.find("g = 9.8012"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_EQ(compare({dir.file("a.json"), dir.file("c.json")}, "", false, &err),
            ai::kCompareBadInput);
  EXPECT_NE(err.find("c.json has no uncertainty_budget"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  // With --type-a-only both are compared with U = 2 x type A: two runs of the same device
  // (seeds 60 and 62) agree.
  const int status =
      compare({dir.file("a.json"), dir.file("c.json")}, dir.file("t.json"), true, &err);
  EXPECT_EQ(status, ai::kCompareConsistent) << err;
  const json t = json::parse(read_file(dir.file("t.json")));
  EXPECT_EQ(t.at("uncertainty"), "type_a_only");
  // U = 2 x the type-A standard uncertainty each result states (angles in degrees).
  const json a = json::parse(read_file(dir.file("a.json")));
  const json c = json::parse(read_file(dir.file("c.json")));
  const double ua = a.at("responsivity_std").at("u"), uc = c.at("responsivity_std").at("u");
  EXPECT_NEAR(t.at("parameters").at("responsivity_u").at("U")[0].get<double>(), 2.0 * ua,
              1e-9 * ua);
  EXPECT_NEAR(t.at("parameters").at("responsivity_u").at("U")[1].get<double>(), 2.0 * uc,
              1e-9 * uc);
  const double aa = a.at("angles_std_deg").at("vw"), oc = c.at("offset_std").at("w");
  EXPECT_NEAR(t.at("parameters").at("angle_vw").at("U")[0].get<double>(), 2.0 * aa, 1e-9 * aa);
  EXPECT_NEAR(t.at("parameters").at("offset_w").at("U")[1].get<double>(), 2.0 * oc, 1e-9 * oc);
  EXPECT_EQ(compare({dir.file("a.json")}, "", false, &err), ai::kCompareBadInput);
}

}  // namespace

namespace {

TEST(Certificate, StandaloneScriptReadsTheNodesYamlToo) {
  TempDir dir;
  core::SimulationOptions sim;
  sim.truth = device(7);
  sim.seed = 7;
  sim.local_gravity = 9.80123;
  const core::PositionTable table = core::simulate_position_table(sim);
  core::CalibrateOptions options;
  options.fit.local_gravity = 9.80123;  // the site's (the standard g is refused without 3e-4)
  core::BudgetSpec spec;
  spec.angle_random_std_deg = 0.01;
  spec.samples = 200;
  options.budget = spec;
  const core::CalibrationReport report = core::calibrate(table, nullptr, options);
  ai::io::ResultContext context;
  context.certificate = {{"lab", "YAML Lab"}};
  std::ofstream(dir.file("intrinsics.yaml")) << ai::io::result_yaml_text(report, context);
  const std::string pdf = dir.file("y.pdf");
  ASSERT_EQ(shell("/usr/bin/python3 " + accel_intrinsics::test_support::source_dir() +
                  "/scripts/certificate_report --out " + pdf + " " + dir.file("intrinsics.yaml")),
            0);
  ASSERT_EQ(shell("pdftotext -layout " + pdf + " " + dir.file("y.txt")), 0);
  const std::string text = read_file(dir.file("y.txt"));
  EXPECT_NE(text.find("YAML Lab"), std::string::npos);
  EXPECT_NE(text.find("angle_random_std_deg"), std::string::npos);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(text, m, std::regex(R"(angle_vw\s+([0-9.]+)\s+±\s+([0-9.]+))")));
  const double x = report.certificate.intrinsics.angles_rad(1) * 180.0 / M_PI;
  const double U = report.budget->expanded.angles_rad(1) * 180.0 / M_PI;
  const double step = std::pow(10.0, -decimals_for(U));
  EXPECT_LE(std::abs(std::stod(m[1]) - x), 0.5 * step * (1 + 1e-9));
  EXPECT_LE(std::abs(std::stod(m[2]) - U), 0.5 * step * (1 + 1e-9));
}

}  // namespace
