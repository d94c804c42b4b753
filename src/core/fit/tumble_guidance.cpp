// After a tumble fit: the rests' up directions, the coverage of the sphere, the intrinsics'
// relative uncertainties and the next pose that would shrink the worst of them (tumble.h).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "accel_intrinsics/core/fit/tumble.h"
#include "accel_intrinsics/core/model/intrinsics.h"
#include "tumble_internal.h"

namespace accel_intrinsics {
namespace core {

using namespace tumble_detail;

std::vector<Eigen::Vector3d> rest_up_directions(const FitResult& fit, const PositionTable& table) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(table.rows.size());
  for (const DwellRecord& row : table.rows) {
    const Eigen::Vector3d a = fit.S.lu().solve(row.mean - fit.O);
    out.push_back(a.normalized());
  }
  return out;
}

TumbleCoverage tumble_coverage(const FitResult& fit, const PositionTable& table, double cone_deg) {
  TumbleCoverage c;
  c.cone_deg = cone_deg;
  const std::vector<Eigen::Vector3d> ups = rest_up_directions(fit, table);
  const char* axis_names[3] = {"u", "v", "w"};
  for (int s = 0; s < 3; ++s) {
    const Eigen::Vector3d axis = fit.S.row(s).normalized();
    for (int side = 0; side < 2; ++side) {
      double best = 180.0;
      for (const Eigen::Vector3d& up : ups) {
        const double cosine = std::clamp((side == 0 ? 1.0 : -1.0) * up.dot(axis), -1.0, 1.0);
        best = std::min(best, std::acos(cosine) * 180.0 / M_PI);
      }
      c.closest_deg[s][side] = best;
      if (best > cone_deg) {
        c.missing.push_back(std::string("no rest with ") + axis_names[s] + " pointing " +
                            (side == 0 ? "up" : "down") + " within " + number(cone_deg) +
                            " deg (closest " + number(best, 3) + " deg)");
      }
    }
  }
  return c;
}

std::vector<RelativeUncertainty> relative_uncertainties(const FitResult& fit) {
  std::vector<RelativeUncertainty> out;
  const Intrinsics& in = fit.intrinsics;
  for (int k = 0; k < 3; ++k)
    out.push_back({kIntrinsicNames[k], in.responsivity_std(k) / in.responsivity(k)});
  for (int k = 0; k < 3; ++k) out.push_back({kIntrinsicNames[3 + k], in.angles_std_rad(k)});
  for (int k = 0; k < 3; ++k)
    out.push_back(
        {kIntrinsicNames[6 + k], fit.O_std(k) / (in.responsivity(k) * fit.local_gravity)});
  return out;
}

PoseSuggestion suggest_next_pose(const FitResult& fit, const PositionTable& table, int candidates) {
  if (fit.model != FitModel::Tumble)
    throw std::invalid_argument("suggest_next_pose needs a tumble fit");
  const double g = fit.local_gravity;
  Parameters p;
  p.S = fit.S;
  p.O = fit.O;
  const TumbleProblem problem = make_problem(table, g, NoiseModel());
  const std::vector<Eigen::Vector3d>& se = problem.se;
  const bool unit_weights = problem.unit_weights;
  const Normal n = accumulate(problem, p, weights_at(problem, p));
  const Matrix9 C = checked_tumble_inverse(n.N);  // unscaled
  const double scale = fit.reduced_chi2 > 1.0 || unit_weights ? fit.reduced_chi2 : 1.0;
  // The typical noise of one more rest: the median standard error per axis.
  Eigen::Vector3d typical;
  for (int s = 0; s < 3; ++s) {
    std::vector<double> v;
    for (const Eigen::Vector3d& e : se) v.push_back(e(s));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    typical(s) = v[v.size() / 2];
  }
  const Matrix9 T = intrinsic_jacobian(fit.S);
  const Vector9 scales = intrinsic_scales(fit.S, g);
  // Variances of the nine intrinsics now (unscaled), and C T^T for the updates.
  const Eigen::Matrix<double, 9, 9> CT = C * T.transpose();
  Vector9 variance;
  for (int k = 0; k < 9; ++k) variance(k) = T.row(k).dot(CT.col(k));
  auto relative = [&](const Vector9& var) {
    return (var.cwiseMax(0.0) * scale).cwiseSqrt().cwiseQuotient(scales);
  };
  const Vector9 now = relative(variance);
  int target = 0;
  now.maxCoeff(&target);
  PoseSuggestion best;
  best.target = kIntrinsicNames[target];
  best.relative_std_now = now(target);
  best.relative_std_after = now(target);
  double best_largest = now.maxCoeff();
  // Candidates on a Fibonacci sphere. One more rest with gradient j and noise sigma changes each
  // variance by -(t_k^T C j)^2 / (sigma^2 + j^T C j) (Sherman-Morrison on the information); the
  // best candidate has the smallest largest relative uncertainty afterwards.
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < candidates; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / candidates;
    const double radius = std::sqrt(std::max(0.0, 1.0 - z * z));
    const Eigen::Vector3d up(radius * std::cos(golden * i), radius * std::sin(golden * i), z);
    const Eigen::Vector3d mean = p.S * (g * up) + p.O;
    const RestTerm term = rest_term(p, mean, g);
    const double sigma = unit_weights ? 1.0 : rest_sigma(term, typical);
    const Vector9& j = term.gradient;
    const Vector9 tCj = CT.transpose() * j;
    const double denominator = sigma * sigma + j.dot(C * j);
    const Vector9 after = relative(variance - tCj.cwiseProduct(tCj) / denominator);
    const double largest = after.maxCoeff();
    if (largest < best_largest) {
      best_largest = largest;
      best.up = up;
      best.relative_std_after = after(target);
    }
  }
  best.largest_after = best_largest;
  best.words = describe_pose(best.up);
  return best;
}

std::string describe_pose(const Eigen::Vector3d& up_in) {
  const Eigen::Vector3d up = up_in.normalized();
  const char* axis[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    const double elevation = std::asin(std::clamp(up(k), -1.0, 1.0)) * 180.0 / M_PI;
    if (elevation >= 80.0) return std::string(axis[k]) + " axis pointing straight up";
    if (elevation <= -80.0) return std::string(axis[k]) + " axis pointing straight down";
  }
  // Name the axes that tilt noticeably, the steepest first.
  std::array<int, 3> order{{0, 1, 2}};
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return std::abs(up(a)) > std::abs(up(b)); });
  std::string words;
  for (int k : order) {
    const double elevation = std::asin(std::clamp(up(k), -1.0, 1.0)) * 180.0 / M_PI;
    if (std::abs(elevation) < 10.0) continue;
    if (!words.empty()) words += ", ";
    words += std::string(axis[k]) + " axis " + number(std::round(std::abs(elevation)), 3) +
             " deg " + (elevation > 0.0 ? "up" : "down");
  }
  return words.empty() ? "level" : words;
}

}  // namespace core
}  // namespace accel_intrinsics
