// Acceptance bounds for statistical tests (issue 15 item 6): a correct implementation must fail a
// test in fewer than 1 of 1000 runs whatever the seed, so every band is a quantile of the
// statistic's distribution under a correct implementation, with the 1e-3 split over the checks
// of a test (Bonferroni). Boost.Math quantiles, computed in the test.
#pragma once

#include <boost/math/distributions/binomial.hpp>
#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/normal.hpp>
#include <cmath>
#include <utility>

namespace accel_intrinsics {
namespace statistical_bounds {

// Largest count c with P(X > c) <= tail for X ~ binomial(trials, p).
inline int binomial_upper(int trials, double p, double tail) {
  const boost::math::binomial_distribution<double> b(trials, p);
  // quantile(complement) rounds outwards (integer_round_outwards): P(X > c) <= tail.
  return static_cast<int>(std::ceil(boost::math::quantile(boost::math::complement(b, tail))));
}
// Smallest count c with P(X < c) <= tail.
inline int binomial_lower(int trials, double p, double tail) {
  const boost::math::binomial_distribution<double> b(trials, p);
  return static_cast<int>(std::floor(boost::math::quantile(b, tail)));
}
// (lo, hi) with P(X < lo) <= tail and P(X > hi) <= tail for X ~ chi2(dof).
inline std::pair<double, double> chi2_band(double dof, double tail) {
  const boost::math::chi_squared_distribution<double> c(dof);
  return {boost::math::quantile(c, tail), boost::math::quantile(boost::math::complement(c, tail))};
}
// k with P(|N(0,1)| > k) = two_sided_tail.
inline double normal_k(double two_sided_tail) {
  const boost::math::normal_distribution<double> n(0.0, 1.0);
  return boost::math::quantile(boost::math::complement(n, 0.5 * two_sided_tail));
}

}  // namespace statistical_bounds
}  // namespace accel_intrinsics
