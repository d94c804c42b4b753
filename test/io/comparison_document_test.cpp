// The comparison document (io/comparison_document.cpp, the one writer of compare_results'
// JSON): every field of a comparison written in the test, each with its own value, is found in
// the document under its key, with a non-finite value written as null; the reference value and
// the degrees of equivalence only for three or more results.
#include "accel_intrinsics/io/comparison_document.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

namespace accel_intrinsics {
namespace {

core::Comparison comparison(int results) {
  core::Comparison c;
  for (int i = 0; i < results; ++i) c.results.push_back("lab" + std::to_string(i) + ".json");
  c.local_gravity = 9.80123;
  c.coverage_factor = 2.1;
  c.consistent = false;
  core::ParameterComparison p;
  p.name = "angle_uv";
  for (int i = 0; i < results; ++i) {
    p.values.push_back(90.0 + 0.01 * i);
    p.expanded.push_back(0.002 + 0.001 * i);
    p.degrees_of_equivalence.push_back(-0.004 + 0.003 * i);
    p.degrees_of_equivalence_expanded.push_back(0.0035 + 0.0005 * i);
  }
  for (int i = 1; i < results; ++i) p.E_n.push_back(0.5 * i);
  p.E_n.back() = std::numeric_limits<double>::quiet_NaN();
  p.reference = 90.0123;
  p.reference_expanded = 0.0011;
  c.parameters.push_back(p);
  return c;
}

void expect_numbers(const nlohmann::json& j, const std::vector<double>& v, const char* key) {
  ASSERT_EQ(j.size(), v.size()) << key;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (std::isfinite(v[i])) {
      EXPECT_EQ(j[i].get<double>(), v[i]) << key << "[" << i << "]";
    } else {
      EXPECT_TRUE(j[i].is_null()) << key << "[" << i << "]";
    }
  }
}

TEST(ComparisonDocument, ThreeResultsCarryEveryFieldUnderItsKey) {
  const core::Comparison c = comparison(3);
  const nlohmann::json j = nlohmann::json::parse(io::comparison_json_text(c, false));
  EXPECT_EQ(j.at("results").get<std::vector<std::string>>(), c.results);
  EXPECT_EQ(j.at("local_gravity").get<double>(), 9.80123);
  EXPECT_EQ(j.at("k").get<double>(), 2.1);
  EXPECT_EQ(j.at("uncertainty").get<std::string>(), "budget");
  EXPECT_FALSE(j.at("consistent").get<bool>());
  const core::ParameterComparison& p = c.parameters[0];
  const nlohmann::json& q = j.at("parameters").at("angle_uv");
  expect_numbers(q.at("values"), p.values, "values");
  expect_numbers(q.at("U"), p.expanded, "U");
  expect_numbers(q.at("E_n"), p.E_n, "E_n");
  EXPECT_EQ(q.at("reference_value").get<double>(), 90.0123);
  EXPECT_EQ(q.at("reference_U").get<double>(), 0.0011);
  expect_numbers(q.at("degrees_of_equivalence"), p.degrees_of_equivalence,
                 "degrees_of_equivalence");
  expect_numbers(q.at("degrees_of_equivalence_U"), p.degrees_of_equivalence_expanded,
                 "degrees_of_equivalence_U");
}

TEST(ComparisonDocument, TwoResultsHaveNoReferenceAndSayTypeAOnly) {
  const nlohmann::json j =
      nlohmann::json::parse(io::comparison_json_text(comparison(2), /*type_a_only=*/true));
  EXPECT_EQ(j.at("uncertainty").get<std::string>(), "type_a_only");
  const nlohmann::json& q = j.at("parameters").at("angle_uv");
  EXPECT_EQ(q.at("values").size(), 2u);
  for (const char* key :
       {"reference_value", "reference_U", "degrees_of_equivalence", "degrees_of_equivalence_U"}) {
    EXPECT_FALSE(q.contains(key)) << key;
  }
}

}  // namespace
}  // namespace accel_intrinsics
