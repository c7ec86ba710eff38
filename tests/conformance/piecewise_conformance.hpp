#pragma once
// The typed conformance suite of data densities (PiecewiseDensity) for every ProjectiveGeometry:
//
//   template <> struct sdot::testing::PiecewiseTraits<MyGeometry> { ... see below ... };
//   INSTANTIATE_TYPED_TEST_SUITE_P(MyGeometry, PiecewiseConformance, ::testing::Types<MyGeometry>);
//
// PiecewiseTraits<G> provides:
//   static G geometry();                                       // the source domain
//   static std::vector<std::array<Point, 3>> coarse_triangles(); // triangles tiling the domain
//   static std::vector<Point> random_sites(std::size_t n, std::mt19937_64& random);
//   static double chart_x(const Point& x);                     // a chart coordinate in [−1, 1]-ish
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "conformance/conformance.hpp"
#include "sdot/piecewise_density.hpp"
#include "sdot/solver.hpp"

namespace sdot::testing {

template <class G>
struct PiecewiseTraits;

/// A mesh over the traits' coarse triangles, refined `levels` times.
template <class G>
using TestMesh = TriangleMesh<typename G::Point>;

template <class G>
TestMesh<G> refine(const G& geometry, const std::vector<std::array<typename G::Point, 3>>& coarse, int levels) {
  TestMesh<G> mesh;
  for (const auto& t : coarse) {
    const int first = static_cast<int>(mesh.vertices.size());
    mesh.vertices.insert(mesh.vertices.end(), t.begin(), t.end());
    mesh.triangles.push_back({first, first + 1, first + 2});
  }
  return subdivide(geometry, mesh, levels);
}

template <class G>
class PiecewiseConformance : public ::testing::Test {
 protected:
  using Traits = PiecewiseTraits<G>;
  using Point = typename G::Point;
  std::mt19937_64 random{2468};
  G geometry = Traits::geometry();
  TestMesh<G> test_mesh = refine(geometry, Traits::coarse_triangles(), 3);

  std::vector<double> vertex_values(const std::function<double(const Point&)>& f) const {
    std::vector<double> values;
    for (const auto& v : test_mesh.vertices) values.push_back(f(v));
    return values;
  }
  static double smooth(const Point& x) { return 1 + 0.6 * std::sin(3 * Traits::chart_x(x)); }
  Eigen::VectorXd varying_masses(std::size_t n, double ratio) { return log_uniform_masses(n, ratio, random); }
  double domain_area(std::span<const Point> sites) const {
    return evaluate(geometry, UniformDensity{}, sites, geometry.default_weights(sites), false).masses.sum();
  }
};

TYPED_TEST_SUITE_P(PiecewiseConformance);

TYPED_TEST_P(PiecewiseConformance, UnitMeshEqualsUniformDensity) {
  using T = typename TestFixture::Traits;
  const auto& mesh = this->test_mesh;
  const std::vector<double> ones(mesh.triangles.size(), 1.0);
  const auto density =
      mesh_density_per_triangle(this->geometry, std::span(mesh.vertices), std::span(mesh.triangles), std::span(ones));
  const auto sites = T::random_sites(80, this->random);
  const double area = this->domain_area(std::span(sites));
  EXPECT_NEAR(density.total_mass(), area, 1e-12 * area);
  const Eigen::VectorXd masses = this->varying_masses(80, 5);
  Options options;
  options.tolerance = 1e-10;
  const auto with_mesh = solve(this->geometry, density, std::span(sites), masses, options);
  const auto uniform = solve(this->geometry, UniformDensity{}, std::span(sites), masses, options);
  ASSERT_TRUE(with_mesh.summary.converged()) << with_mesh.summary.message;
  ASSERT_TRUE(uniform.summary.converged()) << uniform.summary.message;
  EXPECT_LT((with_mesh.weights - uniform.weights).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_NEAR(with_mesh.transport_cost, uniform.transport_cost, 1e-9 * std::abs(uniform.transport_cost) + 1e-12);
}

TYPED_TEST_P(PiecewiseConformance, ConstantLinearMeshEqualsFunctionDensity) {
  using T = typename TestFixture::Traits;
  using P = typename TestFixture::Point;
  const auto& mesh = this->test_mesh;
  const auto values = this->vertex_values([](const P&) { return 2.5; });
  const auto density =
      mesh_density(this->geometry, std::span(mesh.vertices), std::span(mesh.triangles), std::span(values));
  const FunctionDensity<P> function{[](const P&) { return 2.5; }, 6};
  const auto sites = T::random_sites(60, this->random);
  const Eigen::VectorXd masses = this->varying_masses(60, 4);
  const auto a = solve(this->geometry, density, std::span(sites), masses);
  const auto b = solve(this->geometry, function, std::span(sites), masses);
  ASSERT_TRUE(a.summary.converged()) << a.summary.message;
  ASSERT_TRUE(b.summary.converged()) << b.summary.message;
  EXPECT_LT((a.weights - b.weights).cwiseAbs().maxCoeff(), 1e-8);
}

TYPED_TEST_P(PiecewiseConformance, LinearMeshHessianMatchesFiniteDifferences) {
  using T = typename TestFixture::Traits;
  const auto& mesh = this->test_mesh;
  const auto values = this->vertex_values(&TestFixture::smooth);
  const auto density =
      mesh_density(this->geometry, std::span(mesh.vertices), std::span(mesh.triangles), std::span(values));
  const auto sites = T::random_sites(25, this->random);
  // at solved weights for varying masses: the Hessian's error against finite differences
  auto expect_hessian_matches = [&](const auto& d, const char* kind) {
    const Eigen::VectorXd weights = solved_weights(this->geometry, d, std::span(sites), this->varying_masses(25, 4));
    const double error = hessian_fd_error(this->geometry, d, std::span(sites), weights);
    std::printf("  %s mesh density: Hessian vs finite differences, relative error %.2e\n", kind, error);
    EXPECT_LT(error, 1e-6) << kind;
  };
  expect_hessian_matches(density, "piecewise-linear");
  const auto constant_values = [&] {
    std::vector<double> v;
    for (const auto& t : mesh.triangles)
      v.push_back(TestFixture::smooth(mesh.vertices[static_cast<std::size_t>(t[0])]));
    return v;
  }();
  expect_hessian_matches(mesh_density_per_triangle(this->geometry, std::span(mesh.vertices), std::span(mesh.triangles),
                                                   std::span(constant_values)),
                         "piecewise-constant");
}

TYPED_TEST_P(PiecewiseConformance, LinearMeshConvergesAndConservesMass) {
  using T = typename TestFixture::Traits;
  const auto& mesh = this->test_mesh;
  const auto values = this->vertex_values(&TestFixture::smooth);
  const auto density =
      mesh_density(this->geometry, std::span(mesh.vertices), std::span(mesh.triangles), std::span(values));
  const auto sites = T::random_sites(300, this->random);
  const auto result = solve(this->geometry, density, std::span(sites), this->varying_masses(300, 20));
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_LE(result.summary.max_relative_error, 1e-9);
  const double total = density.total_mass();
  EXPECT_NEAR(result.masses.sum(), total, 1e-11 * total);
  EXPECT_NEAR(result.summary.source_mass, total, 1e-11 * total);
}

TYPED_TEST_P(PiecewiseConformance, ZeroDensityRegionConverges) {
  // ρ = 0 on the part of the domain with chart_x < 0.2 (connected support): many sites start
  // with empty mass; the continuation gets every cell into the support.
  using T = typename TestFixture::Traits;
  const auto& mesh = this->test_mesh;
  std::vector<double> values;
  for (const auto& t : mesh.triangles) {
    const auto& a = mesh.vertices[static_cast<std::size_t>(t[0])];
    const auto& b = mesh.vertices[static_cast<std::size_t>(t[1])];
    const auto& c = mesh.vertices[static_cast<std::size_t>(t[2])];
    const double x = (T::chart_x(a) + T::chart_x(b) + T::chart_x(c)) / 3;
    values.push_back(x < 0.2 ? 0.0 : 1.0 + x);
  }
  const auto density =
      mesh_density_per_triangle(this->geometry, std::span(mesh.vertices), std::span(mesh.triangles), std::span(values));
  const auto sites = T::random_sites(120, this->random);
  const auto start = evaluate(this->geometry, density, std::span(sites), this->geometry.default_weights(sites), false);
  int starved = 0;
  for (double m : start.masses) starved += m <= 0;
  ASSERT_GT(starved, 5);  // the test is about cells that start without mass
  Options options;
  options.tolerance = 1e-9;
  const auto result = solve(this->geometry, density, std::span(sites), this->varying_masses(120, 3), options);
  std::printf("  %d of 120 cells start without mass: %s\n", starved, result.summary.message.c_str());
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_NE(result.summary.message.find("continuation"), std::string::npos);
  const Eigen::VectorXd relative = (result.masses - result.target_masses).cwiseQuotient(result.target_masses);
  EXPECT_LE(relative.cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(result.masses.sum(), density.total_mass(), 1e-10 * density.total_mass());
  EXPECT_GT(result.masses.minCoeff(), 0.0);
  // value(): zero where the density vanishes, the piece's value elsewhere.
  for (std::size_t t = 0; t < mesh.triangles.size(); t += 7) {
    const auto& tri = mesh.triangles[t];
    const auto centroid = this->geometry.from_projective(
        this->geometry.to_projective(mesh.vertices[static_cast<std::size_t>(tri[0])]).normalized() +
        this->geometry.to_projective(mesh.vertices[static_cast<std::size_t>(tri[1])]).normalized() +
        this->geometry.to_projective(mesh.vertices[static_cast<std::size_t>(tri[2])]).normalized());
    EXPECT_DOUBLE_EQ(density.value(centroid), values[t]) << "triangle " << t;
  }
}

TYPED_TEST_P(PiecewiseConformance, BadInputNamesTheField) {
  using P = typename TestFixture::Point;
  const auto& mesh = this->test_mesh;
  auto values = this->vertex_values([](const P&) { return 1.0; });
  values[7] = -1;
  EXPECT_NE(input_error([&] {
              (void)mesh_density(this->geometry, std::span(mesh.vertices), std::span(mesh.triangles),
                                 std::span(values));
            }).find("density.values[7]: must be a finite number >= 0"),
            std::string::npos);
  values[7] = NAN;
  EXPECT_NE(input_error([&] {
              (void)mesh_density(this->geometry, std::span(mesh.vertices), std::span(mesh.triangles),
                                 std::span(values));
            }).find("density.values[7]"),
            std::string::npos);
  values[7] = 1;
  auto triangles = mesh.triangles;
  triangles[3][1] = static_cast<int>(mesh.vertices.size());
  EXPECT_NE(input_error([&] {
              (void)mesh_density(this->geometry, std::span(mesh.vertices), std::span(triangles), std::span(values));
            }).find("density.triangles[3]: vertex index"),
            std::string::npos);
  values.pop_back();
  EXPECT_NE(input_error([&] {
              (void)mesh_density(this->geometry, std::span(mesh.vertices), std::span(mesh.triangles),
                                 std::span(values));
            }).find("density.values: has"),
            std::string::npos);
  std::vector<DensityPiece<P>> pieces(1);
  pieces[0].polygon = {mesh.vertices[0], mesh.vertices[1]};
  EXPECT_NE(input_error([&] { PiecewiseDensity<TypeParam>(this->geometry, pieces); }).find("density.pieces[0]"),
            std::string::npos);
}

REGISTER_TYPED_TEST_SUITE_P(PiecewiseConformance, UnitMeshEqualsUniformDensity, ConstantLinearMeshEqualsFunctionDensity,
                            LinearMeshHessianMatchesFiniteDifferences, LinearMeshConvergesAndConservesMass,
                            ZeroDensityRegionConverges, BadInputNamesTheField);

}  // namespace sdot::testing
