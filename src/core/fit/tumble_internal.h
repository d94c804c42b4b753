// The tumble fit's parameters, rest terms and solver, shared by the fit (tumble.cpp), its slow
// part (tumble_slow_part.cpp) and the next-pose guidance (tumble_guidance.cpp). Not installed.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "accel_intrinsics/core/fit/tumble.h"
#include "accel_intrinsics/core/noise/noise.h"

namespace accel_intrinsics {
namespace core {
namespace tumble_detail {

constexpr int kParams = 9;  // S lower-triangular (6) then O (3)
// Row-major index in S of each lower-triangular parameter.
constexpr std::array<int, 6> kLowerIndex{{0, 3, 4, 6, 7, 8}};
constexpr std::array<int, 6> kLowerRow{{0, 1, 1, 2, 2, 2}};
constexpr std::array<int, 6> kLowerCol{{0, 0, 1, 0, 1, 2}};
const char* const kParamNames[kParams] = {"S_ux", "S_vx", "S_vy", "S_wx", "S_wy",
                                          "S_wz", "O_u",  "O_v",  "O_w"};
const char* const kIntrinsicNames[9] = {"responsivity_u", "responsivity_v", "responsivity_w",
                                        "angle_uv",       "angle_vw",       "angle_wu",
                                        "offset_u",       "offset_v",       "offset_w"};

using Vector9 = Eigen::Matrix<double, kParams, 1>;
using Matrix9 = Eigen::Matrix<double, kParams, kParams>;

struct Parameters {
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();  // lower-triangular
  Eigen::Vector3d O = Eigen::Vector3d::Zero();

  Vector9 vector() const {
    Vector9 v;
    for (int k = 0; k < 6; ++k) v(k) = S(kLowerRow[k], kLowerCol[k]);
    v.tail<3>() = O;
    return v;
  }
  static Parameters from(const Vector9& v) {
    Parameters p;
    p.S.setZero();
    for (int k = 0; k < 6; ++k) p.S(kLowerRow[k], kLowerCol[k]) = v(k);
    p.O = v.tail<3>();
    return p;
  }
};

// One rest under the parameters: the specific force a = P (m - O), |a| - g and its gradient.
struct RestTerm {
  Eigen::Vector3d a;
  double residual = 0.0;  // |a| - g
  Vector9 gradient;       // d residual / d parameters
  Eigen::Vector3d c;      // P^T a_hat = d|a| / dm
};

RestTerm rest_term(const Parameters& p, const Eigen::Vector3d& mean, double g);
double rest_sigma(const RestTerm& t, const Eigen::Vector3d& se);
std::string number(double x, int precision = 3);
Parameters ellipsoid_start(const PositionTable& table, double g);
Matrix9 checked_tumble_inverse(const Matrix9& N);
bool has_usable_std(const PositionTable& table);

struct Normal {
  Matrix9 N = Matrix9::Zero();
  Vector9 b = Vector9::Zero();
  double chi2 = 0.0;
};

// The rests to fit and how their means err. White noise: each mean on its own, standard errors
// se. A noise model with a slow part (docs/design.md section 12): the means of neighbouring rests
// err together; R_s = L_s L_s^T from dwell_correlation (noise.h, the one definition of the slow
// covariance between dwells) is their correlation per accelerometer in units of se, i.e.
// Cov(m_i(s), m_j(s)) = se_i(s) se_j(s) R_s(i, j).
struct TumbleProblem {
  const PositionTable* table = nullptr;
  std::vector<Eigen::Vector3d> se;
  bool unit_weights = false;
  double g = kStandardGravity;
  bool gls = false;
  Eigen::MatrixXd R[3];
};

TumbleProblem make_problem(const PositionTable& table, double g, const NoiseModel& noise_model);
// The same with the rests' standard errors given (a prepared table's, dwell_standard_errors).
TumbleProblem make_problem(const PositionTable& table, std::vector<Eigen::Vector3d> se, double g,
                           const NoiseModel& noise_model);

// How the rests are weighted at an estimate. White: each by the sigma of its residual
// (rest_sigma). GLS: jointly, by the lower Cholesky factor L of the residuals' covariance.
// The residual r_i = |P (m_i - O)| - g depends on the mean m_i through c_i = P^T a_hat_i (first
// order), so C(i, j) = sum_s c_i(s) c_j(s) Cov(m_i(s), m_j(s)), the white variances included.
// The gradients c_i are taken at the current estimate and recomputed every Gauss-Newton
// iteration, as the white sigmas are: they depend on P and each rest's direction, which the start
// ellipsoid already gives far better than the weights need, so the iterations barely move them;
// recomputing costs one rests x rests Cholesky per iteration and with no slow part gives exactly
// the white weights. The step halving keeps the iteration's weights so that its costs compare.
struct RestWeights {
  std::vector<double> sigma;  // white
  Eigen::MatrixXd L;          // GLS
};

RestWeights weights_at(const TumbleProblem& problem, const Parameters& p);
Normal accumulate(const TumbleProblem& problem, const Parameters& p, const RestWeights& weights);
Parameters canonical(Parameters p);

// The fit's parameters, information matrix (unscaled) and the covariance scale.
struct TumbleSolution {
  Parameters p;
  Matrix9 information = Matrix9::Zero();
  double chi2 = 0.0;  // at p, with the weights at p
  double scale = 1.0;
};

Matrix9 intrinsic_jacobian(const Eigen::Matrix3d& S);
Vector9 intrinsic_scales(const Eigen::Matrix3d& S, double g);
TumbleSolution solve(const TumbleProblem& problem);

}  // namespace tumble_detail
}  // namespace core
}  // namespace accel_intrinsics
