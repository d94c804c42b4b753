// Type-B uncertainty budget by Monte Carlo through the one model (docs/design.md section 9, GUM
// Supplement 1). For each error source of a budget, the fitted device is simulated noise-free at
// the run's own positions (the position table's angles, times and approaches) under draws of
// that source, refitted with the run's model, and the scatter (standard deviation over the draws)
// of every intrinsic parameter is the source's contribution. Type A (the fit's own covariance) is
// the source `type_a`; the sources combine in quadrature; expanded uncertainty U = k u, k = 2.
//
// The refit. Both closed-form models (joint without effect terms, eq4) give estimates of S and O
// that are LINEAR in the dwell means once the weights are fixed (the weights come from the run's
// dwell standard errors, which the budget keeps). So the refit of a draw is
//   theta = theta_0 + L (y_draw - y_0),  theta = (S row-major, O),
// with y_0 the noise-free outputs of the fitted device at the run's positions, theta_0 its refit
// and L (12 x 3N) the derivative of core::fit() with respect to the dwell means, taken column by
// column from core::fit() itself (differences; exact for the linear fits up to round-off,
// so the budget refits with exactly the code that made the certificate). For a joint fit with
// effect terms (Ceres), the same L is the fit's linearization at the fitted device: a
// Gauss-Newton step, accurate for errors small enough that the estimate stays linear in them.
// The simulation of each draw is NOT linearized: outputs come from model.h (predict_outputs) at
// the perturbed angles, tilts and mountings, and the intrinsics from intrinsics_from_vectors, so
// second-order effects (cos tau of an axis tilt, the arccos of the angles) appear in the scatter.
// Cost: 3N + 1 fits (2 (3N) + 1 with effect terms) to build L once, then O(N) per draw. When the
// budget needs fewer draws in all than L needs fits (large N), a closed-form model is instead
// refitted with core::fit for every draw (also exact, also O(N) per draw), so the cost stays linear
// in draws and in N.
//
// Sources (all standard uncertainties, default 0, a source of 0 is left out of the budget):
//   gravity_std_rel            relative error of the local gravity g the run assumed. g scales
//                              every output exactly, and the refit is linear, so the contribution
//                              is evaluated deterministically at g (1 +- u) (exact for a linear
//                              dependence, where Monte Carlo would add only its sampling noise):
//                              the responsivities move by u |s|, angles and offsets not at all.
//   angle_random_std_deg       an error of the true gimbal angle, independent per position (row)
//   angle_offset_std_deg       a constant angle error per phase (angle_offset[p])
//   angle_scale_std            a relative scale error of the angle per phase (angle_scale[p])
//   axis_tilt_std_deg          rotation axis raised from horizontal, per phase (axis_tilt[p])
//   mount_misalignment_std_deg the DUT's p axis versus the rotation axis in phase p: a small
//                              rotation R_p of the DUT about the two axes other than p, each
//                              component with this standard deviation (a rotation about p itself
//                              is an angle offset). The DUT then sees f_DUT = R_p^T f(alpha), i.e.
//                              outputs S R_p^T f + O: the model with S R_p^T in phase p.
//   samples (2000), seed (1)   draws per source and the seed (each source its own stream).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "accel_intrinsics/core/dwells/position_table.h"
#include "accel_intrinsics/core/fit/fit.h"
#include "accel_intrinsics/core/model/model.h"

namespace accel_intrinsics {
namespace core {

struct BudgetSpec {
  double gravity_std_rel = 0.0;             // 1
  double angle_random_std_deg = 0.0;        // deg, per position
  double angle_offset_std_deg = 0.0;        // deg, per phase
  double angle_scale_std = 0.0;             // 1, per phase
  double axis_tilt_std_deg = 0.0;           // deg, per phase
  double mount_misalignment_std_deg = 0.0;  // deg, per component and phase
  int samples = 2000;                       // draws per source
  std::uint64_t seed = 1;
};

// Throws std::invalid_argument naming the key: negative or non-finite standard uncertainties,
// samples < 10 or > 10^7, angles so large that the small-error model is meaningless (> 10 deg).
void validate(const BudgetSpec& spec);

// One value per intrinsic parameter (values or standard uncertainties).
struct IntrinsicValues {
  Eigen::Vector3d responsivity = Eigen::Vector3d::Zero();  // |u|, |v|, |w| (1)
  Eigen::Vector3d angles_rad = Eigen::Vector3d::Zero();    // uv, vw, wu
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();        // O_u, O_v, O_w (m/s^2)
};

// The names of the budget's sources, in budget order after type_a.
extern const char* const kBudgetSourceNames[6];

struct BudgetSource {
  std::string name;            // "type_a", "gravity_std_rel", "angle_random_std_deg", ...
  double input = 0.0;          // the budget file's value (NaN for type_a)
  IntrinsicValues std;         // standard uncertainty contributed to each parameter
  IntrinsicValues mean_shift;  // mean of the draws minus the unperturbed refit (Monte Carlo
                               // sources; zero for type_a and gravity): a second-order bias the
                               // budget does not correct, reported so it can be seen
};

struct UncertaintyBudget {
  std::vector<BudgetSource> sources;  // type_a first, then the non-zero sources of the spec
  IntrinsicValues combined;           // quadrature sum of all sources
  double coverage_factor = 2.0;       // k
  IntrinsicValues expanded;           // k * combined
  BudgetSpec spec;
  std::string method;  // e.g. "monte_carlo; refit: joint (closed form)"
};

// An error state of the rig for one simulated run (all zero: the nominal rig).
struct RigErrors {
  double gravity_rel = 0.0;
  std::vector<double> row_angle_rad;                           // per table row (empty: none)
  Eigen::Vector3d angle_offset_rad = Eigen::Vector3d::Zero();  // per phase x, y, z
  Eigen::Vector3d angle_scale = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_tilt_rad = Eigen::Vector3d::Zero();
  // Per phase p: rotation vector of the DUT mounting (components along the axes other than p).
  Eigen::Matrix3d mount_rotation = Eigen::Matrix3d::Zero();  // column p = rotation vector of p
};

// The fitted device, simulated at the run's positions and refitted (see the file comment).
class BudgetRefit {
 public:
  // Throws FitError when the run's model cannot be refitted (the fit's own errors). `draws`: how
  // many refits the caller will ask for (chooses between L and direct refits, see above; 0: L).
  BudgetRefit(const PositionTable& table, const FitResult& fit, std::size_t draws = 0);

  // Noise-free outputs of the fitted device under `errors`, one 3-vector per table row, stacked
  // (u, v, w of row 0, then row 1, ...).
  Eigen::VectorXd simulate(const RigErrors& errors) const;
  // The run's refit of such outputs: theta = (S row-major, O).
  Eigen::Matrix<double, 12, 1> refit(const Eigen::VectorXd& outputs) const;
  // simulate -> refit -> intrinsics.
  IntrinsicValues parameters(const RigErrors& errors) const;

  std::size_t rows() const { return geoms_.size(); }
  const std::vector<DwellGeometry>& geometries() const { return geoms_; }
  bool closed_form() const { return closed_form_; }
  bool uses_operator() const { return use_operator_; }
  const FitResult& fit() const { return fit_; }

 private:
  FitResult fit_;
  std::vector<DwellGeometry> geoms_;
  Eigen::VectorXd y0_;
  Eigen::Matrix<double, 12, 1> theta0_;
  Eigen::MatrixXd L_;  // 12 x 3N (when use_operator_)
  bool closed_form_ = true;
  bool use_operator_ = true;
  PositionTable base_;  // the run's table (rows, std, n, times): means replaced per refit
  FitOptions options_;
};

// |u|, |v|, |w|, the angles and O of a parameter vector theta = (S row-major, O).
IntrinsicValues intrinsic_values(const Eigen::Matrix<double, 12, 1>& theta);

// The budget of `fit` (the certificate) for the run `table` it came from. Throws
// std::invalid_argument for an invalid spec and FitError when the refit fails.
UncertaintyBudget uncertainty_budget(const PositionTable& table, const FitResult& fit,
                                     const BudgetSpec& spec);

// The same sources by linear propagation (GUM's law of propagation): the derivative of every
// parameter with respect to each independent input of a source (each row's angle, each phase's
// offset, ...), by central differences through BudgetRefit::parameters, times the input's
// standard uncertainty, summed in quadrature. For comparison with the Monte Carlo (README, bench).
UncertaintyBudget linear_propagation_budget(const PositionTable& table, const FitResult& fit,
                                            const BudgetSpec& spec);

}  // namespace core
}  // namespace accel_intrinsics
