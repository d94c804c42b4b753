// Certificates refuse to mislead (docs/design.md section 15): scripts/certificate_report makes no
// certificate, exit 3 with the reason and its fix on stderr, when g is the standard 9.80665 with a
// budget g uncertainty below 3e-4, or when the certificate block is still the shipped template's;
// --draft makes one anyway with DRAFT on every page (read back with poppler's pdftotext, page by
// page); offline_fit --report passes the refusal on. The results are offline_fit runs on
// simulated position tables with budget files written here.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "../support/source_dir.h"
#include "../support/test_files.h"
#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;
namespace core = accel_intrinsics::core;
namespace fs = std::filesystem;
using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

namespace {

const std::string kScript =
    accel_intrinsics::test_support::source_dir() + "/scripts/certificate_report";

struct Shell {
  int status = -1;
  std::string err;
};

Shell shell(const std::string& command, const TempDir& dir) {
  const std::string err_file = dir.file("stderr.txt");
  const int s = std::system((command + " 2>" + err_file).c_str());
  return {WIFEXITED(s) ? WEXITSTATUS(s) : -1, read_file(err_file)};
}

// A budget file: one source (g) and a certificate block.
std::string budget(const TempDir& dir, double gravity_std_rel, const std::string& lab,
                   const std::string& serial) {
  const std::string path = dir.file("budget.yaml");
  std::ofstream(path) << "gravity_std_rel: " << gravity_std_rel
                      << "\nangle_random_std_deg: 0.005\nsamples: 200\ncertificate:\n  lab: \""
                      << lab << "\"\n  serial: \"" << serial << "\"\n";
  return path;
}

// offline_fit on a simulated run at g (the fit told the same g unless standard); the JSON path.
std::string result(const TempDir& dir, double g, const std::string& budget_file,
                   const std::string& pdf = "", bool draft = false, int* status = nullptr,
                   std::string* err_text = nullptr) {
  core::SimulationOptions sim;
  sim.seed = 5;
  sim.local_gravity = g;
  const std::string csv = dir.file("run.csv");
  core::write_position_table_file(csv, core::simulate_position_table(sim));
  ai::OfflineFitArguments args;
  args.csv = csv;
  args.json_out = dir.file("r.json");
  args.budget = budget_file;
  args.report_pdf = pdf;
  args.report_draft = draft;
  if (g != 9.80665) {
    args.gravity = g;
    args.gravity_given = true;
  }
  std::ostringstream out, err;
  const int s = ai::run_offline_fit(args, out, err);
  if (status) *status = s;
  if (err_text) *err_text = err.str();
  return args.json_out;
}

TEST(CertificateGuard, StandardGravityWithASmallGUncertaintyIsRefused) {
  TempDir dir;
  const std::string json = result(dir, 9.80665, budget(dir, 2e-5, "Test Lab", "SN T-1"));
  const std::string pdf = dir.file("c.pdf");
  const Shell r = shell("/usr/bin/python3 " + kScript + " --out " + pdf + " " + json, dir);
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_FALSE(fs::exists(pdf));
  EXPECT_NE(r.err.find("standard 9.80665"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("gravity_std_rel"), std::string::npos) << r.err;  // the fix
  EXPECT_NE(r.err.find("--gravity"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("template"), std::string::npos) << r.err;  // only the reason that holds
}

TEST(CertificateGuard, StandardGravityWithItsOwnUncertaintyOrTheSitesGIsCertified) {
  TempDir dir;
  const std::string pdf = dir.file("c.pdf");
  const std::string standard = result(dir, 9.80665, budget(dir, 3e-4, "Test Lab", "SN T-1"));
  Shell r = shell("/usr/bin/python3 " + kScript + " --out " + pdf + " " + standard, dir);
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(fs::exists(pdf));
  fs::remove(pdf);
  const std::string site = result(dir, 9.80123, budget(dir, 2e-5, "Test Lab", "SN T-1"));
  r = shell("/usr/bin/python3 " + kScript + " --out " + pdf + " " + site, dir);
  EXPECT_EQ(r.status, 0) << r.err;
  ASSERT_TRUE(fs::exists(pdf));
  ASSERT_EQ(shell("pdftotext " + pdf + " " + dir.file("c.txt"), dir).status, 0);
  EXPECT_EQ(read_file(dir.file("c.txt")).find("DRAFT"), std::string::npos);
}

TEST(CertificateGuard, TheTemplatesCertificateBlockIsRefused) {
  TempDir dir;
  // The shipped template, g from the site: only the block is wrong.
  const std::string json =
      result(dir, 9.80123,
             accel_intrinsics::test_support::source_dir() + "/config/uncertainty_budget.yaml");
  const std::string pdf = dir.file("c.pdf");
  const Shell r = shell("/usr/bin/python3 " + kScript + " --out " + pdf + " " + json, dir);
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_FALSE(fs::exists(pdf));
  EXPECT_NE(r.err.find("template"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("SN 000123"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("certificate: block"), std::string::npos) << r.err;  // the fix
  EXPECT_EQ(r.err.find("9.80665"), std::string::npos) << r.err;
}

TEST(CertificateGuard, DraftMakesOneWithDraftOnEveryPage) {
  TempDir dir;
  // Both reasons at once: standard g, small g uncertainty, the template's serial.
  const std::string json = result(dir, 9.80665, budget(dir, 0.0, "Test Lab", "SN 000123"));
  const std::string pdf = dir.file("c.pdf");
  const Shell refused = shell("/usr/bin/python3 " + kScript + " --out " + pdf + " " + json, dir);
  EXPECT_EQ(refused.status, 3);
  EXPECT_NE(refused.err.find("9.80665"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("template"), std::string::npos) << refused.err;
  const Shell r = shell("/usr/bin/python3 " + kScript + " --draft --out " + pdf + " " + json, dir);
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_TRUE(fs::exists(pdf));
  ASSERT_EQ(shell("pdfinfo " + pdf + " > " + dir.file("info.txt"), dir).status, 0);
  const std::string info = read_file(dir.file("info.txt"));
  const std::size_t at = info.find("Pages:");
  ASSERT_NE(at, std::string::npos) << info;
  const int pages = std::stoi(info.substr(at + 6));
  ASSERT_GE(pages, 2);
  for (int p = 1; p <= pages; ++p) {
    const std::string txt = dir.file("page" + std::to_string(p) + ".txt");
    ASSERT_EQ(shell("pdftotext -f " + std::to_string(p) + " -l " + std::to_string(p) + " " + pdf +
                        " " + txt,
                    dir)
                  .status,
              0);
    EXPECT_NE(read_file(txt).find("DRAFT"), std::string::npos) << "page " << p;
  }
}

TEST(CertificateGuard, OfflineFitReportPassesTheRefusalOnAndDraftThrough) {
  TempDir dir;
  const std::string pdf = dir.file("c.pdf");
  int status = 0;
  std::string err;
  result(dir, 9.80665, budget(dir, 2e-5, "Test Lab", "SN T-1"), pdf, false, &status, &err);
  EXPECT_NE(status, 0);
  EXPECT_NE(err.find("no certificate"), std::string::npos) << err;
  EXPECT_NE(err.find("--draft"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(pdf));
  result(dir, 9.80665, budget(dir, 2e-5, "Test Lab", "SN T-1"), pdf, true, &status, &err);
  EXPECT_EQ(status, 0) << err;
  EXPECT_TRUE(fs::exists(pdf));
}

}  // namespace
