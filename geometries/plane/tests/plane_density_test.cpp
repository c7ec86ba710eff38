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

#include <filesystem>

#include "sdot/geometries/plane_densities.hpp"

namespace sdot::testing {

namespace {
GrayImage test_image(int width, int height, unsigned seed, double zero_fraction = 0) {
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> uniform(0, 1);
  GrayImage image{width, height, {}};
  for (int k = 0; k < width * height; ++k)
    image.values.push_back(uniform(random) < zero_fraction ? 0 : 0.2 + uniform(random));
  return image;
}
std::vector<Plane::Point> sites_in_box(std::size_t n, double x0, double y0, double x1, double y1, unsigned seed) {
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> ux(x0, x1), uy(y0, y1);
  std::vector<Plane::Point> sites;
  while (sites.size() < n) sites.emplace_back(ux(random), uy(random));
  return sites;
}
}  // namespace

TEST(PlaneDensity, ConstantImageIsExactAndConverges) {
  const Plane plane(ConvexPolygon::rectangle(-1, 0, 2, 2));
  const GrayImage image = test_image(12, 8, 1);
  const auto density = image_density(plane, image, Eigen::AlignedBox2d(Eigen::Vector2d(-1, 0), Eigen::Vector2d(2, 2)),
                                     ImageInterpolation::constant);
  double expected = 0;
  for (double v : image.values) expected += v * 0.25 * 0.25;
  EXPECT_NEAR(density.total_mass(), expected, 1e-13 * expected);
  const auto sites = sites_in_box(200, -1, 0, 2, 2, 3);
  const Eigen::VectorXd masses = equal_masses(sites.size(), 1.0);
  const auto result = solve(plane, density, std::span<const Plane::Point>(sites), masses);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_NEAR(result.masses.sum(), expected, 1e-11 * expected);
  const double error = hessian_fd_error(
      plane, density, std::span<const Plane::Point>(sites).first(40),
      solved_weights(plane, density, std::span<const Plane::Point>(sites).first(40), equal_masses(40, 1.0)));
  std::printf("  constant image: Hessian vs finite differences %.2e\n", error);
  EXPECT_LT(error, 1e-6);
}

TEST(PlaneDensity, BilinearImageFromFileConvergesWithZeroPixels) {
  // Written and read back through the image reader, with 30% zero pixels.
  const auto path = std::filesystem::temp_directory_path() / "sdot_plane_density_test.pgm";
  write_pgm(path.string(), test_image(16, 16, 5, 0.3), true);
  const GrayImage image = read_image(path.string());
  std::filesystem::remove(path);
  const Plane plane;
  const auto density = image_density(plane, image, Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1)),
                                     ImageInterpolation::bilinear);
  GrayImage flat{16, 16, std::vector<double>(256, 0.5)};
  const auto flat_density = image_density(
      plane, flat, Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1)), ImageInterpolation::bilinear);
  EXPECT_NEAR(flat_density.total_mass(), 0.5, 1e-13);
  // The bilinear interpolant at pixel centres is the pixel value.
  EXPECT_NEAR(density.value(Plane::Point(5.5 / 16, 1 - 3.5 / 16)), image.at(3, 5), 1e-14);
  const auto sites = sites_in_box(150, 0, 0, 1, 1, 8);
  const auto result = solve(plane, density, std::span<const Plane::Point>(sites), equal_masses(sites.size(), 1.0));
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_LE(result.summary.max_relative_error, 1e-9);
  const auto few = std::span<const Plane::Point>(sites).first(30);
  // The steep interpolant has large third derivatives: a small step keeps the FD truncation
  // error (∝ δ², 3e-6 at δ = 1e-6) below the check.
  const double error =
      hessian_fd_error(plane, density, few, solved_weights(plane, density, few, equal_masses(30, 1.0)), 1e-7);
  std::printf("  bilinear image: Hessian vs finite differences %.2e\n", error);
  EXPECT_LT(error, 1e-6);
}

TEST(PlaneDensity, DomainWithHolesAndSitesInsideTheHoles) {
  // The square [0, 4]² minus two square holes; some sites lie in the holes.
  const PlaneRegion region(
      {PolygonWithHoles{{{0, 0}, {4, 0}, {4, 4}, {0, 4}},
                        {{{1, 1}, {1, 2}, {2, 2}, {2, 1}}, {{2.5, 2.5}, {2.5, 3.5}, {3.5, 3.5}, {3.5, 2.5}}}}});
  const Plane plane(ConvexPolygon::rectangle(0, 0, 4, 4));
  const auto density = region_density(plane, region);
  EXPECT_NEAR(density.total_mass(), 14, 1e-12);
  const auto sites = sites_in_box(300, 0, 0, 4, 4, 13);
  const auto result = solve(plane, density, std::span<const Plane::Point>(sites), equal_masses(sites.size(), 1.0));
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_LE(result.summary.max_relative_error, 1e-9);
  EXPECT_NEAR(result.masses.sum(), 14, 1e-10);
  const auto few = std::span<const Plane::Point>(sites).first(40);
  const double region_error =
      hessian_fd_error(plane, density, few, solved_weights(plane, density, few, equal_masses(40, 1.0)));
  std::printf("  uniform density on a domain with holes: Hessian vs finite differences %.2e\n", region_error);
  EXPECT_LT(region_error, 1e-6);
  // A density restricted to the region: ∫ over the region only.
  const GrayImage image = test_image(8, 8, 21);
  const auto on_square = image_density(plane, image, Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(4, 4)),
                                       ImageInterpolation::constant);
  const auto restricted = on_square.restricted_to(region.convex_pieces());
  double expected = 0;
  for (int r = 0; r < 8; ++r)
    for (int c = 0; c < 8; ++c) {
      const Plane::Point center((c + 0.5) * 0.5, 4 - (r + 0.5) * 0.5);
      // Pixels are 0.5 wide; the holes are unions of whole pixels.
      if (region.contains(center)) expected += image.at(r, c) * 0.25;
    }
  EXPECT_NEAR(restricted.total_mass(), expected, 1e-12 * expected);
  const auto restricted_result =
      solve(plane, restricted, std::span<const Plane::Point>(sites), equal_masses(sites.size(), 1.0));
  ASSERT_TRUE(restricted_result.summary.converged()) << restricted_result.summary.message;
}

}  // namespace sdot::testing
namespace sdot::testing {

TEST(PlaneDensity, RestrictedImageHessianMatchesFiniteDifferences) {
  // Pixels cut by the region's pieces: clipping through pixel corners once produced corner
  // duplicates whose edge had no direction, and the pieces were lost from the masses only.
  const PlaneRegion region({PolygonWithHoles{{{0, 0}, {4, 0}, {4, 4}, {0, 4}}, {{{1, 1}, {1, 2}, {2, 2}, {2, 1}}}}});
  const Plane plane(ConvexPolygon::rectangle(0, 0, 4, 4));
  const GrayImage image = test_image(32, 32, 5);
  const auto sites = sites_in_box(40, 0, 0, 4, 4, 8);
  const auto span = std::span<const Plane::Point>(sites);
  for (auto interpolation : {ImageInterpolation::constant, ImageInterpolation::bilinear}) {
    const auto restricted =
        image_density(plane, image, Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(4, 4)), interpolation)
            .restricted_to(region.convex_pieces());
    if (interpolation == ImageInterpolation::constant) {
      EXPECT_EQ(restricted.piece_count(), 32u * 32u - 8u * 8u);
    }
    const double error =
        hessian_fd_error(plane, restricted, span, solved_weights(plane, restricted, span, equal_masses(40, 1.0)), 1e-7);
    std::printf("  restricted %s image: Hessian vs finite differences %.2e\n",
                interpolation == ImageInterpolation::constant ? "constant" : "bilinear", error);
    EXPECT_LT(error, 1e-6);
  }
}

}  // namespace sdot::testing
