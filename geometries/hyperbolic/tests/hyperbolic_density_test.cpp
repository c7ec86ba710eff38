// Data densities on H²: the piecewise-density conformance suite and H² specifics.
#include <gtest/gtest.h>

#include <random>

#include "conformance/piecewise_conformance.hpp"
#include "sdot/geometries/hyperbolic.hpp"

namespace sdot::testing {

namespace {
using Point = Hyperbolic::Point;

Hyperbolic klein_pentagon() {
  const std::vector<Eigen::Vector2d> vertices{{-0.55, -0.5}, {0.6, -0.45}, {0.7, 0.2}, {0.1, 0.65}, {-0.6, 0.3}};
  return Hyperbolic::from_klein(vertices);
}
}  // namespace

template <>
struct PiecewiseTraits<Hyperbolic> {
  static Hyperbolic geometry() { return klein_pentagon(); }
  static std::vector<std::array<Point, 3>> coarse_triangles() {
    const auto g = geometry();
    std::vector<std::array<Point, 3>> triangles;
    const auto& v = g.domain();
    for (std::size_t k = 0; k < v.size(); ++k) triangles.push_back({g.center(), v[k], v[(k + 1) % v.size()]});
    return triangles;
  }
  static std::vector<Point> random_sites(std::size_t n, std::mt19937_64& random) {
    return geometry().uniform_samples(n, random());
  }
  static double chart_x(const Point& x) { return Hyperbolic::to_klein(x).x() / 0.65; }
};

GTEST_ALLOW_UNINSTANTIATED_PARAMETERIZED_TEST(GeometryConformance);
INSTANTIATE_TYPED_TEST_SUITE_P(Hyperbolic, PiecewiseConformance, ::testing::Types<Hyperbolic>);

TEST(HyperbolicDensity, KleinLinearMeshEqualsFunctionDensity) {
  // A function linear in Klein coordinates is reproduced exactly by the mesh interpolant.
  const auto g = klein_pentagon();
  const auto mesh = refine(g, PiecewiseTraits<Hyperbolic>::coarse_triangles(), 2);
  const auto rho = [](const Point& x) {
    const Eigen::Vector2d k = Hyperbolic::to_klein(x);
    return 1 + 0.5 * k.x() - 0.3 * k.y();
  };
  std::vector<double> values;
  for (const auto& v : mesh.vertices) values.push_back(rho(v));
  const auto density = mesh_density(g, std::span(mesh.vertices), std::span(mesh.triangles), std::span(values), 8);
  const auto sites = g.uniform_samples(50, 11);
  const Eigen::VectorXd masses = equal_masses(sites.size(), 1.0);
  const auto a = solve(g, density, std::span<const Point>(sites), masses);
  const auto b = solve(g, FunctionDensity<Point>{rho, 8}, std::span<const Point>(sites), masses);
  ASSERT_TRUE(a.summary.converged()) << a.summary.message;
  ASSERT_TRUE(b.summary.converged()) << b.summary.message;
  EXPECT_LT((a.weights - b.weights).cwiseAbs().maxCoeff(), 1e-8);
}

}  // namespace sdot::testing
