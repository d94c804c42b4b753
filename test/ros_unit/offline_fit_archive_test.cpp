// offline_fit --archive (docs/design.md section 13), in process: the result goes into a SQLite lab
// archive through scripts/archive, once however often it is fitted, and `history` reads it back;
// an archive that cannot be reached is a warning, the result file stays.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "../support/source_dir.h"
#include "accel_intrinsics/ros/offline_fit.h"

namespace ai = accel_intrinsics;

namespace {

const std::string kSource = accel_intrinsics::test_support::source_dir();

struct ArchiveDir {
  ArchiveDir() {
    char templ[] = "/tmp/offline_fit_archive_test_XXXXXX";
    path = ::mkdtemp(templ);
  }
  ~ArchiveDir() {
    if (std::getenv("KEEP_TEST_FILES") == nullptr) std::system(("rm -rf '" + path + "'").c_str());
  }
  std::string file(const std::string& name) const { return path + "/" + name; }
  std::string url() const { return "sqlite:///" + file("archive.db"); }
  std::string path;
};

ai::OfflineFitArguments six_position_args(const ArchiveDir& dir) {
  ai::OfflineFitArguments args;
  args.csv = kSource + "/docs/examples/six_position.csv";
  args.output_unit = "counts";
  args.budget = kSource + "/config/uncertainty_budget.yaml";  // certificate serial "SN 000123"
  args.json_out = dir.file("result.json");
  args.archive = dir.url();
  args.rig = "bench_1";
  return args;
}

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// scripts/history SERIAL --json: the device's history document.
nlohmann::json history(const ArchiveDir& dir, const std::string& serial) {
  const std::string out = dir.file("history.json");
  const std::string command = "/usr/bin/python3 " + kSource + "/scripts/history '" + serial +
                              "' --archive " + dir.url() + " --json " + out + " > /dev/null";
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
  return read_json(out);
}

}  // namespace

TEST(OfflineFitArchive, ResultGoesInOnceAndHistoryReadsIt) {
  ArchiveDir dir;
  const ai::OfflineFitArguments args = six_position_args(dir);
  for (int run = 0; run < 2; ++run) {
    std::ostringstream out, err;
    ASSERT_EQ(ai::run_offline_fit(args, out, err), ai::kOfflineFitOk) << err.str();
    EXPECT_EQ(err.str().find("not archived"), std::string::npos) << err.str();
  }
  const nlohmann::json result = read_json(args.json_out);
  const nlohmann::json doc = history(dir, "SN 000123");
  ASSERT_EQ(doc["records"].size(), 1u);  // the same input and result: one record
  const nlohmann::json& record = doc["records"][0];
  EXPECT_EQ(record["rig"], "bench_1");
  EXPECT_EQ(record["method"], "positions");  // known orientations
  EXPECT_DOUBLE_EQ(record["values"]["responsivity_v"].get<double>(),
                   result["responsivity"]["v"].get<double>());
  EXPECT_DOUBLE_EQ(record["expanded"]["angle_wu"].get<double>(),
                   result["uncertainty_budget"]["expanded"]["angles_deg"]["wu"].get<double>());
}

TEST(OfflineFitArchive, UnreachableArchiveIsAWarning) {
  ArchiveDir dir;
  ai::OfflineFitArguments args = six_position_args(dir);
  args.archive = "postgresql://lab:pw-not-shown@127.0.0.1:1/archive";
  std::ostringstream out, err;
  EXPECT_EQ(ai::run_offline_fit(args, out, err), ai::kOfflineFitOk);
  EXPECT_NE(err.str().find("offline_fit: warning: --archive: the result was not archived"),
            std::string::npos)
      << err.str();
  EXPECT_EQ(err.str().find("pw-not-shown"), std::string::npos);
  EXPECT_TRUE(std::ifstream(args.json_out).good());
}

TEST(OfflineFitArchive, HandTumbleIsArchivedAsTumble) {
  // imu_tk's Xsens session (--samples, raw counts) and no budget file: the serial comes from
  // --device, the expanded uncertainties are 2 x the standard ones.
  ArchiveDir dir;
  ai::OfflineFitArguments args;
  args.samples = kSource + "/test/data/imu_tk_xsens/xsens_acc.mat";
  args.output_unit = "counts";
  args.json_out = dir.file("tumble.json");
  args.archive = dir.url();
  args.device = "XSENS-1";
  std::ostringstream out, err;
  ASSERT_EQ(ai::run_offline_fit(args, out, err), ai::kOfflineFitOk) << err.str();
  const nlohmann::json result = read_json(args.json_out);
  const nlohmann::json doc = history(dir, "XSENS-1");
  ASSERT_EQ(doc["records"].size(), 1u);
  EXPECT_EQ(doc["records"][0]["method"], "tumble");
  EXPECT_DOUBLE_EQ(doc["records"][0]["expanded"]["offset_u"].get<double>(),
                   2.0 * result["offset_std"]["u"].get<double>());
}

TEST(OfflineFitArchive, CommandLine) {
  ai::OfflineFitArguments args;
  int status = -1;
  std::ostringstream out, err;
  ASSERT_TRUE(ai::parse_offline_fit_arguments(
      {"--csv", "t.csv", "--archive", "sqlite:///a.db", "--device", "SN-1", "--rig", "A"}, &args,
      &status, out, err))
      << err.str();
  EXPECT_EQ(args.archive, "sqlite:///a.db");
  EXPECT_EQ(args.device, "SN-1");
  EXPECT_EQ(args.rig, "A");
  // --device and --rig name an archive record: refused without --archive
  ai::OfflineFitArguments no_archive;
  EXPECT_FALSE(ai::parse_offline_fit_arguments({"--csv", "t.csv", "--rig", "A"}, &no_archive,
                                               &status, out, err));
  EXPECT_EQ(status, ai::kOfflineFitBadCommandLine);
  EXPECT_NE(err.str().find("--rig requires --archive"), std::string::npos) << err.str();
}
