// Type-B budget by Monte Carlo through the one model; see uncertainty_budget.h for the method.
#include "accel_intrinsics/core/analysis/uncertainty_budget.h"

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/fit/tumble.h"
#include "accel_intrinsics/core/model/constants.h"
#include "accel_intrinsics/core/model/intrinsics.h"

namespace accel_intrinsics {
namespace core {

const char* const kBudgetSourceNames[6] = {"gravity_std_rel",      "angle_random_std_deg",
                                           "angle_offset_std_deg", "angle_scale_std",
                                           "axis_tilt_std_deg",    "mount_misalignment_std_deg"};

namespace {

using Vector12d = Eigen::Matrix<double, 12, 1>;

enum Source { kGravity = 0, kAngleRandom, kAngleOffset, kAngleScale, kAxisTilt, kMount };
constexpr int kNumSources = 6;

double source_input(const BudgetSpec& spec, int source) {
  switch (source) {
    case kGravity: return spec.gravity_std_rel;
    case kAngleRandom: return spec.angle_random_std_deg;
    case kAngleOffset: return spec.angle_offset_std_deg;
    case kAngleScale: return spec.angle_scale_std;
    case kAxisTilt: return spec.axis_tilt_std_deg;
    case kMount: return spec.mount_misalignment_std_deg;
  }
  return 0.0;
}

// The standard uncertainty in model units (radians for the angles).
double source_sigma(const BudgetSpec& spec, int source) {
  const double x = source_input(spec, source);
  return source == kGravity || source == kAngleScale ? x : deg_to_rad(x);
}

std::string number_text(double x) {
  std::ostringstream out;
  out << x;
  return out.str();
}

// The two axes other than p, in increasing order.
void other_axes(int p, int* a, int* b) {
  *a = p == 0 ? 1 : 0;
  *b = p == 2 ? 1 : 2;
}

// Independent inputs of a source: how many, and how to set input i to `value`.
int source_inputs(int source, std::size_t rows) {
  switch (source) {
    case kGravity: return 1;
    case kAngleRandom: return static_cast<int>(rows);
    case kMount: return 6;
    default: return 3;
  }
}

void set_input(int source, int i, double value, RigErrors* e, std::size_t rows) {
  switch (source) {
    case kGravity: e->gravity_rel = value; break;
    case kAngleRandom:
      if (e->row_angle_rad.size() != rows) e->row_angle_rad.assign(rows, 0.0);
      e->row_angle_rad[static_cast<std::size_t>(i)] = value;
      break;
    case kAngleOffset: e->angle_offset_rad(i) = value; break;
    case kAngleScale: e->angle_scale(i) = value; break;
    case kAxisTilt: e->axis_tilt_rad(i) = value; break;
    case kMount: {
      const int p = i / 2;
      int a = 0, b = 0;
      other_axes(p, &a, &b);
      e->mount_rotation(i % 2 == 0 ? a : b, p) = value;
      break;
    }
  }
}

Eigen::Matrix<double, 9, 1> as_vector(const IntrinsicValues& v) {
  Eigen::Matrix<double, 9, 1> out;
  out << v.responsivity, v.angles_rad, v.offset;
  return out;
}

IntrinsicValues from_vector(const Eigen::Matrix<double, 9, 1>& x) {
  IntrinsicValues v;
  v.responsivity = x.segment<3>(0);
  v.angles_rad = x.segment<3>(3);
  v.offset = x.segment<3>(6);
  return v;
}

IntrinsicValues type_a(const FitResult& fit) {
  IntrinsicValues v;
  v.responsivity = fit.intrinsics.responsivity_std;
  v.angles_rad = fit.intrinsics.angles_std_rad;
  v.offset = fit.O_std;
  return v;
}

// Sources combined in quadrature, and expanded.
void combine(UncertaintyBudget* budget) {
  Eigen::Matrix<double, 9, 1> sum = Eigen::Matrix<double, 9, 1>::Zero();
  for (const BudgetSource& s : budget->sources) sum += as_vector(s.std).cwiseAbs2();
  budget->combined = from_vector(sum.cwiseSqrt());
  budget->expanded = from_vector(budget->coverage_factor * sum.cwiseSqrt());
}

UncertaintyBudget start_budget(const BudgetRefit& refit, const BudgetSpec& spec,
                               const char* method) {
  UncertaintyBudget budget;
  budget.spec = spec;
  budget.method = std::string(method) + "; refit: " + refit.fit().model_label() +
                  (!refit.closed_form()    ? " (linearized at the fitted device)"
                   : refit.uses_operator() ? " (closed form, linear in the dwell means)"
                                           : " (closed form, core::fit per draw)");
  BudgetSource a;
  a.name = "type_a";
  a.input = std::numeric_limits<double>::quiet_NaN();
  a.std = type_a(refit.fit());
  budget.sources.push_back(a);
  return budget;
}

// g: deterministic two-point evaluation (see the header).
BudgetSource gravity_source(const BudgetRefit& refit, const BudgetSpec& spec) {
  BudgetSource s;
  s.name = kBudgetSourceNames[kGravity];
  s.input = spec.gravity_std_rel;
  RigErrors up, down;
  up.gravity_rel = spec.gravity_std_rel;
  down.gravity_rel = -spec.gravity_std_rel;
  s.std = from_vector(
      0.5 * (as_vector(refit.parameters(up)) - as_vector(refit.parameters(down))).cwiseAbs());
  return s;
}

}  // namespace

void validate(const BudgetSpec& spec) {
  auto check = [](const char* key, double value, double max, const char* unit) {
    if (!std::isfinite(value) || value < 0.0 || value > max)
      throw std::invalid_argument(
          std::string("uncertainty budget: ") + key + " is " + number_text(value) +
          "; it must be a standard uncertainty in [0, " + number_text(max) + "]" + unit);
  };
  check("gravity_std_rel", spec.gravity_std_rel, 0.01, " (relative)");
  check("angle_random_std_deg", spec.angle_random_std_deg, 10.0, " deg");
  check("angle_offset_std_deg", spec.angle_offset_std_deg, 10.0, " deg");
  check("angle_scale_std", spec.angle_scale_std, 0.1, " (relative)");
  check("axis_tilt_std_deg", spec.axis_tilt_std_deg, 10.0, " deg");
  check("mount_misalignment_std_deg", spec.mount_misalignment_std_deg, 10.0, " deg");
  if (spec.samples < 10 || spec.samples > 10000000)
    throw std::invalid_argument("uncertainty budget: samples is " + std::to_string(spec.samples) +
                                "; it must be in [10, 10000000] draws per source");
}

IntrinsicValues intrinsic_values(const Vector12d& theta) {
  Eigen::Matrix3d S;
  for (int k = 0; k < 9; ++k) S(k / 3, k % 3) = theta(k);
  const Intrinsics in = intrinsics_from_vectors(S);
  IntrinsicValues v;
  v.responsivity = in.responsivity;
  v.angles_rad = in.angles_rad;
  v.offset = theta.tail<3>();
  return v;
}

namespace {

Vector12d theta_of_fit(const FitResult& r) {
  Vector12d theta;
  for (int k = 0; k < 9; ++k) theta(k) = r.S(k / 3, k % 3);
  theta.tail<3>() = r.O;
  return theta;
}

}  // namespace

BudgetRefit::BudgetRefit(const PositionTable& table, const FitResult& fit, std::size_t draws)
    : fit_(fit), base_(table) {
  geoms_ = dwell_geometries(table);
  if (geoms_.size() != table.rows.size())
    throw FitError("uncertainty budget: the position table's geometry does not match its rows");
  closed_form_ = fit.effects.empty();
  if (fit.model == FitModel::Tumble) {
    // A hand tumble: each rest where the fit puts it (its orientation is not known otherwise);
    // the tumble fit is not linear in the means.
    const std::vector<Eigen::Vector3d> ups = rest_up_directions(fit, table);
    for (std::size_t i = 0; i < geoms_.size(); ++i) {
      geoms_[i].has_direction = true;
      geoms_[i].direction = ups[i];
    }
    closed_form_ = false;
  }
  y0_ = simulate(RigErrors{});

  // The run's fit, on the noise-free outputs of the fitted device (weights: the run's std).
  options_.model = fit.model;
  options_.local_gravity = fit.local_gravity;
  options_.effects = fit.effects;  // fitted values: the starting guess
  const std::size_t n = table.rows.size();
  auto theta_of = [&](const Eigen::VectorXd& y) {
    for (std::size_t i = 0; i < n; ++i) base_.rows[i].mean = y.segment<3>(3 * i);
    return theta_of_fit(core::fit(base_, options_));
  };
  theta0_ = theta_of(y0_);
  use_operator_ = !closed_form_ || draws == 0 || draws >= 3 * n + 1;
  if (!use_operator_) return;
  // Differences of the refit with respect to each dwell mean: forward for the closed-form fits
  // (linear: exact), central for the linearized Ceres fit. A step of 1e-3 g keeps round-off near
  // 1e-13 of the parameters for the linear fits.
  const double h = 1e-3 * fit.local_gravity;
  L_.resize(12, static_cast<Eigen::Index>(3 * n));
  Eigen::VectorXd y = y0_;
  for (Eigen::Index j = 0; j < y.size(); ++j) {
    y(j) = y0_(j) + h;
    const Vector12d plus = theta_of(y);
    if (closed_form_) {
      L_.col(j) = (plus - theta0_) / h;
    } else {
      y(j) = y0_(j) - h;
      L_.col(j) = (plus - theta_of(y)) / (2.0 * h);
    }
    y(j) = y0_(j);
  }
}

Eigen::VectorXd BudgetRefit::simulate(const RigErrors& e) const {
  const std::size_t n = geoms_.size();
  // The device's own terms, then one term per phase for each gimbal source.
  std::vector<Effect> terms = fit_.effects;
  std::vector<double> values;
  for (const Effect& t : terms) values.push_back(t.value);
  for (int p = 0; p < 3; ++p) {
    terms.push_back(Effect{EffectKind::AngleScale, p, 0.0});
    values.push_back(e.angle_scale(p));
    terms.push_back(Effect{EffectKind::AngleOffset, p, 0.0});
    values.push_back(e.angle_offset_rad(p));
    terms.push_back(Effect{EffectKind::AxisTilt, p, 0.0});
    values.push_back(e.axis_tilt_rad(p));
  }
  // S R_p^T per phase: the mounting rotated by R_p (see the header).
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> S_phase[3];
  for (int p = 0; p < 3; ++p) {
    const Eigen::Vector3d r = e.mount_rotation.col(p);
    const double angle = r.norm();
    const Eigen::Matrix3d R = angle > 0.0 ? Eigen::AngleAxisd(angle, r / angle).toRotationMatrix()
                                          : Eigen::Matrix3d::Identity();
    S_phase[p] = fit_.S * R.transpose();
  }
  const double g = fit_.local_gravity * (1.0 + e.gravity_rel);
  const bool per_row = e.row_angle_rad.size() == n;
  Eigen::VectorXd y(static_cast<Eigen::Index>(3 * n));
  for (std::size_t i = 0; i < n; ++i) {
    DwellGeometry geom = geoms_[i];
    if (per_row) geom.angle_rad += e.row_angle_rad[i];
    const int p = index(geom.phase);
    y.segment<3>(static_cast<Eigen::Index>(3 * i)) =
        predict_outputs(S_phase[p].data(), fit_.O.data(), terms, values.data(), geom, g);
  }
  return y;
}

Vector12d BudgetRefit::refit(const Eigen::VectorXd& outputs) const {
  if (use_operator_) return theta0_ + L_ * (outputs - y0_);
  PositionTable drawn = base_;
  for (std::size_t i = 0; i < drawn.rows.size(); ++i)
    drawn.rows[i].mean = outputs.segment<3>(static_cast<Eigen::Index>(3 * i));
  return theta_of_fit(core::fit(drawn, options_));
}

IntrinsicValues BudgetRefit::parameters(const RigErrors& errors) const {
  return intrinsic_values(refit(simulate(errors)));
}

UncertaintyBudget uncertainty_budget(const PositionTable& table, const FitResult& fit,
                                     const BudgetSpec& spec) {
  validate(spec);
  std::size_t draws = 0;
  for (int source = 0; source < kNumSources; ++source)
    if (source != kGravity && source_input(spec, source) > 0.0)
      draws += static_cast<std::size_t>(spec.samples);
  const BudgetRefit refit(table, fit, draws + 2);
  UncertaintyBudget budget = start_budget(refit, spec, "monte_carlo");
  const Eigen::Matrix<double, 9, 1> nominal = as_vector(refit.parameters(RigErrors{}));
  for (int source = 0; source < kNumSources; ++source) {
    if (!(source_input(spec, source) > 0.0)) continue;
    if (source == kGravity) {
      budget.sources.push_back(gravity_source(refit, spec));
      continue;
    }
    // Each source its own stream: adding a source leaves the others' draws unchanged.
    std::seed_seq seq{static_cast<std::uint32_t>(spec.seed & 0xffffffffu),
                      static_cast<std::uint32_t>(spec.seed >> 32),
                      static_cast<std::uint32_t>(source)};
    std::mt19937_64 rng(seq);
    std::normal_distribution<double> normal(0.0, source_sigma(spec, source));
    const int inputs = source_inputs(source, refit.rows());
    // Welford over the deviations from the nominal refit.
    Eigen::Matrix<double, 9, 1> mean = Eigen::Matrix<double, 9, 1>::Zero();
    Eigen::Matrix<double, 9, 1> m2 = Eigen::Matrix<double, 9, 1>::Zero();
    RigErrors errors;
    for (int k = 0; k < spec.samples; ++k) {
      for (int i = 0; i < inputs; ++i) set_input(source, i, normal(rng), &errors, refit.rows());
      const Eigen::Matrix<double, 9, 1> d = as_vector(refit.parameters(errors)) - nominal;
      const Eigen::Matrix<double, 9, 1> delta = d - mean;
      mean += delta / static_cast<double>(k + 1);
      m2 += delta.cwiseProduct(d - mean);
    }
    BudgetSource s;
    s.name = kBudgetSourceNames[source];
    s.input = source_input(spec, source);
    s.std = from_vector((m2 / static_cast<double>(spec.samples - 1)).cwiseSqrt());
    s.mean_shift = from_vector(mean);
    budget.sources.push_back(s);
  }
  combine(&budget);
  return budget;
}

UncertaintyBudget linear_propagation_budget(const PositionTable& table, const FitResult& fit,
                                            const BudgetSpec& spec) {
  validate(spec);
  const BudgetRefit refit(table, fit);
  UncertaintyBudget budget = start_budget(refit, spec, "linear_propagation");
  for (int source = 0; source < kNumSources; ++source) {
    const double sigma = source_sigma(spec, source);
    if (!(sigma > 0.0)) continue;
    // Central differences with a step well inside the linear range of the source.
    const double h = 1e-3 * sigma;
    Eigen::Matrix<double, 9, 1> var = Eigen::Matrix<double, 9, 1>::Zero();
    const int inputs = source_inputs(source, refit.rows());
    for (int i = 0; i < inputs; ++i) {
      RigErrors up, down;
      set_input(source, i, h, &up, refit.rows());
      set_input(source, i, -h, &down, refit.rows());
      const Eigen::Matrix<double, 9, 1> derivative =
          (as_vector(refit.parameters(up)) - as_vector(refit.parameters(down))) / (2.0 * h);
      var += (sigma * derivative).cwiseAbs2();
    }
    BudgetSource s;
    s.name = kBudgetSourceNames[source];
    s.input = source_input(spec, source);
    s.std = from_vector(var.cwiseSqrt());
    budget.sources.push_back(s);
  }
  combine(&budget);
  return budget;
}

}  // namespace core
}  // namespace accel_intrinsics
