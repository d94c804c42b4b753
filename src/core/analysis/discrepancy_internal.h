// Helpers shared by the discrepancy analysis (discrepancy.cpp), its screening (screening.cpp)
// and the gap (gap.cpp). Not installed.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "accel_intrinsics/core/analysis/discrepancy.h"

namespace accel_intrinsics {
namespace core {
namespace analysis_detail {

bool same_term(const Effect& a, const Effect& b);
bool contains_term(const std::vector<Effect>& list, const Effect& e);

// gap.cpp
// P(chi2(dof) >= x).
double chi2_sf(double x, double dof);
double chi2_quantile(double p, double dof);
// Standard errors of the dwell means, the weights of every fit.
std::vector<Eigen::Vector3d> weights_for(const PositionTable& table, const FitResult& fit);
// Normalized twin residuals z (index 3 row + s).
Eigen::VectorXd normalized_residuals(const std::vector<Eigen::Vector3d>& residuals,
                                     const std::vector<Eigen::Vector3d>& se);
GapSummary summarize(double chi2, int dof, double sum_sq, int n);

// screening.cpp
// Parameters: S row-major (0..8), O (9..11), values of `terms` (12..). Returns d(R)/d(param)
// for every row and accelerometer (index 3 row + s), divided by the standard error.
Eigen::VectorXd weighted_derivative(const std::vector<DwellGeometry>& geoms,
                                    const std::vector<Eigen::Vector3d>& se, const Device& device,
                                    const std::vector<Effect>& terms, int param, double g);
// Orthonormal basis of the column space of A (numerical rank).
Eigen::MatrixXd column_space(const Eigen::MatrixXd& A);

// Screening of the candidates at the current fit.
struct Screening {
  ScreeningStep step;
  std::vector<Eigen::VectorXd> directions;  // unit b_perp of step.candidates (identifiable only)
  Eigen::MatrixXd correlation;              // of the identifiable candidates, in step order
  std::vector<int> identifiable_index;      // step.candidates index -> row of correlation (-1)
};

Screening screen(const PositionTable& table, const std::vector<DwellGeometry>& geoms,
                 const FitResult& fit, const std::vector<Effect>& model_terms,
                 const std::vector<Effect>& candidates, const AnalysisOptions& options,
                 int step_number);
double ambiguity_threshold_corr(const Screening& s, int a_row, int b_row);

}  // namespace analysis_detail
}  // namespace core
}  // namespace accel_intrinsics
