#include <gtest/gtest.h>

#include <cmath>

#include "sdot/error.hpp"
#include "sdot/quadrature.hpp"

namespace sdot {
namespace {

TEST(Quadrature, GaussLegendreIsExactUpToDegree2nMinus1) {
  for (int order = 1; order <= 20; ++order) {
    const auto& rule = gauss_legendre(order);
    ASSERT_EQ(rule.size(), static_cast<std::size_t>(order));
    for (int degree = 0; degree <= 2 * order - 1; ++degree) {
      double integral = 0;
      for (const auto& node : rule) integral += node.weight * std::pow(node.x, degree);
      EXPECT_NEAR(integral, 1.0 / (degree + 1), 1e-14) << "order " << order << " degree " << degree;
    }
  }
}

TEST(Quadrature, TriangleRuleIsExactUpToDegree2nMinus2) {
  // ∫_T s^a t^b = a! b! / (a + b + 2)!
  auto exact = [](int a, int b) { return std::tgamma(a + 1) * std::tgamma(b + 1) / std::tgamma(a + b + 3); };
  for (int order = 1; order <= 8; ++order)
    for (int a = 0; a + 0 <= 2 * order - 2; ++a)
      for (int b = 0; a + b <= 2 * order - 2; ++b) {
        double integral = 0;
        for (const auto& node : triangle_rule(order))
          integral += node.weight * std::pow(node.s, a) * std::pow(node.t, b);
        EXPECT_NEAR(integral, exact(a, b), 1e-15) << order << " " << a << " " << b;
      }
}

TEST(Quadrature, RejectsBadOrders) {
  EXPECT_THROW(gauss_legendre(0), InputError);
  EXPECT_THROW(triangle_rule(65), InputError);
}

}  // namespace
}  // namespace sdot
