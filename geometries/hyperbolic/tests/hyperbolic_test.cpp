// The hyperbolic plane: conformance suite plus H²-specific cases (closed forms, exact integrals
// against quadrature and the angle defect, Lorentz-boost invariance, far domains, bad input).
#include <gtest/gtest.h>

#include <numbers>
#include <random>

#include "conformance/conformance.hpp"
#include "conformance/partial_conformance.hpp"
#include "sdot/geometries/hyperbolic.hpp"
#include "sdot/quadrature.hpp"
#include "sdot/solver.hpp"

namespace sdot::testing {

namespace {
using Point = Hyperbolic::Point;

/// Sites uniform in hyperbolic area over the geometry's domain.
std::vector<Point> random_sites_in(const Hyperbolic& g, std::size_t n, std::mt19937_64& random) {
  return g.uniform_samples(n, random());
}

/// Area of a geodesic polygon by the angle defect (n − 2)π − Σα (independent of the VOS formula).
double angle_defect_area(const std::vector<Point>& v) {
  const std::size_t n = v.size();
  double angles = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const Point& a = v[k];
    auto tangent = [&](const Point& b) {
      const Point t = b + Hyperbolic::minkowski(a, b) * a;
      return Point(t / std::sqrt(Hyperbolic::minkowski(t, t)));
    };
    const Point p = tangent(v[(k + n - 1) % n]), q = tangent(v[(k + 1) % n]);
    angles += std::acos(std::clamp(Hyperbolic::minkowski(p, q), -1.0, 1.0));
  }
  return (static_cast<double>(n) - 2) * std::numbers::pi - angles;
}

Hyperbolic klein_pentagon() {
  const std::vector<Eigen::Vector2d> vertices{{-0.55, -0.5}, {0.6, -0.45}, {0.7, 0.2}, {0.1, 0.65}, {-0.6, 0.3}};
  return Hyperbolic::from_klein(vertices);
}
}  // namespace

template <>
struct ConformanceTraits<Hyperbolic> {
  static Hyperbolic geometry() { return klein_pentagon(); }
  static std::vector<Point> random_sites(std::size_t n, std::mt19937_64& random) {
    return random_sites_in(geometry(), n, random);
  }
  static TwoSiteCase<Hyperbolic> two_site_case() {
    // Sites at chart points (±s, 0) over the chart square [−a, a]²; ν₀ = area{k₁ ≥ c} by the
    // angle defect: h₀ − h₁ = ln((1 − cs)/(1 + cs)) (math.md §4.3).
    const double a = 0.6, s = 0.3, c = 0.17;
    auto area = [](std::vector<Eigen::Vector2d> klein) {
      std::vector<Point> v;
      for (const auto& k : klein) v.push_back(Hyperbolic::from_klein(k));
      return angle_defect_area(v);
    };
    Eigen::VectorXd masses(2);
    masses << area({{c, -a}, {a, -a}, {a, a}, {c, a}}), area({{-a, -a}, {c, -a}, {c, a}, {-a, a}});
    const std::vector<Eigen::Vector2d> square{{-a, -a}, {a, -a}, {a, a}, {-a, a}};
    return {Hyperbolic::from_klein(square),
            {Hyperbolic::from_klein(Eigen::Vector2d(s, 0)), Hyperbolic::from_klein(Eigen::Vector2d(-s, 0))},
            masses,
            std::log((1 - c * s) / (1 + c * s))};
  }
  static ScalarField<Point> smooth_density() {
    return [](const Point& x) { return 1 + 0.6 * std::sin(2 * x.x()) * std::cos(3 * x.y()); };
  }
};

INSTANTIATE_TYPED_TEST_SUITE_P(Hyperbolic, GeometryConformance, ::testing::Types<Hyperbolic>);

template <>
struct PartialTraits<Hyperbolic> {
  static double disc_area(double radius) { return 2 * std::numbers::pi * (std::cosh(radius) - 1); }
  static std::vector<Point> separate_sites() {
    return {Hyperbolic::from_klein({0.0, 0.0}), Hyperbolic::from_klein({0.3, 0.1}),
            Hyperbolic::from_klein({-0.2, 0.25})};
  }
  /// The point at fraction t of the arc from a to b around the site, by a Lorentz rotation: boost
  /// the site to the origin, turn about the x₃ axis, boost back.
  static Point arc_point(const Point& site, const Point& a, const Point& b, double t) {
    const Eigen::Matrix3d to_site = Hyperbolic::boost_to(site), from_site = Hyperbolic::lorentz_inverse(to_site);
    const Point la = from_site * a, lb = from_site * b;
    double angle = std::atan2(la.x() * lb.y() - la.y() * lb.x(), la.x() * lb.x() + la.y() * lb.y());
    if (angle < 0) angle += 2 * std::numbers::pi;
    const double c = std::cos(t * angle), s = std::sin(t * angle);
    return to_site * Point(c * la.x() - s * la.y(), s * la.x() + c * la.y(), la.z());
  }
};
INSTANTIATE_TYPED_TEST_SUITE_P(Hyperbolic, PartialConformance, ::testing::Types<Hyperbolic>);

namespace {

Cell<Point> cell_of(const std::vector<Eigen::Vector2d>& klein) {
  Cell<Point> cell;
  for (const auto& k : klein) cell.vertices.push_back(Hyperbolic::from_klein(k));
  cell.neighbors.assign(klein.size(), -1);
  return cell;
}

/// High-order reference integrals over a cell (fan from vertex 0, 40² points per triangle).
CellIntegrals<Point> reference_integrals(const Hyperbolic& g, const Cell<Point>& cell, const Point& site) {
  return g.integrate(
      cell, site, [](const Point&) { return 1.0; }, 40);
}

TEST(Hyperbolic, UniformSamplesFollowTheHyperbolicArea) {
  // The samples' mean must be the domain's exact first moment over its area (Monte Carlo).
  const Hyperbolic g = Hyperbolic::regular_polygon(6, 1.2, Hyperbolic::polar(1.0, 0.5));
  Cell<Point> whole{g.domain(), std::vector<int>(g.domain().size(), -1)};
  const auto exact = g.integrate(whole, g.center());
  const auto samples = g.uniform_samples(40000, 3);
  Point mean = Point::Zero();
  for (const auto& x : samples) mean += x / static_cast<double>(samples.size());
  const Point expected = exact.first_moment / exact.mass;
  EXPECT_LT((mean - expected).norm(), 0.02 * expected.norm()) << mean.transpose() << " vs " << expected.transpose();
  EXPECT_EQ(samples.front(), g.uniform_samples(1, 3).front());  // deterministic per seed
}

TEST(Hyperbolic, CoordinateConversions) {
  const Eigen::Vector2d k(0.3, -0.5);
  const Point x = Hyperbolic::from_klein(k);
  EXPECT_NEAR(Hyperbolic::minkowski(x, x), -1, 1e-15);
  EXPECT_LT((Hyperbolic::to_klein(x) - k).norm(), 1e-15);
  const Eigen::Vector2d p = Hyperbolic::to_poincare(x);
  EXPECT_LT((Hyperbolic::from_poincare(p) - x).norm(), 1e-14);
  // Klein k = 2p / (1 + |p|²).
  EXPECT_LT((k - 2 * p / (1 + p.squaredNorm())).norm(), 1e-15);
  EXPECT_NEAR(Hyperbolic::distance(Point(0, 0, 1), Hyperbolic::polar(2.5, 1)), 2.5, 1e-14);
  const Eigen::Matrix3d l = Hyperbolic::boost_to(Hyperbolic::polar(3, 0.4));
  EXPECT_LT((l * Hyperbolic::lorentz_inverse(l) - Eigen::Matrix3d::Identity()).norm(), 1e-13);
  EXPECT_LT((l * Point(0, 0, 1) - Hyperbolic::polar(3, 0.4)).norm(), 1e-13);
}

TEST(Hyperbolic, ExactIntegralsMatchQuadratureAndAngleDefect) {
  const auto g = klein_pentagon();
  for (const auto& klein : std::vector<std::vector<Eigen::Vector2d>>{
           {{0.1, 0}, {0.5, 0.2}, {0.4, 0.6}, {0.0, 0.5}},          // moderate
           {{-0.8, -0.5}, {0.85, -0.4}, {0.7, 0.6}, {-0.7, 0.65}},  // large, near the ideal boundary
           {{0.3, 0.3}, {0.305, 0.3}, {0.302, 0.304}}}) {           // tiny
    const auto cell = cell_of(klein);
    for (const Point& site : {Point(Hyperbolic::from_klein(Eigen::Vector2d(0.2, 0.3))), Hyperbolic::polar(4, 2)}) {
      const auto exact = g.integrate(cell, site);
      const auto reference = reference_integrals(g, cell, site);
      EXPECT_NEAR(exact.mass, angle_defect_area(cell.vertices), 1e-13 * (1 + exact.mass));
      EXPECT_NEAR(exact.mass, reference.mass, 1e-12 * exact.mass);
      EXPECT_LT((exact.first_moment - reference.first_moment).norm(), 1e-12 * reference.first_moment.norm());
      EXPECT_NEAR(exact.cost, reference.cost, 1e-12 * std::abs(reference.cost)) << klein[0].transpose();
      // The centroid lies inside the cell (its Klein point is in the Klein polygon).
      const Eigen::Vector2d c = Hyperbolic::to_klein(g.centroid(exact));
      for (std::size_t k = 0; k < klein.size(); ++k) {
        const Eigen::Vector2d e = klein[(k + 1) % klein.size()] - klein[k], d = c - klein[k];
        EXPECT_GT(e.x() * d.y() - e.y() * d.x(), 0);
      }
    }
  }
}

TEST(Hyperbolic, FunctionDensityQuadratureIsAccurate) {
  // ρ = 1 + ⟨β, x⟩_M is ambient-affine: its mass is exactly Area + ⟨β, M⟩_M.
  const auto g = klein_pentagon();
  const auto cell = cell_of({{-0.6, -0.4}, {0.5, -0.5}, {0.6, 0.3}, {-0.2, 0.6}});
  const Point beta(0.3, -0.2, 0.1);
  const auto exact = g.integrate(cell, Point(0, 0, 1));
  const auto quadrature = g.integrate(
      cell, Point(0, 0, 1), [&](const Point& x) { return 1 + Hyperbolic::minkowski(beta, x); }, 24);
  EXPECT_NEAR(quadrature.mass, exact.mass + Hyperbolic::minkowski(beta, exact.first_moment), 1e-12 * exact.mass);
}

TEST(Hyperbolic, TwoSitesAtAnyDistance) {
  // The §4.3 closed form, with the whole configuration boosted 3 units away.
  const auto c = ConformanceTraits<Hyperbolic>::two_site_case();
  const Eigen::Matrix3d l = Hyperbolic::boost_to(Hyperbolic::polar(3, 1.1));
  std::vector<Point> domain, sites;
  for (const auto& v : c.geometry.domain()) domain.push_back(l * v);
  for (const auto& s : c.sites) sites.push_back(l * s);
  Options options;
  options.tolerance = 1e-12;
  const auto result = solve(Hyperbolic(domain), UniformDensity{}, std::span<const Point>(sites), c.masses, options);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_NEAR(result.weights[0] - result.weights[1], c.expected_weight_difference, 1e-10);
}

TEST(Hyperbolic, LorentzBoostInvariance) {
  const auto g = klein_pentagon();
  std::mt19937_64 random(4);
  const auto sites = random_sites_in(g, 200, random);
  Eigen::VectorXd masses(200);
  for (Eigen::Index i = 0; i < 200; ++i) masses[i] = 1 + 0.02 * static_cast<double>(i);
  Options options;
  options.tolerance = 1e-11;
  const auto a = solve(g, UniformDensity{}, std::span<const Point>(sites), masses, options);
  ASSERT_TRUE(a.summary.converged()) << a.summary.message;

  const Eigen::Matrix3d l = Hyperbolic::boost_to(Hyperbolic::polar(1.7, -2.3));
  std::vector<Point> domain, boosted;
  for (const auto& v : g.domain()) domain.push_back(l * v);
  for (const auto& s : sites) boosted.push_back(l * s);
  const Hyperbolic moved(domain);
  EXPECT_NEAR(moved.domain_area(), g.domain_area(), 1e-13 * g.domain_area());
  const auto b = solve(moved, UniformDensity{}, std::span<const Point>(boosted), masses, options);
  ASSERT_TRUE(b.summary.converged()) << b.summary.message;
  EXPECT_LT((a.weights - b.weights).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(a.transport_cost, b.transport_cost, 1e-11 * a.transport_cost);
  double worst = 0;
  for (std::size_t i = 0; i < sites.size(); ++i)
    worst = std::max(worst, Hyperbolic::distance(l * a.centroids[i], b.centroids[i]));
  EXPECT_LT(worst, 1e-10);
  EXPECT_EQ(a.adjacency(), b.adjacency());
}

TEST(Hyperbolic, FarDomainConvergesTo1e10) {
  // A source centred at hyperbolic distance 3 from the chart origin (Klein radius tanh 3 ≈ 0.995).
  const auto g = Hyperbolic::regular_polygon(7, 1.2, Hyperbolic::polar(3, 0.7));
  EXPECT_NEAR(Hyperbolic::distance(g.center(), Point(0, 0, 1)), 3, 1e-12);
  std::mt19937_64 random(9);
  const auto sites = random_sites_in(g, 2000, random);
  Eigen::VectorXd masses(2000);
  std::uniform_real_distribution<double> uniform(1, 10);
  for (auto& m : masses) m = uniform(random);
  Options options;
  options.tolerance = 1e-10;
  const auto result = solve(g, UniformDensity{}, std::span<const Point>(sites), masses, options);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_LE(result.summary.max_relative_error, 1e-10);
  EXPECT_NEAR(result.masses.sum(), g.domain_area(), 1e-12 * g.domain_area());
  // The regular 7-gon's area by the angle defect.
  EXPECT_NEAR(g.domain_area(), angle_defect_area(g.domain()), 1e-12);
}

TEST(Hyperbolic, SitesFarOutsideTheDomain) {
  const auto g = klein_pentagon();
  std::mt19937_64 random(5);
  std::uniform_real_distribution<double> radius(0, 6), angle(0, 2 * std::numbers::pi);
  std::vector<Point> sites(150);
  for (auto& s : sites) s = Hyperbolic::polar(radius(random), angle(random));
  const auto result = solve(g, UniformDensity{}, std::span<const Point>(sites), equal_masses(150));
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  for (const auto& c : result.centroids)
    EXPECT_TRUE(g.chart_domain().contains(Hyperbolic::to_klein(Hyperbolic::lorentz_inverse(g.boost()) * c), 1e-12));
}

TEST(Hyperbolic, CellsAreLaguerreCellsThroughWarmStartedBuilds) {
  // One object keeps its last triangulation (of the sites' Klein points) for the next weights:
  // every build must give the cells of a build from scratch (a fresh object), and those must be
  // the Laguerre cells: at each vertex the cell's site has the lowest cost − weight of all sites
  // (brute force), tied with the neighbour across each edge.
  const auto g = Hyperbolic::regular_polygon(8, 1.5);
  std::mt19937_64 random(9);
  std::vector<Point> sites = random_sites_in(g, 1200, random);
  std::uniform_real_distribution<double> radius(0, 5), angle(0, 2 * std::numbers::pi);
  for (int k = 0; k < 100; ++k) sites.push_back(Hyperbolic::polar(radius(random), angle(random)));  // some far out
  const auto n = static_cast<Eigen::Index>(sites.size());
  std::normal_distribution<double> normal(0, 1);
  std::vector<Eigen::VectorXd> steps{g.default_weights(sites)};
  for (double sigma : {1e-4, 1e-4, 1e-6}) {  // cells are about 0.05 across: ln cosh d ≈ d²/2 ~ 1e-3
    Eigen::VectorXd next = steps.back();
    for (auto& w : next) w += sigma * normal(random);
    steps.push_back(next);
  }
  steps.push_back(steps.back());
  steps.back()[17] -= 0.05;  // site 17 hidden: an empty cell
  steps.push_back(steps[2]);
  for (std::size_t step = 0; step < steps.size(); ++step) {
    SCOPED_TRACE("step " + std::to_string(step));
    const Eigen::VectorXd& w = steps[step];
    const auto warm = g.build_diagram(sites, w);
    const auto cold = Hyperbolic::regular_polygon(8, 1.5).build_diagram(sites, w);
    std::size_t empty = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto& cell = warm.cells[static_cast<std::size_t>(i)];
      ASSERT_EQ(cell.vertices, cold.cells[static_cast<std::size_t>(i)].vertices) << "cell " << i;
      ASSERT_EQ(cell.neighbors, cold.cells[static_cast<std::size_t>(i)].neighbors) << "cell " << i;
      empty += cell.empty();
      for (std::size_t k = 0; k < cell.size(); ++k) {
        const Point& x = cell.vertices[k];
        const double own = Hyperbolic::cost(x, sites[static_cast<std::size_t>(i)]) - w[i];
        double lowest = own;
        for (Eigen::Index j = 0; j < n; ++j)
          lowest = std::min(lowest, Hyperbolic::cost(x, sites[static_cast<std::size_t>(j)]) - w[j]);
        ASSERT_LT(own - lowest, 1e-9) << "cell " << i << ", vertex " << k;
        for (const std::size_t end : {k, (k + 1) % cell.size()}) {
          const int j = cell.neighbors[k];
          if (is_boundary(j)) continue;
          const Point& y = cell.vertices[end];
          EXPECT_NEAR(Hyperbolic::cost(y, sites[static_cast<std::size_t>(i)]) - w[i],
                      Hyperbolic::cost(y, sites[static_cast<std::size_t>(j)]) - w[j], 1e-9)
              << "cell " << i << ", edge " << k;
        }
      }
    }
    EXPECT_LT(empty, 100u);  // at most the sites far out, and site 17 at step 4
    EXPECT_EQ(warm.cells[17].empty(), step == 4);
  }
}

TEST(Hyperbolic, DefaultWeightsGiveNonEmptyCells) {
  const auto g = Hyperbolic::regular_polygon(5, 0.8, Hyperbolic::polar(1, 2));
  std::mt19937_64 random(6);
  std::uniform_real_distribution<double> radius(0, 8), angle(0, 2 * std::numbers::pi);
  std::vector<Point> sites(300);
  for (auto& s : sites) s = Hyperbolic::polar(radius(random), angle(random));
  const auto evaluation = evaluate(g, UniformDensity{}, std::span<const Point>(sites), g.default_weights(sites), false);
  EXPECT_GT(evaluation.masses.minCoeff(), 0);
}

TEST(Hyperbolic, QuadratureHessianOnAFarDomain) {
  const auto g = Hyperbolic::regular_polygon(6, 1, Hyperbolic::polar(2, 0.3));
  std::mt19937_64 random(8);
  const auto sites = random_sites_in(g, 20, random);
  const FunctionDensity<Point> density{[](const Point& x) { return 2 + std::cos(x.x() + 0.5 * x.y()); }, 10};
  const Eigen::VectorXd weights = solved_weights(g, density, std::span<const Point>(sites), equal_masses(20));
  const double quadrature = hessian_fd_error(g, density, std::span<const Point>(sites), weights);
  const double exact = hessian_fd_error(g, UniformDensity{}, std::span<const Point>(sites), weights);
  std::printf("  far domain: Hessian vs FD, exact %.2e, quadrature %.2e\n", exact, quadrature);
  EXPECT_LT(exact, 1e-7);
  EXPECT_LT(quadrature, 1e-6);
}

TEST(Hyperbolic, FunctionDensityEqualToOneMatchesUniform) {
  const auto g = klein_pentagon();
  std::mt19937_64 random(2);
  const auto sites = random_sites_in(g, 100, random);
  const auto uniform = solve(g, UniformDensity{}, std::span<const Point>(sites), equal_masses(100));
  const FunctionDensity<Point> one{[](const Point&) { return 1.0; }, 8};
  const auto function = solve(g, one, std::span<const Point>(sites), equal_masses(100));
  ASSERT_TRUE(function.summary.converged()) << function.summary.message;
  EXPECT_LT((uniform.weights - function.weights).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_NEAR(uniform.transport_cost, function.transport_cost, 1e-10 * uniform.transport_cost);
}

// ---- bad input -------------------------------------------------------------------------

TEST(HyperbolicBadInput, PointsOnOrOutsideTheIdealBoundary) {
  const std::vector<Eigen::Vector2d> on{{0, 0}, {1, 0}, {0, 0.5}};
  EXPECT_EQ(input_error([&] { Hyperbolic::from_klein(on); }).rfind("domain[1]: Klein point lies on or outside", 0), 0u);
  const std::vector<Eigen::Vector2d> outside{{0, 0}, {0.5, 0}, {0.3, 0.5}, {-0.8, 0.9}};
  EXPECT_EQ(
      input_error([&] { Hyperbolic::from_poincare(outside); }).rfind("domain[3]: Poincare point lies on or outside", 0),
      0u);
  EXPECT_EQ(input_error([] {
              Hyperbolic::from_klein(Eigen::Vector2d(0.6, -0.8), "sites[5]");
            }).rfind("sites[5]: Klein point lies on or outside the ideal boundary", 0),
            0u);
}

TEST(HyperbolicBadInput, NonFiniteAndOffTheHyperboloid) {
  const auto g = klein_pentagon();
  std::vector<Point> sites{Point(0, 0, 1), Point(NAN, 0, 1), Point(0.1, 0, 1)};
  EXPECT_EQ(input_error([&] { solve(g, UniformDensity{}, std::span<const Point>(sites), equal_masses(3)); }),
            "sites[1]: coordinate is not finite");
  sites[1] = Point(0.5, 0.5, 1);  // ⟨x, x⟩_M = −0.5
  sites[2] = Hyperbolic::polar(1, 1);
  EXPECT_EQ(input_error([&] {
              solve(g, UniformDensity{}, std::span<const Point>(sites), equal_masses(3));
            }).rfind("sites[1]: point is not on the hyperboloid", 0),
            0u);
  sites[1] = -Hyperbolic::polar(1, 2);  // lower sheet
  EXPECT_EQ(input_error([&] {
              solve(g, UniformDensity{}, std::span<const Point>(sites), equal_masses(3));
            }).rfind("sites[1]: point is not on the hyperboloid", 0),
            0u);
  sites[1] = sites[2];
  EXPECT_EQ(input_error([&] { solve(g, UniformDensity{}, std::span<const Point>(sites), equal_masses(3)); }),
            "sites[2]: duplicate of sites[1]");
  const std::vector<Eigen::Vector2d> nan_domain{{0, 0}, {0.5, NAN}, {0, 0.5}};
  EXPECT_EQ(input_error([&] { Hyperbolic::from_klein(nan_domain); }), "domain[1]: coordinate is not finite");
}

TEST(HyperbolicBadInput, DegenerateDomains) {
  const std::vector<Eigen::Vector2d> two{{0, 0}, {0.5, 0}};
  EXPECT_EQ(input_error([&] { Hyperbolic::from_klein(two); }).rfind("domain:", 0), 0u);
  const std::vector<Eigen::Vector2d> flat{{-0.5, 0}, {0, 0}, {0.5, 0}};
  EXPECT_EQ(input_error([&] { Hyperbolic::from_klein(flat); }), "domain: polygon is degenerate (zero area)");
  const std::vector<Eigen::Vector2d> concave{{-0.5, -0.5}, {0.5, -0.5}, {0, -0.3}, {0, 0.5}};
  EXPECT_NE(input_error([&] { Hyperbolic::from_klein(concave); }).find("not convex"), std::string::npos);
  const std::vector<Point> off{Point(0, 0, 1), Point(0.5, 0, 1), Hyperbolic::polar(0.5, 2)};
  EXPECT_EQ(input_error([&] { Hyperbolic h(off); }).rfind("domain[1]: point is not on the hyperboloid", 0), 0u);
}

}  // namespace
}  // namespace sdot::testing
