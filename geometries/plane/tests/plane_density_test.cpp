// Data densities on the plane: the piecewise-density conformance suite.
#include <gtest/gtest.h>

#include <random>

#include "conformance/piecewise_conformance.hpp"
#include "sdot/geometries/plane.hpp"

namespace sdot::testing {

template <>
struct PiecewiseTraits<Plane> {
  using Point = Plane::Point;
  static Plane geometry() { return Plane(ConvexPolygon({{0, 0}, {2, 0}, {2.4, 1.2}, {1, 2}, {-0.3, 1}})); }
  static std::vector<std::array<Point, 3>> coarse_triangles() {
    const auto domain = geometry().domain();
    const Point center = domain.centroid();
    std::vector<std::array<Point, 3>> triangles;
    const auto& v = domain.vertices();
    for (std::size_t k = 0; k < v.size(); ++k) triangles.push_back({center, v[k], v[(k + 1) % v.size()]});
    return triangles;
  }
  static std::vector<Point> random_sites(std::size_t n, std::mt19937_64& random) {
    std::uniform_real_distribution<double> uniform(-0.3, 2.4);
    std::vector<Point> sites;
    const auto g = geometry();
    while (sites.size() < n)
      if (const Point p(uniform(random), uniform(random)); g.domain().contains(p)) sites.push_back(p);
    return sites;
  }
  static double chart_x(const Point& x) { return (x.x() - 1.05) / 1.35; }
};

GTEST_ALLOW_UNINSTANTIATED_PARAMETERIZED_TEST(GeometryConformance);
INSTANTIATE_TYPED_TEST_SUITE_P(Plane, PiecewiseConformance, ::testing::Types<Plane>);

}  // namespace sdot::testing

namespace sdot::testing {

TEST(PlaneDensity, LinearMeshEqualsLinearFunctionDensity) {
  const auto g = PiecewiseTraits<Plane>::geometry();
  const auto mesh = refine(g, PiecewiseTraits<Plane>::coarse_triangles(), 2);
  const auto rho = [](const Plane::Point& x) { return 1 + 0.4 * x.x() - 0.2 * x.y(); };
  std::vector<double> values;
  for (const auto& v : mesh.vertices) values.push_back(rho(v));
  const auto density = mesh_density(g, std::span(mesh.vertices), std::span(mesh.triangles), std::span(values), 3);
  std::mt19937_64 random(9);
  const auto sites = PiecewiseTraits<Plane>::random_sites(70, random);
  const Eigen::VectorXd masses = equal_masses(sites.size(), 1.0);
  Options options;
  options.tolerance = 1e-11;
  const auto a = solve(g, density, std::span<const Plane::Point>(sites), masses, options);
  const auto b = solve(g, FunctionDensity<Plane::Point>{rho, 3}, std::span<const Plane::Point>(sites), masses, options);
  ASSERT_TRUE(a.summary.converged()) << a.summary.message;
  ASSERT_TRUE(b.summary.converged()) << b.summary.message;
  EXPECT_LT((a.weights - b.weights).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_NEAR(a.transport_cost, b.transport_cost, 1e-11 * b.transport_cost);
}

}  // namespace sdot::testing
