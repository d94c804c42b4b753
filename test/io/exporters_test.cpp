// Exporters (io/exporters.h): every format read back the way its own tool reads it (each tool's
// documented equation written here independently), applied to the raw dwell means of a second
// simulated run, recovers the true specific force (or its magnitude, for the rotated frames of
// kalibr and imu_tk) within the noise of the means and the uncertainty of the fit; px4 and
// ardupilot: the leftover error they state bounds the error they leave.
#include "accel_intrinsics/io/exporters.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "../support/test_files.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/calibration_forms.h"
#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/core/simulation/simulator.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/result_document.h"

namespace accel_intrinsics {
namespace {

using accel_intrinsics::test_support::read_file;
using accel_intrinsics::test_support::TempDir;

namespace fs = std::filesystem;
using namespace core;

// A triad with 1-3 % scale errors, misalignments of about 1 degree and offsets.
SimulationOptions device_options(std::uint64_t seed) {
  SimulationOptions sim;
  sim.seed = seed;
  sim.truth.S << 1.02, 0.015, -0.02, 0.018, 0.97, 0.012, -0.011, 0.021, 1.03;
  sim.truth.O << 0.12, -0.08, 0.2;
  sim.local_gravity = 9.8123;
  return sim;
}

// The specific force of docs/design.md section 1, written out again here.
Eigen::Vector3d true_force(const DwellRecord& row, double g) {
  const double s = std::sin(row.angle_rad), c = std::cos(row.angle_rad);
  switch (row.phase) {
    case Phase::X: return g * Eigen::Vector3d(0.0, s, c);
    case Phase::Y: return g * Eigen::Vector3d(s, 0.0, c);
    default: return g * Eigen::Vector3d(s, c, 0.0);
  }
}

// The fit of one simulated run and an independent run (another seed) to test it on.
struct Fixture {
  FitResult fit;
  PositionTable test_run;
  double g = 0.0;
};

const Fixture& fixture() {
  static const Fixture f = [] {
    Fixture out;
    SimulationOptions sim = device_options(11);
    out.g = sim.local_gravity;
    FitOptions options;
    options.local_gravity = sim.local_gravity;
    out.fit = fit(simulate_position_table(sim), options);
    SimulationOptions other = device_options(12);
    other.protocol.steps_per_phase = 36;
    out.test_run = simulate_position_table(other);
    return out;
  }();
  return f;
}

// Standard uncertainty of each component of P (R - O) at a dwell: the dwell mean's noise through
// P and the fit's covariance of (S, O) through d(a) = -P (dS a + dO).
Eigen::Vector3d corrected_std(const FitResult& fit, const DwellRecord& row) {
  const Eigen::Matrix3d P = fit.S.inverse();
  const Eigen::Vector3d a = P * (row.mean - fit.O);
  Eigen::Matrix<double, 3, 12> J = Eigen::Matrix<double, 3, 12>::Zero();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) J.col(3 * i + j) = -P.col(i) * a(j);
    J.col(9 + i) = -P.col(i);
  }
  Eigen::Matrix3d cov = J * fit.covariance * J.transpose();
  Eigen::Vector3d se = row.std / std::sqrt(static_cast<double>(row.n));
  cov += P * se.cwiseAbs2().asDiagonal() * P.transpose();
  return cov.diagonal().cwiseSqrt();
}

io::CalibrationToExport to_export() {
  io::CalibrationToExport c = io::calibration_to_export(fixture().fit, "simulated run (seed 11)");
  c.date = "2026-11-23T10:00:00Z";
  return c;
}

std::string write(io::ExportFormat format, const TempDir& dir, io::ExportText* text = nullptr) {
  const std::string path = dir.file(std::string(io::export_format_name(format)) + ".out");
  const io::ExportText t = io::write_export(path, format, to_export());
  if (text) *text = t;
  return path;
}

// Every file states the direction, the g, the date and the source.
void expect_statements(const std::string& text) {
  EXPECT_NE(text.find("direction"), std::string::npos) << text;
  EXPECT_NE(text.find("local gravity g = 9.8123 m/s^2"), std::string::npos) << text;
  EXPECT_NE(text.find("2026-11-23T10:00:00Z"), std::string::npos) << text;
  EXPECT_NE(text.find("simulated run (seed 11)"), std::string::npos) << text;
}

// At every dwell of the test run, `apply(raw)` equals the true force within 5 standard
// uncertainties per component.
template <typename Apply>
void expect_recovers_force(Apply apply) {
  const Fixture& f = fixture();
  int checked = 0;
  for (const DwellRecord& row : f.test_run.rows) {
    const Eigen::Vector3d a = apply(Eigen::Vector3d(row.mean));
    const Eigen::Vector3d truth = true_force(row, f.g);
    const Eigen::Vector3d tol = 5.0 * corrected_std(f.fit, row);
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(a(i), truth(i), tol(i))
          << "phase " << phase_name(row.phase) << " step " << row.step << " component " << i;
    }
    ++checked;
  }
  EXPECT_EQ(checked, 108);
}

// For the rotated frames: |apply(raw)| equals g within 5 uncertainties of the magnitude.
template <typename Apply>
void expect_recovers_magnitude(Apply apply) {
  const Fixture& f = fixture();
  for (const DwellRecord& row : f.test_run.rows) {
    const double magnitude = apply(Eigen::Vector3d(row.mean)).norm();
    // The magnitude's uncertainty is the component uncertainty along the force direction.
    const Eigen::Vector3d u = true_force(row, f.g).normalized();
    const double tol = 5.0 * corrected_std(f.fit, row).cwiseAbs().dot(u.cwiseAbs());
    EXPECT_NEAR(magnitude, f.g, tol) << "phase " << phase_name(row.phase) << " step " << row.step;
  }
}

// ---- imu_calib: dpkoch/imu_calib AccelCalib::loadCalib (SM 9 row-major, bias 3), applyCalib:
// corrected = SM * raw - bias ------------------------------------------------------------------
TEST(Exporters, ImuCalibRoundTrip) {
  TempDir dir;
  const std::string path = write(io::ExportFormat::ImuCalib, dir);
  expect_statements(read_file(path));
  const YAML::Node node = YAML::LoadFile(path);
  ASSERT_TRUE(node["SM"].IsSequence());
  ASSERT_EQ(node["SM"].size(), 9u);
  ASSERT_EQ(node["bias"].size(), 3u);
  Eigen::Matrix3d SM;
  Eigen::Vector3d bias;
  for (int i = 0; i < 9; ++i) SM(i / 3, i % 3) = node["SM"][i].as<double>();
  for (int i = 0; i < 3; ++i) bias(i) = node["bias"][i].as<double>();
  expect_recovers_force(
      [&](const Eigen::Vector3d& raw) { return Eigen::Vector3d(SM * raw - bias); });
}

// ---- imucal: FerrarisCalibrationInfo._calibrate_acc: inv(R_a) @ inv(K_a) @ (acc - b_a); the
// loader checks _format_version 2.0.0 and cal_type; _validate_units compares from_acc_unit ------
TEST(Exporters, ImucalRoundTrip) {
  TempDir dir;
  const std::string path = write(io::ExportFormat::Imucal, dir);
  const nlohmann::json j = nlohmann::json::parse(read_file(path));
  expect_statements(j.at("comment").get<std::string>());
  EXPECT_EQ(j.at("_format_version"), "2.0.0");
  EXPECT_EQ(j.at("cal_type"), "Ferraris");
  EXPECT_EQ(j.at("from_acc_unit"), "m/s^2");
  for (const char* key : {"K_g", "R_g", "K_ga", "b_g"}) EXPECT_TRUE(j.contains(key)) << key;
  auto matrix = [&](const char* key) {
    Eigen::Matrix3d m;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m(r, c) = j.at(key).at(r).at(c).get<double>();
    return m;
  };
  const Eigen::Matrix3d K_a = matrix("K_a"), R_a = matrix("R_a");
  Eigen::Vector3d b_a;
  for (int i = 0; i < 3; ++i) b_a(i) = j.at("b_a").at(i).get<double>();
  EXPECT_TRUE(K_a.isDiagonal());
  for (int r = 0; r < 3; ++r) EXPECT_NEAR(R_a.row(r).norm(), 1.0, 1e-12);
  const Eigen::Matrix3d acc_mat = R_a.inverse() * K_a.inverse();
  expect_recovers_force(
      [&](const Eigen::Vector3d& raw) { return Eigen::Vector3d(acc_mat * (raw - b_a)); });
}

// ---- kalibr: IccScaledMisalignedImu: measured = M * a_i + b, M lower triangular (its design
// variable pattern [[1,0,0],[1,1,0],[1,1,1]]), written as imu0.accelerometers.M --------------
TEST(Exporters, KalibrRoundTrip) {
  TempDir dir;
  const std::string path = write(io::ExportFormat::Kalibr, dir);
  expect_statements(read_file(path));
  const YAML::Node imu0 = YAML::LoadFile(path)["imu0"];
  ASSERT_TRUE(imu0);
  EXPECT_EQ(imu0["model"].as<std::string>(), "scale-misalignment");
  Eigen::Matrix3d M;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) M(r, c) = imu0["accelerometers"]["M"][r][c].as<double>();
  EXPECT_EQ(M(0, 1), 0.0);
  EXPECT_EQ(M(0, 2), 0.0);
  EXPECT_EQ(M(1, 2), 0.0);
  // kalibr estimates its own bias; the file states ours in a comment, the test takes the fit's.
  const Eigen::Vector3d b = fixture().fit.O;
  expect_recovers_magnitude(
      [&](const Eigen::Vector3d& raw) { return Eigen::Vector3d(M.inverse() * (raw - b)); });
}

// ---- imu_tk: CalibratedTriad_::load reads 9 (T, row-major), 9 (K), 3 (B) numbers with >>;
// unbiasNormalize: T * K * (raw - B) ------------------------------------------------------------
TEST(Exporters, ImuTkRoundTrip) {
  TempDir dir;
  const std::string path = write(io::ExportFormat::ImuTk, dir);
  expect_statements(read_file(path));
  std::ifstream file(path);
  double v[21];
  for (double& x : v) file >> x;
  ASSERT_TRUE(file.good()) << "the 21 numbers must come first";
  Eigen::Matrix3d T, K;
  for (int i = 0; i < 9; ++i) T(i / 3, i % 3) = v[i];
  for (int i = 0; i < 9; ++i) K(i / 3, i % 3) = v[9 + i];
  const Eigen::Vector3d B(v[18], v[19], v[20]);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(T(i, i), 1.0);
  EXPECT_EQ(T(1, 0), 0.0);
  EXPECT_EQ(T(2, 0), 0.0);
  EXPECT_EQ(T(2, 1), 0.0);
  EXPECT_TRUE(K.isDiagonal());
  expect_recovers_magnitude(
      [&](const Eigen::Vector3d& raw) { return Eigen::Vector3d(T * K * (raw - B)); });
}

// The leftover error the file states (the number after "at 1 g: ").
double stated_leftover(const std::string& text) {
  const std::string key = "largest error left over all orientations at 1 g: ";
  const std::size_t at = text.find(key);
  if (at == std::string::npos) return NAN;
  return std::strtod(text.c_str() + at + key.size(), nullptr);
}

// px4 / ardupilot: the stated leftover bounds |a - f| at every dwell (plus the noise allowance),
// and is not loose: the dwells of the three phases come within 30 % of it.
template <typename Apply>
void expect_bounded(Apply apply, double stated) {
  const Fixture& f = fixture();
  double largest = 0.0;
  for (const DwellRecord& row : f.test_run.rows) {
    const Eigen::Vector3d err = apply(Eigen::Vector3d(row.mean)) - true_force(row, f.g);
    const double allowance = 5.0 * corrected_std(f.fit, row).norm();
    EXPECT_LE(err.norm(), stated + allowance)
        << "phase " << phase_name(row.phase) << " step " << row.step;
    largest = std::max(largest, err.norm());
  }
  EXPECT_GT(largest, 0.7 * stated);
}

// ---- px4: calibration::Accelerometer::Correct: (data - offset).emult(scale), parameters
// CAL_ACC0_{X,Y,Z}{OFF,SCALE}; QGC file lines "vehicle component name value type" -------------
TEST(Exporters, Px4LeftoverBoundsError) {
  TempDir dir;
  io::ExportText t;
  const std::string path = write(io::ExportFormat::Px4, dir, &t);
  const std::string text = read_file(path);
  expect_statements(text);
  std::map<std::string, double> params;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    int vehicle = 0, component = 0, type = 0;
    std::string name;
    double value = 0.0;
    ASSERT_TRUE(static_cast<bool>(fields >> vehicle >> component >> name >> value >> type)) << line;
    EXPECT_EQ(type, 9) << "MAV_PARAM_TYPE_REAL32";
    params[name] = value;
  }
  ASSERT_EQ(params.size(), 6u);
  const Eigen::Vector3d off(params.at("CAL_ACC0_XOFF"), params.at("CAL_ACC0_YOFF"),
                            params.at("CAL_ACC0_ZOFF"));
  const Eigen::Vector3d scale(params.at("CAL_ACC0_XSCALE"), params.at("CAL_ACC0_YSCALE"),
                              params.at("CAL_ACC0_ZSCALE"));
  const double stated = stated_leftover(text);
  EXPECT_NEAR(stated, t.leftover_error, 1e-3 * t.leftover_error);
  EXPECT_NE(t.notice.find("largest error"), std::string::npos);
  expect_bounded(
      [&](const Eigen::Vector3d& raw) { return Eigen::Vector3d((raw - off).cwiseProduct(scale)); },
      stated);
}

// ---- ardupilot: AP_InertialSensor_Backend::_rotate_and_correct_accel: accel -= offset, then
// per-axis *= scale; Mission Planner lines NAME,VALUE -----------------------------------------
TEST(Exporters, ArdupilotLeftoverBoundsError) {
  TempDir dir;
  io::ExportText t;
  const std::string path = write(io::ExportFormat::Ardupilot, dir, &t);
  const std::string text = read_file(path);
  expect_statements(text);
  std::map<std::string, double> params;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (line.empty() || line[0] == '#') continue;
    const std::size_t comma = line.find(',');
    ASSERT_NE(comma, std::string::npos) << line;
    params[line.substr(0, comma)] = std::stod(line.substr(comma + 1));
  }
  ASSERT_EQ(params.size(), 6u);
  const Eigen::Vector3d offs(params.at("INS_ACCOFFS_X"), params.at("INS_ACCOFFS_Y"),
                             params.at("INS_ACCOFFS_Z"));
  const Eigen::Vector3d scal(params.at("INS_ACCSCAL_X"), params.at("INS_ACCSCAL_Y"),
                             params.at("INS_ACCSCAL_Z"));
  const double stated = stated_leftover(text);
  EXPECT_GT(stated, 0.1);  // this device's couplings are large enough to matter
  expect_bounded(
      [&](const Eigen::Vector3d& raw) {
        Eigen::Vector3d a = raw - offs;
        return Eigen::Vector3d(a.cwiseProduct(scal));
      },
      stated);
}

// px4 and ardupilot SCALE from the diagonal written out here: SCALE_i = S_ii / |s_i|^2 with s_i
// the i-th row of the fitted S (the least-squares per-axis gain: at the three axis-aligned
// orientations a = g e_j the outputs are raw = g S e_j + O, and SCALE_i minimizes the sum over j
// of (SCALE_i (raw_i - O_i) - g delta_ij)^2). Checked two ways: the numbers in the files equal
// the formula, and at the axis-aligned orientations no other gain does better (1/S_ii or 1/|s_i|
// moves the gain by 3e-4 to 7e-4 relative for this device; the check sees 1e-5).
TEST(Exporters, DiagonalScaleIsTheLeastSquaresGainAtTheAxisAlignedOrientations) {
  const Eigen::Matrix3d S = fixture().fit.S;
  const Eigen::Vector3d O = fixture().fit.O;
  const double g = fixture().g;
  Eigen::Vector3d expected;
  for (int i = 0; i < 3; ++i) {
    const double row2 = S(i, 0) * S(i, 0) + S(i, 1) * S(i, 1) + S(i, 2) * S(i, 2);
    expected(i) = S(i, i) / row2;
  }
  TempDir dir;
  std::map<std::string, double> px4, ardu;
  {
    std::istringstream lines(read_file(write(io::ExportFormat::Px4, dir)));
    for (std::string line; std::getline(lines, line);) {
      if (line.empty() || line[0] == '#') continue;
      std::istringstream fields(line);
      int vehicle = 0, component = 0;
      std::string name;
      double value = 0.0;
      fields >> vehicle >> component >> name >> value;
      px4[name] = value;
    }
    std::istringstream alines(read_file(write(io::ExportFormat::Ardupilot, dir)));
    for (std::string line; std::getline(alines, line);) {
      if (line.empty() || line[0] == '#') continue;
      const std::size_t comma = line.find(',');
      ardu[line.substr(0, comma)] = std::stod(line.substr(comma + 1));
    }
  }
  const char* axes[3] = {"X", "Y", "Z"};
  for (int i = 0; i < 3; ++i) {
    const double p = px4.at(std::string("CAL_ACC0_") + axes[i] + "SCALE");
    const double a = ardu.at(std::string("INS_ACCSCAL_") + axes[i]);
    EXPECT_NEAR(p, expected(i), 1e-14 * expected(i)) << axes[i];
    EXPECT_NEAR(a, expected(i), 1e-14 * expected(i)) << axes[i];
    EXPECT_NEAR(px4.at(std::string("CAL_ACC0_") + axes[i] + "OFF"), O(i), 1e-15) << axes[i];
    EXPECT_NEAR(ardu.at(std::string("INS_ACCOFFS_") + axes[i]), O(i), 1e-15) << axes[i];
    // The summed squared error of axis i over the six axis-aligned orientations +-g e_j.
    auto error = [&](double gain) {
      double sum = 0.0;
      for (int j = 0; j < 3; ++j) {
        for (double sign : {1.0, -1.0}) {
          const Eigen::Vector3d raw = S * (sign * g * Eigen::Vector3d::Unit(j)) + O;
          const double e = gain * (raw(i) - O(i)) - (i == j ? sign * g : 0.0);
          sum += e * e;
        }
      }
      return sum;
    };
    for (double step : {1e-5, -1e-5}) {
      EXPECT_LT(error(p), error(p * (1.0 + step))) << axes[i] << " gain moved by " << step;
    }
    // The leftover at axis i's own orientation is the coupling the format drops: never larger
    // than the stated worst case.
    const Eigen::Vector3d raw = S * (g * Eigen::Vector3d::Unit(i)) + O;
    Eigen::Vector3d corrected;
    for (int k = 0; k < 3; ++k)
      corrected(k) = px4.at(std::string("CAL_ACC0_") + axes[k] + "SCALE") * (raw(k) - O(k));
    EXPECT_LE((corrected - g * Eigen::Vector3d::Unit(i)).norm(),
              diagonal_form(S).worst_error_per_g * g * (1.0 + 1e-12));
  }
}

// The stated bound is the worst case over all orientations: a dense sweep of the sphere with
// the fitted S never exceeds it and comes within 1 % of it.
TEST(Exporters, DiagonalBoundIsWorstOverSphere) {
  const Eigen::Matrix3d S = fixture().fit.S;
  const DiagonalForm d = diagonal_form(S);
  const Eigen::Matrix3d E = d.scale.asDiagonal() * S - Eigen::Matrix3d::Identity();
  double worst = 0.0;
  for (int i = 0; i <= 180; ++i) {
    for (int k = 0; k < 360; ++k) {
      const double th = kPi * i / 180.0, ph = 2.0 * kPi * k / 360.0;
      const Eigen::Vector3d a(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph),
                              std::cos(th));
      worst = std::max(worst, (E * a).norm());
    }
  }
  EXPECT_LE(worst, d.worst_error_per_g * (1.0 + 1e-12));
  EXPECT_GT(worst, 0.99 * d.worst_error_per_g);
}

// The triangular forms reproduce S and P exactly.
TEST(Exporters, TriangularFormsReproduceTheMatrix) {
  const Eigen::Matrix3d S = fixture().fit.S;
  const LowerTriangularForm l = lower_triangular_form(S);
  EXPECT_TRUE((l.M * l.Q).isApprox(S, 1e-12));
  EXPECT_TRUE((l.Q * l.Q.transpose()).isIdentity(1e-12));
  EXPECT_TRUE(l.M.isLowerTriangular(1e-15));
  const UpperTriangularInverseForm u = upper_triangular_inverse_form(S);
  EXPECT_TRUE((u.T * u.K).isApprox(u.Q * S.inverse(), 1e-12));
  EXPECT_TRUE(u.T.isUpperTriangular(1e-15));
  EXPECT_THROW(lower_triangular_form(Eigen::Matrix3d::Zero()), std::invalid_argument);
}

// A result file (the node's YAML form) goes through read_result_file into an export.
TEST(Exporters, FromStoredResultFile) {
  TempDir dir;
  CalibrationReport report;
  report.base_fit = report.certificate = fixture().fit;
  report.noise = dwell_noise(simulate_position_table(device_options(11)));
  ASSERT_TRUE(report.noise.has_value());
  const std::string result = dir.file("intrinsics.yaml");
  io::write_result_yaml(result, report, io::ResultContext{});
  const io::StoredResult stored = io::read_result_file(result);
  const io::CalibrationToExport c = io::calibration_to_export(stored, result);
  const io::ExportText t = io::export_text(io::ExportFormat::ImuCalib, c);
  EXPECT_NE(t.text.find(result), std::string::npos);
  EXPECT_TRUE(c.S.isApprox(fixture().fit.S, 1e-12));
  // The dwells' white noise travels with the result into kalibr's noise key (the largest axis).
  EXPECT_TRUE(stored.noise_density.isApprox(report.noise->density, 1e-12));
  EXPECT_NEAR(stored.sample_rate_hz, report.noise->rate_hz, 1e-9);
  const YAML::Node imu0 = YAML::Load(io::export_text(io::ExportFormat::Kalibr, c).text)["imu0"];
  EXPECT_DOUBLE_EQ(imu0["accelerometer_noise_density"].as<double>(),
                   report.noise->density.maxCoeff());
  EXPECT_NEAR(imu0["update_rate"].as<double>(), report.noise->rate_hz, 1e-9);
}

// A result that fails the quality gate is refused in every format, from a report and from the
// stored file alike, with the gate's reasons in the message.
TEST(Exporters, RefuseAResultThatFailsTheQualityGate) {
  TempDir dir;
  CalibrationReport report;
  report.base_fit = report.certificate = fixture().fit;
  report.quality = Quality{false, {"reduced chi-square 812 is far above 1"}};
  const std::string result = dir.file("intrinsics.yaml");
  io::write_result_yaml(result, report, io::ResultContext{});
  const io::StoredResult stored = io::read_result_file(result);
  EXPECT_FALSE(stored.quality_pass);
  for (const io::CalibrationToExport& c :
       {io::calibration_to_export(report, "report"), io::calibration_to_export(stored, result)}) {
    for (io::ExportFormat format :
         {io::ExportFormat::ImuCalib, io::ExportFormat::Imucal, io::ExportFormat::Kalibr,
          io::ExportFormat::ImuTk, io::ExportFormat::Px4, io::ExportFormat::Ardupilot}) {
      try {
        io::export_text(format, c);
        ADD_FAILURE() << io::export_format_name(format) << " exported a failing result";
      } catch (const io::IoError& e) {
        EXPECT_NE(std::string(e.what()).find(
                      "fails the quality gate (reduced chi-square 812 is far above 1)"),
                  std::string::npos)
            << e.what();
      }
    }
  }
  // The same result once it passes (the gate's verdict is the only difference) exports.
  report.quality = Quality{};
  EXPECT_NO_THROW(
      io::export_text(io::ExportFormat::ImuCalib, io::calibration_to_export(report, "r")));
}

TEST(Exporters, BadInputIsOneClearLine) {
  try {
    io::parse_export_format("matlab");
    FAIL();
  } catch (const io::IoError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("unknown export format 'matlab'"), std::string::npos) << m;
    EXPECT_NE(m.find("imu_calib, imucal, kalibr, imu_tk, px4, ardupilot"), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos);
  }
  EXPECT_THROW(io::parse_export_spec("px4"), io::IoError);
  EXPECT_THROW(io::parse_export_spec("=file"), io::IoError);
  const auto spec = io::parse_export_spec("kalibr=/tmp/x=y.yaml");
  EXPECT_EQ(spec.first, io::ExportFormat::Kalibr);
  EXPECT_EQ(spec.second, "/tmp/x=y.yaml");
  io::CalibrationToExport c = to_export();
  c.S = Eigen::Matrix3d::Zero();
  EXPECT_THROW(io::export_text(io::ExportFormat::Kalibr, c), io::IoError);
  c = to_export();
  c.local_gravity = NAN;
  EXPECT_THROW(io::export_text(io::ExportFormat::Px4, c), io::IoError);
}

}  // namespace
}  // namespace accel_intrinsics
