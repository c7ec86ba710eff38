// The sphere: conformance suite (whole sphere, cap, polygon) plus closed forms (math.md §4.2),
// degenerate configurations, rotation invariance, densities, builders and bad input.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <numbers>
#include <random>

#include "conformance/conformance.hpp"
#include "conformance/partial_conformance.hpp"
#include "sdot/geometries/sphere.hpp"
#include "sdot/quadrature.hpp"
#include "sdot/solver.hpp"

namespace sdot {

/// The sphere restricted to a cap, as its own type for the typed conformance suite.
struct SphereCap : Sphere {
  SphereCap() : Sphere(Sphere::cap(Point(1, 2, 3).normalized(), 0.8)) {}
  explicit SphereCap(Sphere sphere) : Sphere(std::move(sphere)) {}
};
/// The sphere restricted to a convex spherical polygon.
struct SpherePolygon : Sphere {
  SpherePolygon()
      : Sphere(Sphere::polygon({{1, 0.1, 0.2}, {0.3, 1, 0.1}, {-0.2, 0.5, 0.9}, {0.2, -0.4, 1}, {0.8, -0.5, 0.3}})) {}
  explicit SpherePolygon(Sphere sphere) : Sphere(std::move(sphere)) {}
};

namespace testing {
namespace {

constexpr double pi = std::numbers::pi;
using Vec = Sphere::Point;

Vec random_unit(std::mt19937_64& random) {
  std::normal_distribution<double> normal(0, 1);
  Vec v;
  do v = Vec(normal(random), normal(random), normal(random));
  while (v.norm() < 1e-3);
  return v.normalized();
}

std::vector<Vec> random_sphere(std::size_t n, unsigned seed) {
  std::mt19937_64 random(seed);
  std::vector<Vec> sites(n);
  for (auto& s : sites) s = random_unit(random);
  return sites;
}

/// Sites uniform in the region {x : inside(x)} by rejection.
template <class Inside>
std::vector<Vec> random_in(std::size_t n, std::mt19937_64& random, Inside&& inside) {
  std::vector<Vec> sites;
  while (sites.size() < n)
    if (const Vec v = random_unit(random); inside(v)) sites.push_back(v);
  return sites;
}

/// Spherical area of the gnomonic chart rectangle [x0, x1] × [y0, y1] at e_z (closed form).
double chart_rectangle_area(double x0, double y0, double x1, double y1) {
  auto f = [](double x, double y) { return std::atan(x * y / std::sqrt(1 + x * x + y * y)); };
  return f(x1, y1) - f(x0, y1) - f(x1, y0) + f(x0, y0);
}

/// Area of {k₁ ≥ c} inside the chart disk of radius ρ (cap of angle atan ρ around e_z):
/// (2/√(1+ρ²)) ∫_c^ρ √(ρ² − k²)/(1 + k²) dk, with k = ρ sin θ, by Gauss–Legendre.
double cap_slice_area(double c, double rho) {
  const double t0 = std::asin(c / rho), t1 = pi / 2;
  double integral = 0;
  for (const auto& node : gauss_legendre(60)) {
    const double t = t0 + node.x * (t1 - t0), s = std::sin(t), co = std::cos(t);
    integral += node.weight * rho * rho * co * co / (1 + rho * rho * s * s);
  }
  return 2 / std::sqrt(1 + rho * rho) * integral * (t1 - t0);
}

}  // namespace

template <>
struct ConformanceTraits<Sphere> {
  static Sphere geometry() { return Sphere(); }
  static std::vector<Vec> random_sites(std::size_t n, std::mt19937_64& random) {
    return random_in(n, random, [](const Vec&) { return true; });
  }
  static TwoSiteCase<Sphere> two_site_case() {
    // math.md §4.3: sites at chart points (±s, 0) over the chart square [−a, a]² at e_z.
    const double a = 0.9, s = 0.35, c = 0.2;
    Eigen::VectorXd masses(2);
    masses << chart_rectangle_area(c, -a, a, a), chart_rectangle_area(-a, -a, c, a);
    Sphere square = Sphere::polygon({{-a, -a, 1}, {a, -a, 1}, {a, a, 1}, {-a, a, 1}});
    return {
        square, {Vec(s, 0, 1).normalized(), Vec(-s, 0, 1).normalized()}, masses, std::log((1 - c * s) / (1 + c * s))};
  }
  static ScalarField<Vec> smooth_density() {
    return [](const Vec& x) { return 1 + 0.5 * std::sin(3 * x.x()) * std::cos(2 * x.y()) + 0.3 * x.z(); };
  }
};

template <>
struct ConformanceTraits<SphereCap> {
  static SphereCap geometry() { return SphereCap(); }
  static std::vector<Vec> random_sites(std::size_t n, std::mt19937_64& random) {
    const SphereCap g;
    const double cos_angle = std::cos(g.cap_angle());
    return random_in(n, random, [&](const Vec& v) { return v.dot(g.center()) > cos_angle; });
  }
  static TwoSiteCase<SphereCap> two_site_case() {
    const double angle = 0.7, s = 0.3, c = 0.15;
    const double rho = std::tan(angle);
    const double total = 4 * pi * std::pow(std::sin(angle / 2), 2);
    Eigen::VectorXd masses(2);
    masses << cap_slice_area(c, rho), total - cap_slice_area(c, rho);
    return {SphereCap(Sphere::cap(Vec::UnitZ(), angle)),
            {Vec(s, 0, 1).normalized(), Vec(-s, 0, 1).normalized()},
            masses,
            std::log((1 - c * s) / (1 + c * s))};
  }
  static ScalarField<Vec> smooth_density() {
    return [](const Vec& x) { return 1 + 0.6 * std::sin(4 * x.x() + x.z()) * std::cos(3 * x.y()); };
  }
};

template <>
struct ConformanceTraits<SpherePolygon> {
  static SpherePolygon geometry() { return SpherePolygon(); }
  static std::vector<Vec> random_sites(std::size_t n, std::mt19937_64& random) {
    const SpherePolygon g;
    const auto& v = g.polygon_vertices();
    return random_in(n, random, [&](const Vec& x) {
      for (std::size_t k = 0; k < v.size(); ++k)
        if (v[k].cross(v[(k + 1) % v.size()]).dot(x) <= 0) return false;
      return true;
    });
  }
  static TwoSiteCase<SpherePolygon> two_site_case() {
    auto base = ConformanceTraits<Sphere>::two_site_case();
    return {SpherePolygon(base.geometry), base.sites, base.masses, base.expected_weight_difference};
  }
  static ScalarField<Vec> smooth_density() { return ConformanceTraits<Sphere>::smooth_density(); }
};

INSTANTIATE_TYPED_TEST_SUITE_P(Sphere, GeometryConformance, ::testing::Types<Sphere>);
INSTANTIATE_TYPED_TEST_SUITE_P(SphereCap, GeometryConformance, ::testing::Types<SphereCap>);
INSTANTIATE_TYPED_TEST_SUITE_P(SpherePolygon, GeometryConformance, ::testing::Types<SpherePolygon>);

/// The partial-transport traits of the whole sphere and of the cap (whose cells have both the
/// cap's arcs and the balls' arcs).
struct SpherePartialTraits {
  static double disc_area(double radius) { return 4 * pi * std::pow(std::sin(radius / 2), 2); }
  static Vec arc_point(const Vec& site, const Vec& a, const Vec& b, double t) {
    const Vec p = site.normalized();
    double angle = std::atan2(p.dot(a.cross(b)), a.dot(b) - a.dot(p) * b.dot(p));
    if (angle < 0) angle += 2 * pi;
    const Vec radial = a - a.dot(p) * p;
    return a.dot(p) * p + std::cos(t * angle) * radial + std::sin(t * angle) * p.cross(radial);
  }
};
template <>
struct PartialTraits<Sphere> : SpherePartialTraits {
  static std::vector<Vec> separate_sites() {
    return {Vec(1, 1, 1).normalized(), Vec(1, -1, -1).normalized(), Vec(-1, 1, -1).normalized(),
            Vec(-1, -1, 1).normalized()};
  }
};
template <>
struct PartialTraits<SphereCap> : SpherePartialTraits {
  static std::vector<Vec> separate_sites() {
    const SphereCap cap;
    const Eigen::Matrix3d frame = Eigen::Quaterniond::FromTwoVectors(Vec::UnitZ(), cap.center()).toRotationMatrix();
    const double r = 0.5 * std::tan(cap.cap_angle());
    return {cap.center(), (frame * Vec(r, 0, 1)).normalized(), (frame * Vec(-r, 0.2 * r, 1)).normalized()};
  }
};
INSTANTIATE_TYPED_TEST_SUITE_P(Sphere, PartialConformance, ::testing::Types<Sphere>);
INSTANTIATE_TYPED_TEST_SUITE_P(SphereCap, PartialConformance, ::testing::Types<SphereCap>);

namespace {

Eigen::VectorXd zeros(std::size_t n) {
  return Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n));
}

/// Off-diagonal facet weights by pair (i < j) of an evaluation.
std::map<std::pair<int, int>, double> pair_weights(const Evaluation<Vec>& e) {
  std::map<std::pair<int, int>, double> weights;
  for (const auto& t : e.facet_weights) weights[{std::min(t.row(), t.col()), std::max(t.row(), t.col())}] += t.value();
  return weights;
}

std::vector<Vec> octahedron() {
  return {Vec::UnitX(), -Vec::UnitX(), Vec::UnitY(), -Vec::UnitY(), Vec::UnitZ(), -Vec::UnitZ()};
}

std::vector<Vec> cube() {
  std::vector<Vec> sites;
  for (int k = 0; k < 8; ++k) sites.push_back(Vec(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1).normalized());
  return sites;
}

// ---- closed forms ----------------------------------------------------------------------

TEST(SphereClosedForms, OctahedronHessianIsLaplacianOverSqrt3) {
  for (auto builder : {Sphere::Builder::clipping, Sphere::Builder::hull}) {
    Sphere sphere;
    sphere.set_builder(builder);
    const auto sites = octahedron();
    const auto e = evaluate(sphere, UniformDensity{}, std::span(sites), zeros(6), true);
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(e.masses[i], 4 * pi / 6, 1e-14);
    const auto weights = pair_weights(e);
    int edges = 0;
    for (int i = 0; i < 6; ++i)
      for (int j = i + 1; j < 6; ++j) {
        const bool antipodal = sites[i].dot(sites[j]) < -0.5;
        const double w = weights.contains({i, j}) ? weights.at({i, j}) : 0.0;
        EXPECT_NEAR(w, antipodal ? 0 : 1 / std::sqrt(3.0), 1e-14) << i << "," << j;
        edges += !antipodal;
      }
    EXPECT_EQ(edges, 12);
  }
}

TEST(SphereClosedForms, CubeHessianIsTheGraphLaplacianWithAnExactFiniteDifference) {
  for (auto builder : {Sphere::Builder::clipping, Sphere::Builder::hull}) {
    Sphere sphere;
    sphere.set_builder(builder);
    const auto sites = cube();
    const auto e = evaluate(sphere, UniformDensity{}, std::span(sites), zeros(8), true);
    for (int i = 0; i < 8; ++i) EXPECT_NEAR(e.masses[i], pi / 2, 1e-14);
    const auto weights = pair_weights(e);
    for (int i = 0; i < 8; ++i)
      for (int j = i + 1; j < 8; ++j) {
        const bool edge = std::abs(sites[i].dot(sites[j]) - 1.0 / 3) < 1e-12;  // cube edge
        const double w = weights.contains({i, j}) ? weights.at({i, j}) : 0.0;
        EXPECT_NEAR(w, edge ? 1.0 : 0.0, 1e-13) << i << "," << j;
      }
    // The degenerate vertices (4 cells meet at each face centre) must not lose entries.
    // O(δ) at the degenerate vertices (see CoCircularSitesHaveAnExactHessian): δ = 1e-7.
    const double error = hessian_fd_error(sphere, UniformDensity{}, std::span(sites), zeros(8), 1e-7);
    std::printf("  cube (%s): Hessian vs finite differences %.2e\n",
                builder == Sphere::Builder::hull ? "hull" : "clipping", error);
    EXPECT_LT(error, 3e-8);
  }
}

TEST(SphereClosedForms, BipyramidPoleHeights) {
  // n equatorial sites and two poles; pole mass A ⇔ H = h_pole − h_equator with
  // A = 2n·arccos(sin(π/n)/√(1+e^{2H})) − (n−2)π (math.md §4.2).
  for (int n : {3, 4, 5, 7}) {
    for (double height : {-0.3, 0.1, 0.4}) {
      const double pole = 2 * n * std::acos(std::sin(pi / n) / std::sqrt(1 + std::exp(2 * height))) - (n - 2) * pi;
      std::vector<Vec> sites{Vec::UnitZ(), -Vec::UnitZ()};
      Eigen::VectorXd masses(n + 2);
      masses[0] = masses[1] = pole;
      for (int k = 0; k < n; ++k) {
        sites.emplace_back(std::cos(2 * pi * k / n), std::sin(2 * pi * k / n), 0);
        masses[k + 2] = (4 * pi - 2 * pole) / n;
      }
      Options options;
      options.tolerance = 1e-13;
      const auto result = solve(Sphere(), UniformDensity{}, std::span(sites), masses, options);
      ASSERT_TRUE(result.summary.converged()) << "n = " << n << ": " << result.summary.message;
      EXPECT_NEAR(result.weights[0] - result.weights[2], height, 1e-12) << "n = " << n;
      EXPECT_NEAR(result.weights[1] - result.weights[n + 1], height, 1e-12) << "n = " << n;
    }
  }
}

TEST(SphereClosedForms, OctahedronPoleFormula) {
  // Octahedron (n = 4): H = ½ ln((tan²((A + 2π)/8) − 1)/2).
  const double pole = 2.5;
  const double height = 0.5 * std::log((std::pow(std::tan((pole + 2 * pi) / 8), 2) - 1) / 2);
  const auto sites = octahedron();  // ±x, ±y, ±z: poles are ±z (indices 4, 5)
  Eigen::VectorXd masses = Eigen::VectorXd::Constant(6, (4 * pi - 2 * pole) / 4);
  masses[4] = masses[5] = pole;
  Options options;
  options.tolerance = 1e-13;
  const auto result = solve(Sphere(), UniformDensity{}, std::span(sites), masses, options);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_NEAR(result.weights[4] - result.weights[0], height, 1e-12);
}

TEST(SphereClosedForms, VoronoiAreasGiveConstantHeights) {
  const auto sites = random_sphere(400, 17);
  const auto voronoi = evaluate(Sphere(), UniformDensity{}, std::span(sites), zeros(400), false);
  EXPECT_NEAR(voronoi.masses.sum(), 4 * pi, 1e-12);
  std::mt19937_64 random(3);
  std::normal_distribution<double> normal(0, 1e-5);
  Eigen::VectorXd start(400);
  for (auto& w : start) w = normal(random);
  Options options;
  options.tolerance = 1e-13;
  const auto result = solve(Sphere(), UniformDensity{}, std::span(sites), voronoi.masses, options, start);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  const double spread = result.weights.maxCoeff() - result.weights.minCoeff();
  std::printf("  height spread %.2e after %d iterations\n", spread, result.summary.iterations);
  EXPECT_LT(spread, 1e-12);
}

// ---- exact integrals -------------------------------------------------------------------

// The cost of cells within tan²θ ≤ 10⁻³ of their site (from about 10⁴ sites on) comes from
// edge integrals of a series, each tier of it (t ≤ 10⁻⁵, 10⁻⁴, 10⁻³) exercised by some N here;
// the larger weight spread moves sites outside their cells, where the fan from p is signed.
TEST(SphereIntegrals, ExactFormulasMatchHighOrderQuadrature) {
  for (const auto& [n, spread] : {std::pair<std::size_t, double>{8, 0.1},
                                  {30, 0.1},
                                  {3000, 0.1},
                                  {20000, 0.1},
                                  {20000, 4.0},
                                  {100000, 0.1},
                                  {100000, 4.0},
                                  {400000, 0.1}}) {
    const auto sites = random_sphere(n, 5);
    Eigen::VectorXd weights(n);
    std::mt19937_64 random(1);
    std::uniform_real_distribution<double> uniform(-spread / n, spread / n);
    for (auto& w : weights) w = uniform(random);
    const Sphere sphere;
    double worst = 0;
    int outside = 0;
    const auto diagram = sphere.build_diagram(sites, weights);
    const ScalarField<Vec> one = [](const Vec&) { return 1.0; };
    for (std::size_t i = 0; i < sites.size(); ++i) {
      if (diagram.cells[i].empty()) continue;
      const auto exact = sphere.integrate(diagram.cells[i], sites[i]);
      const auto quadrature = sphere.integrate(diagram.cells[i], sites[i], one, 30);
      EXPECT_NEAR(exact.mass, quadrature.mass, 2e-14 * quadrature.mass);
      // The moment's Stokes sum (½ L n_in over edges ~√mass long) cancels to ~1e-19 absolute on slivers.
      EXPECT_NEAR((exact.first_moment - quadrature.first_moment).norm(), 0, 2e-13 * quadrature.mass + 1e-18);
      EXPECT_NEAR(exact.cost, quadrature.cost, 1e-13 * quadrature.cost);
      worst = std::max(worst, std::abs(exact.cost - quadrature.cost) / quadrature.cost);
      outside += (exact.first_moment.normalized() - sites[i].normalized()).norm() >
                 std::sqrt(exact.mass / pi);  // the site is farther from the centroid than the cell's radius
      if (n > 1000 && i > 2000) break;
    }
    std::printf("  N = %zu, weight spread %g/N: cost quadrature relative error %.2e, %d sites off their cell\n", n,
                spread, worst, outside);
  }
}

TEST(SphereIntegrals, CapCellsMatchHighOrderQuadrature) {
  const SphereCap cap;
  std::mt19937_64 random(4);
  const auto sites = ConformanceTraits<SphereCap>::random_sites(12, random);
  const auto diagram = cap.build_diagram(sites, cap.default_weights(sites));
  const ScalarField<Vec> one = [](const Vec&) { return 1.0; };
  double total = 0;
  int arcs = 0;
  for (std::size_t i = 0; i < sites.size(); ++i) {
    ASSERT_FALSE(diagram.cells[i].empty());
    for (int label : diagram.cells[i].neighbors) arcs += cap.is_circle_arc(label);
    const auto exact = cap.integrate(diagram.cells[i], sites[i]);
    const auto quadrature = cap.integrate(diagram.cells[i], sites[i], one, 30);
    total += exact.mass;
    EXPECT_NEAR(exact.mass, quadrature.mass, 1e-14);
    EXPECT_NEAR((exact.first_moment - quadrature.first_moment).norm(), 0, 1e-14);
    EXPECT_NEAR(exact.cost, quadrature.cost, 1e-12 * quadrature.cost);
  }
  EXPECT_GT(arcs, 0);
  EXPECT_NEAR(total, cap.domain_area(), 1e-14);
}

TEST(SphereIntegrals, SingleSiteOwnsTheCap) {
  const Sphere cap = Sphere::cap(Vec(0, 1, 1).normalized(), 1.2);
  const std::vector<Vec> sites{Vec(0.1, 1, 0.9)};
  const auto result = solve(cap, UniformDensity{}, std::span(sites), Eigen::VectorXd::Ones(1));
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_NEAR(result.masses[0], 2 * pi * (1 - std::cos(1.2)), 1e-14);
  EXPECT_NEAR((result.centroids[0] - cap.center()).norm(), 0, 1e-14);
  const auto integrals = cap.integrate(result.diagram.cells[0], sites[0]);
  EXPECT_NEAR(integrals.first_moment.norm(), pi * std::pow(std::sin(1.2), 2), 1e-14);
}

TEST(SphereIntegrals, TransportCostOfAHemisphereCapAroundItsSite) {
  // ∫_cap(α) −ln cos θ dA = 2π ∫₀^α −ln(cos θ) sin θ dθ = 2π [u − u ln u]_{cos α}^{1}.
  const double angle = 1.1, u = std::cos(angle);
  const Sphere cap = Sphere::cap(Vec::UnitZ(), angle);
  const std::vector<Vec> sites{Vec::UnitZ()};
  const auto diagram = cap.build_diagram(sites, zeros(1));
  const double cost = cap.integrate(diagram.cells[0], sites[0]).cost;
  EXPECT_NEAR(cost, 2 * pi * (1 - (u - u * std::log(u))), 1e-13);
}

// ---- the solver on the sphere ----------------------------------------------------------

TEST(SphereSolver, FiveThousandSitesWithMassesVarying100x) {
  const auto sites = random_sphere(5000, 21);
  std::mt19937_64 random(8);
  std::uniform_real_distribution<double> uniform(0, 1);
  Eigen::VectorXd masses(5000);
  for (auto& m : masses) m = std::pow(100.0, uniform(random));
  Options options;
  options.tolerance = 1e-10;
  const auto result = solve(Sphere(), UniformDensity{}, std::span(sites), masses, options);
  std::printf("  %s in %d iterations, %.3f s\n", result.summary.message.c_str(), result.summary.iterations,
              result.summary.timings.total_s);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_LE(result.summary.max_relative_error, 1e-10);
  EXPECT_NEAR(result.masses.sum(), 4 * pi, 1e-10);
}

// 1000 of 3000 sites crushed into a cap 0.05 rad wide, equal masses: from the Voronoi start the
// first steps are short, and once the cluster has spread, steps of ¾ pass where the full step
// does not (the test fails without the ¾ trial). Every step is 1, ¾ or a power of 2, and each
// solve converges.
TEST(SphereSolver, ThreeQuarterStepsAreTriedBetweenTheFullStepAndHalfOfIt) {
  int three_quarter_steps = 0;
  for (unsigned seed = 1; seed <= 6; ++seed) {
    std::mt19937_64 random(seed);
    std::vector<Vec> sites(2000);
    for (auto& s : sites) s = random_unit(random);
    while (sites.size() < 3000)
      if (const Vec v = random_unit(random); v.z() > std::cos(0.05)) sites.push_back(v);
    const Eigen::VectorXd masses = Eigen::VectorXd::Ones(3000);
    const auto result = solve(Sphere(), UniformDensity{}, std::span(sites), masses, Options{});
    ASSERT_TRUE(result.summary.converged()) << "seed " << seed << ": " << result.summary.message;
    for (std::size_t k = 1; k < result.summary.history.size(); ++k) {
      const double step = result.summary.history[k].step;
      int exponent = 0;
      EXPECT_TRUE(step == 0.75 || std::frexp(step, &exponent) == 0.5) << "seed " << seed << ", step " << step;
      three_quarter_steps += step == 0.75;
    }
  }
  EXPECT_GE(three_quarter_steps, 2);
}

TEST(SphereSolver, CoCircularSitesHaveAnExactHessian) {
  // Latitude rings: every 4 sites on two neighbouring rings are co-circular, so Laguerre
  // vertices are degenerate and the hull (Qt) has zero-length edges.
  std::vector<Vec> sites{Vec::UnitZ(), -Vec::UnitZ()};
  for (double z : {-0.6, 0.0, 0.6}) {
    const double r = std::sqrt(1 - z * z);
    for (int k = 0; k < 10; ++k) sites.emplace_back(r * std::cos(2 * pi * k / 10), r * std::sin(2 * pi * k / 10), z);
  }
  for (auto builder : {Sphere::Builder::clipping, Sphere::Builder::hull}) {
    Sphere sphere;
    sphere.set_builder(builder);
    // At a degenerate vertex the masses are C¹ but their second derivative jumps (the vertex
    // splits one way for +δ, the other for −δ), so the central difference is only O(δ) accurate:
    // measured 4.1e-6, 4.1e-7, 4.1e-8 for δ = 1e-5, 1e-6, 1e-7. A dropped entry would be O(1).
    const double error = hessian_fd_error(sphere, UniformDensity{}, std::span(sites), zeros(sites.size()), 1e-7);
    std::printf("  co-circular: Hessian vs finite differences (δ = 1e-7) %.2e\n", error);
    EXPECT_LT(error, 1e-7);
    Eigen::VectorXd masses = Eigen::VectorXd::LinSpaced(static_cast<Eigen::Index>(sites.size()), 1, 3);
    Options options;
    options.tolerance = 1e-12;
    const auto result = solve(sphere, UniformDensity{}, std::span(sites), masses, options);
    EXPECT_TRUE(result.summary.converged()) << result.summary.message;
  }
}

TEST(SphereSolver, RotationInvariance) {
  const auto sites = random_sphere(300, 2);
  Eigen::VectorXd masses = Eigen::VectorXd::LinSpaced(300, 1, 10);
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(0.7, Vec(1, -2, 0.5).normalized()).toRotationMatrix();
  std::vector<Vec> rotated;
  for (const auto& s : sites) rotated.push_back(rotation * s);
  Options options;
  options.tolerance = 1e-12;
  const auto a = solve(Sphere(), UniformDensity{}, std::span(sites), masses, options);
  const auto b = solve(Sphere(), UniformDensity{}, std::span(rotated), masses, options);
  ASSERT_TRUE(a.summary.converged() && b.summary.converged());
  EXPECT_LT((a.weights - b.weights).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_NEAR(a.transport_cost, b.transport_cost, 1e-12);
  for (std::size_t i = 0; i < sites.size(); ++i) EXPECT_LT((rotation * a.centroids[i] - b.centroids[i]).norm(), 1e-10);
  EXPECT_EQ(a.adjacency(), b.adjacency());
}

TEST(SphereSolver, TransportCostIsSkippedOnRequest) {
  const auto sites = random_sphere(300, 4);
  const Eigen::VectorXd masses = Eigen::VectorXd::LinSpaced(300, 1, 10);
  Options options;
  options.tolerance = 1e-10;
  const auto with_cost = solve(Sphere(), UniformDensity{}, std::span(sites), masses, options);
  options.compute_transport_cost = false;
  const auto without = solve(Sphere(), UniformDensity{}, std::span(sites), masses, options);
  ASSERT_TRUE(with_cost.summary.converged() && without.summary.converged());
  EXPECT_TRUE(std::isfinite(with_cost.transport_cost));
  EXPECT_GT(with_cost.transport_cost, 0);
  EXPECT_TRUE(std::isnan(without.transport_cost));
  // Nothing else changes.
  EXPECT_EQ(with_cost.weights, without.weights);
  for (std::size_t i = 0; i < sites.size(); ++i) EXPECT_EQ(with_cost.centroids[i], without.centroids[i]);
}

TEST(SphereSolver, NonUniformDensityConvergesWithAnFDCheckedHessian) {
  const auto sites = random_sphere(400, 6);
  const FunctionDensity<Vec> density{[](const Vec& x) { return 1 + 0.9 * x.z(); }, 8};
  Options options;
  options.tolerance = 1e-9;
  const auto result = solve(Sphere(), density, std::span(sites), equal_masses(400), options);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  // ρ is ambient-affine: ∫ρ = 4π exactly (∫z = 0).
  EXPECT_NEAR(result.summary.source_mass, 4 * pi, 1e-11);
  // Denser cells are smaller: the cells in the north have less area.
  const auto uniform = evaluate(Sphere(), UniformDensity{}, std::span(sites), result.weights, false);
  for (std::size_t i = 0; i < sites.size(); ++i)
    if (sites[i].z() > 0.8) {
      EXPECT_LT(uniform.masses[i], 4 * pi / 400);
    }
  const auto small = random_sphere(40, 7);
  const auto w = solve(Sphere(), density, std::span(small), equal_masses(40)).weights;
  const double error = hessian_fd_error(Sphere(), density, std::span(small), w);
  std::printf("  ρ = 1 + 0.9z: Hessian vs finite differences %.2e\n", error);
  EXPECT_LT(error, 1e-6);
}

TEST(SphereSolver, AffineDensityMatchesExactMoments) {
  // ρ = α + ⟨β, x⟩ integrates exactly as α·Area + ⟨β, M⟩ (math.md §2).
  const auto sites = random_sphere(50, 12);
  const Sphere sphere;
  const auto diagram = sphere.build_diagram(sites, zeros(50));
  const Vec beta(0.2, -0.5, 0.9);
  const ScalarField<Vec> rho = [&](const Vec& x) { return 1 + beta.dot(x); };
  for (std::size_t i = 0; i < sites.size(); ++i) {
    const auto exact = sphere.integrate(diagram.cells[i], sites[i]);
    const auto quadrature = sphere.integrate(diagram.cells[i], sites[i], rho, 8);
    EXPECT_NEAR(quadrature.mass, exact.mass + beta.dot(exact.first_moment), 1e-13);
  }
}

namespace {
/// Heights ~ N(0, sigma²), seeded.
Eigen::VectorXd random_heights(Eigen::Index n, double sigma, unsigned seed) {
  std::mt19937_64 random(seed);
  std::normal_distribution<double> normal(0, sigma);
  Eigen::VectorXd heights(n);
  for (auto& h : heights) h = normal(random);
  return heights;
}

/// The clipping builder and the hull builder give the same diagram for these heights.
void expect_builders_agree(const Sphere& clipping, const Sphere& hull, const std::vector<Vec>& sites,
                           const Eigen::VectorXd& heights) {
  const auto a = evaluate(clipping, UniformDensity{}, std::span(sites), heights, true);
  const auto b = evaluate(hull, UniformDensity{}, std::span(sites), heights, true);
  EXPECT_LT((a.masses - b.masses).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(adjacency(a.diagram), adjacency(b.diagram));
  EXPECT_LT((dense_hessian(a) - dense_hessian(b)).cwiseAbs().maxCoeff(), 1e-12);
}

Sphere with_builder(Sphere::Builder builder) {
  Sphere sphere;
  sphere.set_builder(builder);
  return sphere;
}
}  // namespace

TEST(SphereSolver, BuildersAgree) {
  // The fast clipping builder against the Qhull hull of e^{h}p (the paper's construction).
  const auto sites = random_sphere(3000, 31);
  Eigen::VectorXd weights = random_heights(3000, 2e-4, 2);
  for (int k = 0; k < 3000; k += 300) weights[k] += 0.01;  // a few large cells: some empty ones
  expect_builders_agree(with_builder(Sphere::Builder::clipping), with_builder(Sphere::Builder::hull), sites, weights);
}

TEST(SphereSolver, BuildersAgreeOnCocircularSites) {
  // Degenerate hulls for the default (hull) builder: every face of the cube has four co-circular
  // sites, and a latitude–longitude grid has co-circular quadruples everywhere and two poles of
  // high degree. Masses must match the certified clipping builder, also after a solve.
  std::vector<std::vector<Vec>> cases{octahedron(), cube()};
  std::vector<Vec> grid{Vec::UnitZ(), -Vec::UnitZ()};
  for (int i = 1; i < 20; ++i)
    for (int j = 0; j < 40; ++j) {
      const double polar = std::numbers::pi * i / 20, azimuth = 2 * std::numbers::pi * j / 40;
      grid.emplace_back(std::sin(polar) * std::cos(azimuth), std::sin(polar) * std::sin(azimuth), std::cos(polar));
    }
  cases.push_back(grid);
  const Sphere hull = with_builder(Sphere::Builder::automatic), clipping = with_builder(Sphere::Builder::clipping);
  for (const auto& sites : cases) {
    SCOPED_TRACE(std::to_string(sites.size()) + " sites");
    const auto n = static_cast<Eigen::Index>(sites.size());
    const auto a = evaluate(clipping, UniformDensity{}, std::span(sites), Eigen::VectorXd::Zero(n), false);
    const auto b = evaluate(hull, UniformDensity{}, std::span(sites), Eigen::VectorXd::Zero(n), false);
    EXPECT_LT((a.masses - b.masses).cwiseAbs().maxCoeff(), 1e-13);
    Eigen::VectorXd targets(n);
    for (Eigen::Index i = 0; i < n; ++i) targets[i] = 2 + sites[static_cast<std::size_t>(i)].z();
    targets *= 4 * std::numbers::pi / targets.sum();
    const auto by_hull = solve(hull, UniformDensity{}, std::span(sites), targets);
    const auto by_clipping = solve(clipping, UniformDensity{}, std::span(sites), targets);
    ASSERT_TRUE(by_hull.summary.converged()) << by_hull.summary.message;
    ASSERT_TRUE(by_clipping.summary.converged()) << by_clipping.summary.message;
    EXPECT_LT((by_hull.weights - by_clipping.weights).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(SphereSolver, HullBuilderUpdatesItsHullAcrossEvaluations) {
  // One Sphere object keeps its last hull and updates it for the next heights: flips, a vertex
  // removed where a cell empties, a point inserted where it comes back. Every evaluation must
  // equal the clipping builder's.
  const auto sites = random_sphere(3000, 41);
  const Sphere hull = with_builder(Sphere::Builder::hull), clipping = with_builder(Sphere::Builder::clipping);
  const Eigen::VectorXd weights = random_heights(3000, 1e-4, 3);
  {
    SCOPED_TRACE("first hull (grown by insertion)");
    expect_builders_agree(clipping, hull, sites, weights);
  }
  const Eigen::VectorXd moved = weights + random_heights(3000, 1e-4, 4);
  {
    SCOPED_TRACE("heights moved (flips)");
    expect_builders_agree(clipping, hull, sites, moved);
  }
  Eigen::VectorXd emptied = moved;
  emptied[17] -= 0.05;  // site 17's cell empties: its point falls inside the hull
  {
    SCOPED_TRACE("a cell emptied (a vertex removed)");
    expect_builders_agree(clipping, hull, sites, emptied);
    EXPECT_TRUE(hull.build_diagram(std::span(sites), emptied).cells[17].empty());
    // a caller that rejects empty cells gets no cells at all, and the hull stays cached
    const auto stopped = hull.build_diagram(std::span(sites), emptied, true);
    EXPECT_TRUE(std::all_of(stopped.cells.begin(), stopped.cells.end(), [](const auto& c) { return c.empty(); }));
  }
  {
    SCOPED_TRACE("back, from a hull that misses a point (inserted again)");
    expect_builders_agree(clipping, hull, sites, moved);
    // with no empty cell (zero heights: the Voronoi diagram), stopping changes nothing
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(3000);
    const auto full = hull.build_diagram(std::span(sites), zero, true);
    EXPECT_EQ(adjacency(full), adjacency(clipping.build_diagram(std::span(sites), zero)));
    EXPECT_TRUE(std::none_of(full.cells.begin(), full.cells.end(), [](const auto& c) { return c.empty(); }));
  }
  // a whole solve on one object: every Newton step and trial after the first reuses the hull
  Eigen::VectorXd targets(3000);
  for (Eigen::Index i = 0; i < 3000; ++i) targets[i] = 1 + 0.5 * std::sin(3 * sites[static_cast<std::size_t>(i)].z());
  targets *= 4 * std::numbers::pi / targets.sum();
  const auto by_hull = solve(hull, UniformDensity{}, std::span(sites), targets);
  const auto by_clipping = solve(clipping, UniformDensity{}, std::span(sites), targets);
  ASSERT_TRUE(by_hull.summary.converged()) << by_hull.summary.message;
  ASSERT_TRUE(by_clipping.summary.converged()) << by_clipping.summary.message;
  EXPECT_EQ(by_hull.summary.iterations, by_clipping.summary.iterations);
  EXPECT_LT((by_hull.weights - by_clipping.weights).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(SphereSolver, SitesInOneHemisphereOfACap) {
  // A chart builder only needs each domain point within π/2 of some site (math.md §5).
  const Sphere cap = Sphere::cap(Vec::UnitZ(), 0.3);
  std::mt19937_64 random(9);
  const auto sites = random_in(50, random, [](const Vec& v) { return v.z() > std::cos(0.25); });
  const auto result = solve(cap, UniformDensity{}, std::span(sites), equal_masses(50));
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_NEAR(result.masses.sum(), cap.domain_area(), 1e-14);
}

// ---- bad input -------------------------------------------------------------------------

TEST(SphereBadInput, ZeroVector) {
  auto sites = random_sphere(10, 1);
  sites[4] = Vec::Zero();
  EXPECT_EQ(input_error([&] { solve(Sphere(), UniformDensity{}, std::span(sites), equal_masses(10)); }),
            "sites[4]: is the zero vector (a site is a direction in R³)");
}

TEST(SphereBadInput, NonFiniteCoordinate) {
  auto sites = random_sphere(10, 1);
  sites[7] = Vec(0.1, NAN, 1);
  EXPECT_EQ(input_error([&] { solve(Sphere(), UniformDensity{}, std::span(sites), equal_masses(10)); }),
            "sites[7]: coordinate is not finite");
  sites[7] = Vec(INFINITY, 0, 1);
  EXPECT_EQ(input_error([&] { solve(Sphere(), UniformDensity{}, std::span(sites), equal_masses(10)); }),
            "sites[7]: coordinate is not finite");
}

TEST(SphereBadInput, DuplicateAfterNormalisation) {
  auto sites = random_sphere(10, 1);
  sites[8] = 3 * sites[2];
  EXPECT_EQ(input_error([&] { solve(Sphere(), UniformDensity{}, std::span(sites), equal_masses(10)); }),
            "sites[8]: duplicate of sites[2] (after normalisation)");
  // Many sites (a fine grid, searched in its bin order): the lowest index with an earlier twin.
  auto many = random_sphere(20000, 2);
  many[15000] = 2 * many[40];
  many[9000] = many[17000];
  EXPECT_EQ(input_error([&] { solve(Sphere(), UniformDensity{}, std::span(many), equal_masses(20000)); }),
            "sites[15000]: duplicate of sites[40] (after normalisation)");
}

TEST(SphereBadInput, HemisphereCondition) {
  // All sites with z ≥ 0 (a closed hemisphere, some on its boundary).
  std::vector<Vec> sites{Vec::UnitX(), Vec::UnitY(), -Vec::UnitX(), -Vec::UnitY(), Vec(1, 1, 1).normalized()};
  const auto message = input_error([&] { solve(Sphere(), UniformDensity{}, std::span(sites), equal_masses(5)); });
  EXPECT_EQ(message.rfind("sites: all sites lie in a closed hemisphere", 0), 0u) << message;
  // Strictly inside an open hemisphere, many sites.
  std::mt19937_64 random(1);
  const auto north = random_in(200, random, [](const Vec& v) { return v.z() > 0.05; });
  EXPECT_EQ(input_error([&] {
              solve(Sphere(), UniformDensity{}, std::span(north), equal_masses(200));
            }).rfind("sites: all sites lie in a closed hemisphere", 0),
            0u);
  // Fewer than 4 sites always lie in a closed hemisphere.
  const std::vector<Vec> three{Vec::UnitX(), Vec::UnitY(), -Vec(1, 1, 0).normalized()};
  EXPECT_EQ(input_error([&] {
              solve(Sphere(), UniformDensity{}, std::span(three), equal_masses(3));
            }).rfind("sites: all sites lie in a closed hemisphere", 0),
            0u);
  // A tetrahedron is fine.
  const std::vector<Vec> tetra{Vec(1, 1, 1), Vec(1, -1, -1), Vec(-1, 1, -1), Vec(-1, -1, 1)};
  EXPECT_TRUE(solve(Sphere(), UniformDensity{}, std::span(tetra), equal_masses(4)).summary.converged());
}

TEST(SphereBadInput, DomainNotCoveredBySites) {
  const Sphere cap = Sphere::cap(Vec::UnitZ(), 1.2);
  const std::vector<Vec> sites{Vec(1, 0, 0.05), Vec(0.9, 0.3, 0.1)};  // far side of the cap unseen
  EXPECT_EQ(input_error([&] {
              solve(cap, UniformDensity{}, std::span(sites), equal_masses(2));
            }).rfind("sites: part of the source domain is at distance >= π/2 from every site", 0),
            0u);
}

TEST(SphereBadInput, Domains) {
  EXPECT_EQ(input_error([] { Sphere::cap(Vec::UnitZ(), 2.0); }).rfind("domain.angle:", 0), 0u);
  EXPECT_EQ(input_error([] { Sphere::cap(Vec::Zero(), 0.5); }), "domain.center: is the zero vector");
  EXPECT_EQ(input_error([] { Sphere::polygon({{1, 0, 1}, {0, 1, 1}}); }).rfind("domain:", 0), 0u);
  EXPECT_EQ(input_error([] {
              Sphere::polygon({{0, 0, 1}, {1, 0, 1}, {0.5, 0.1, 1}, {0.5, 1, 1}});
            }),
            "domain[2]: polygon is not convex at this vertex");
  EXPECT_EQ(input_error([] {
              Sphere::polygon({{1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}});
            }).rfind("domain", 0),
            0u);
}

}  // namespace
}  // namespace testing
}  // namespace sdot
