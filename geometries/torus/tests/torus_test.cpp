// The periodic plane: conformance suite plus torus cases (translation invariance, agreement with
// a 3 × 3 tiling of the plane, wrapping, tiny N, one periodic axis, densities, bad input).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "conformance/conformance.hpp"
#include "sdot/geometries/plane.hpp"
#include "sdot/geometries/plane_densities.hpp"
#include "sdot/geometries/torus.hpp"
#include "sdot/geometries/torus_densities.hpp"
#include "sdot/solver.hpp"

namespace sdot::testing {

template <>
struct ConformanceTraits<Torus> {
  static Torus geometry() {
    return Torus(Eigen::AlignedBox2d(Torus::Point(-0.3, 0.2), Torus::Point(1.7, 1.4)), {true, true});
  }
  static std::vector<Torus::Point> random_sites(std::size_t n, std::mt19937_64& random) {
    std::uniform_real_distribution<double> x(-0.3, 1.7), y(0.2, 1.4);
    std::vector<Torus::Point> sites(n);
    for (auto& s : sites) s = {x(random), y(random)};
    return sites;
  }
  static TwoSiteCase<Torus> two_site_case() {
    // [−a, a]² periodic, sites (±s, 0): the cells are vertical strips, bounded by the bisector
    // x = −d/(2s) and, across the side, x = a + d/(2(a − s)) (d = w₀ − w₁); strip 0 is a − c wide
    // for d = −2cs(a − s)/a.
    const double a = 1, s = 0.3, c = 0.27;
    Eigen::VectorXd masses(2);
    masses << 2 * a * (a - c), 2 * a * (a + c);
    return {Torus(Eigen::AlignedBox2d(Torus::Point(-a, -a), Torus::Point(a, a)), {true, true}),
            {{s, 0}, {-s, 0}},
            masses,
            -2 * c * s * (a - s) / a};
  }
  static ScalarField<Torus::Point> smooth_density() {
    // Periodic in the box, so smooth across its sides too.
    return [](const Torus::Point& x) {
      return 1 +
             0.8 * std::sin(std::numbers::pi * (x.x() + 0.3)) * std::cos(2 * std::numbers::pi * (x.y() - 0.2) / 1.2);
    };
  }
};

INSTANTIATE_TYPED_TEST_SUITE_P(Torus, GeometryConformance, ::testing::Types<Torus>);

namespace {

using Point = Torus::Point;

std::vector<Point> random_points(std::size_t n, unsigned seed, double low = 0, double high = 1) {
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> uniform(low, high);
  std::vector<Point> points(n);
  for (auto& p : points) p = {uniform(random), uniform(random)};
  return points;
}

Eigen::VectorXd random_masses(std::size_t n, unsigned seed, double ratio, double total) {
  std::mt19937_64 random(seed);
  Eigen::VectorXd masses = log_uniform_masses(n, ratio, random);
  return masses * (total / masses.sum());
}

/// The distance on the unit torus between two points.
double torus_distance(const Point& a, const Point& b) {
  return std::sqrt(2 * Torus().cost(a, b));
}

Options tight(double tolerance = 1e-11) {
  Options options;
  options.tolerance = tolerance;
  return options;
}

TEST(Torus, WrapAndCost) {
  const Torus torus;
  EXPECT_EQ(torus.wrap(Point(0.3, 0.7)), Point(0.3, 0.7));  // inside: unchanged
  EXPECT_NEAR((torus.wrap(Point(1.25, -0.5)) - Point(0.25, 0.5)).norm(), 0, 1e-15);
  EXPECT_EQ(torus.wrap(Point(1, 0)), Point(0, 0));  // the upper side is the lower one
  EXPECT_NEAR((torus.wrap(Point(-7.75, 13.5)) - Point(0.25, 0.5)).norm(), 0, 1e-14);
  const Point w = torus.wrap(Point(-1e-18, 0.5));
  EXPECT_TRUE(w.x() >= 0 && w.x() < 1) << w.x();
  EXPECT_NEAR(torus.cost(Point(0.05, 0.5), Point(0.95, 0.5)), 0.1 * 0.1 / 2, 1e-15);
  EXPECT_NEAR(torus.cost(Point(0.05, 0.05), Point(0.95, 0.95)), 0.1 * 0.1, 1e-15);
  // x periodic only: y is not wrapped, and the cost is the plane's along y.
  const Torus cylinder(Eigen::AlignedBox2d(Point(0, 0), Point(2, 1)), {true, false});
  EXPECT_EQ(cylinder.wrap(Point(2.5, 3)), Point(0.5, 3));
  EXPECT_NEAR(cylinder.cost(Point(0.1, 0.1), Point(1.9, 0.9)), (0.04 + 0.64) / 2, 1e-15);
}

TEST(Torus, UniformVoronoiMassesSumToTheBoxArea) {
  const Torus torus(Eigen::AlignedBox2d(Point(-1, 2), Point(1.5, 3)), {true, true});
  const auto sites = random_points(500, 3, -1, 3);  // many outside the box: wrapped
  const auto evaluation =
      evaluate(torus, UniformDensity{}, std::span<const Point>(sites), torus.default_weights(sites), false);
  EXPECT_NEAR(evaluation.masses.sum(), 2.5, 1e-12);
  EXPECT_GT(evaluation.masses.minCoeff(), 0);
}

// Moving every site by the same vector changes nothing but the cells' positions.
TEST(Torus, TranslationInvariance) {
  const std::size_t n = 300;
  const auto sites = random_points(n, 5);
  const Eigen::VectorXd masses = random_masses(n, 6, 20, 1);
  const auto reference = solve(Torus(), UniformDensity{}, std::span<const Point>(sites), masses, tight());
  ASSERT_TRUE(reference.summary.converged()) << reference.summary.message;
  for (const Point& translation : {Point(0.37, 0.81), Point(-2.4, 0.5), Point(1, -3)}) {
    std::vector<Point> moved(n);
    for (std::size_t i = 0; i < n; ++i) moved[i] = sites[i] + translation;
    const auto result = solve(Torus(), UniformDensity{}, std::span<const Point>(moved), masses, tight());
    ASSERT_TRUE(result.summary.converged()) << result.summary.message;
    // Both weight vectors have mean zero, so they agree without a constant.
    EXPECT_LT((result.weights - reference.weights).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LT(((result.masses - reference.masses).array() / masses.array()).abs().maxCoeff(), 1e-10);
    EXPECT_NEAR(result.transport_cost, reference.transport_cost, 1e-12);
    for (std::size_t i = 0; i < n; ++i) {
      EXPECT_TRUE(Eigen::AlignedBox2d(Point(0, 0), Point(1, 1)).contains(result.centroids[i]));
      EXPECT_LT(torus_distance(result.centroids[i], reference.centroids[i] + translation), 1e-9) << i;
    }
  }
}

/// The periodic weights, repeated over a 3 × 3 tiling of the plane, give the plane's power
/// diagram whose central tile is the periodic diagram (cells, masses, centroids, Hessian).
TEST(Torus, CentralTileOfATilingIsThePeriodicDiagram) {
  const std::size_t n = 200;
  const auto sites = random_points(n, 7);
  const Eigen::VectorXd masses = random_masses(n, 8, 30, 1);
  const auto periodic = solve(Torus(), UniformDensity{}, std::span<const Point>(sites), masses, tight());
  ASSERT_TRUE(periodic.summary.converged()) << periodic.summary.message;
  std::vector<Point> tiled;
  Eigen::VectorXd tiled_weights(9 * static_cast<Eigen::Index>(n));
  for (int tile = 0; tile < 9; ++tile)
    for (std::size_t i = 0; i < n; ++i) {
      tiled_weights[static_cast<Eigen::Index>(tiled.size())] = periodic.weights[static_cast<Eigen::Index>(i)];
      tiled.push_back(sites[i] + Point(tile % 3 - 1, tile / 3 - 1));
    }
  const Plane plane(ConvexPolygon::rectangle(-1, -1, 2, 2));
  const auto evaluation = evaluate(plane, UniformDensity{}, std::span<const Point>(tiled), tiled_weights, true);
  const std::size_t central = 4 * n;
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_NEAR(evaluation.masses[static_cast<Eigen::Index>(central + i)],
                periodic.masses[static_cast<Eigen::Index>(i)], 1e-14);
    const Point centroid = plane.centroid(evaluation.integrals[central + i]);
    EXPECT_LT(torus_distance(centroid, periodic.centroids[i]), 1e-12) << i;
  }
  // The Hessian: each tiled pair (i in the central tile, any image of j) is a periodic pair.
  const auto torus_evaluation =
      evaluate(Torus(), UniformDensity{}, std::span<const Point>(sites), periodic.weights, true);
  const Eigen::MatrixXd torus_hessian = dense_hessian(torus_evaluation);
  const Eigen::MatrixXd plane_hessian = dense_hessian(evaluation);
  Eigen::MatrixXd folded = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < 9 * n; ++j)
      folded(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j % n)) +=
          plane_hessian(static_cast<Eigen::Index>(central + i), static_cast<Eigen::Index>(j));
  EXPECT_LT((folded - torus_hessian).cwiseAbs().maxCoeff(), 1e-10 * torus_hessian.cwiseAbs().maxCoeff());
}

/// Sites symmetric under x ↦ −x and y ↦ −y (mod 1): the box's sides are then lines of the
/// periodic diagram, and the non-periodic problem on [0, 3]² with the 3 × 3 tiled sites and
/// masses has the periodic solution. (For sites without that symmetry the solves differ near
/// the tiling's outer sides, where the plane has no images beyond.)
TEST(Torus, AgreesWithTheSolveOnASymmetricTiling) {
  const auto quarter = random_points(20, 9, 0.02, 0.48);
  const Eigen::VectorXd quarter_masses = random_masses(20, 10, 10, 0.25);
  std::vector<Point> sites;
  Eigen::VectorXd masses(80);
  for (int mirror = 0; mirror < 4; ++mirror)
    for (std::size_t i = 0; i < 20; ++i) {
      const Point p = quarter[i];
      masses[static_cast<Eigen::Index>(sites.size())] = quarter_masses[static_cast<Eigen::Index>(i)];
      sites.emplace_back(mirror & 1 ? 1 - p.x() : p.x(), mirror & 2 ? 1 - p.y() : p.y());
    }
  const auto periodic = solve(Torus(), UniformDensity{}, std::span<const Point>(sites), masses, tight(1e-12));
  ASSERT_TRUE(periodic.summary.converged()) << periodic.summary.message;
  std::vector<Point> tiled;
  Eigen::VectorXd tiled_masses(9 * 80);
  for (int tile = 0; tile < 9; ++tile)
    for (std::size_t i = 0; i < 80; ++i) {
      tiled_masses[static_cast<Eigen::Index>(tiled.size())] = masses[static_cast<Eigen::Index>(i)];
      tiled.push_back(sites[i] + Point(tile % 3, tile / 3));
    }
  const Plane plane(ConvexPolygon::rectangle(0, 0, 3, 3));
  const auto flat = solve(plane, UniformDensity{}, std::span<const Point>(tiled), tiled_masses, tight(1e-12));
  ASSERT_TRUE(flat.summary.converged()) << flat.summary.message;
  const std::size_t central = 4 * 80;
  const double offset = flat.weights[static_cast<Eigen::Index>(central)] - periodic.weights[0];
  for (std::size_t i = 0; i < 80; ++i) {
    const auto k = static_cast<Eigen::Index>(central + i);
    EXPECT_NEAR(flat.weights[k] - offset, periodic.weights[static_cast<Eigen::Index>(i)], 1e-10) << i;
    EXPECT_NEAR(flat.masses[k], periodic.masses[static_cast<Eigen::Index>(i)],
                1e-12 * masses[static_cast<Eigen::Index>(i)]);
    EXPECT_LT((flat.centroids[central + i] - Point(1, 1) - periodic.centroids[i]).norm(), 1e-9) << i;
  }
}

TEST(Torus, CentroidsLieInTheBox) {
  const Eigen::AlignedBox2d box(Point(2, -1), Point(3, 1));
  const Torus torus(box, {true, true});
  const auto sites = random_points(400, 11, -3, 5);  // anywhere: wrapped into the box
  const auto result = solve(torus, UniformDensity{}, std::span<const Point>(sites), random_masses(400, 12, 10, 2));
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_NEAR(result.masses.sum(), 2, 1e-12);
  for (const auto& c : result.centroids) {
    EXPECT_TRUE(c.x() >= 2 && c.x() < 3 && c.y() >= -1 && c.y() < 1) << c.transpose();
  }
  // The cells surround the wrapped sites, within half a period along each axis.
  for (std::size_t i = 0; i < sites.size(); ++i)
    for (const auto& v : result.diagram.cells[i].vertices) {
      const Point offset = (v - torus.wrap(sites[i])).cwiseAbs();
      EXPECT_LE(offset.x(), 0.5 + 1e-12);
      EXPECT_LE(offset.y(), 1 + 1e-12);
    }
}

TEST(Torus, SitesOutsideTheBoxAreWrapped) {
  const auto sites = random_points(100, 13);
  std::vector<Point> moved = sites;
  for (std::size_t i = 0; i < moved.size(); ++i)
    moved[i] += Point(static_cast<double>(i % 5) - 2, 3 - static_cast<double>(i % 7));
  const Eigen::VectorXd masses = random_masses(100, 14, 5, 1);
  const auto inside = solve(Torus(), UniformDensity{}, std::span<const Point>(sites), masses, tight());
  const auto outside = solve(Torus(), UniformDensity{}, std::span<const Point>(moved), masses, tight());
  ASSERT_TRUE(inside.summary.converged() && outside.summary.converged());
  EXPECT_LT((inside.weights - outside.weights).cwiseAbs().maxCoeff(), 1e-9);
  for (std::size_t i = 0; i < sites.size(); ++i) EXPECT_LT((inside.centroids[i] - outside.centroids[i]).norm(), 1e-9);
  EXPECT_NEAR(inside.transport_cost, outside.transport_cost, 1e-13);
}

// One to three sites: cells as wide as the box, touching their own images.
TEST(Torus, TinyProblems) {
  const Torus torus;
  {
    const std::vector<Point> one{{3.2, -0.4}};
    const auto result = solve(torus, UniformDensity{}, std::span<const Point>(one), equal_masses(1));
    ASSERT_TRUE(result.summary.converged()) << result.summary.message;
    EXPECT_NEAR(result.masses[0], 1, 1e-14);
    EXPECT_LT(torus_distance(result.centroids[0], Point(0.2, 0.6)), 1e-14);
    // ∫ over the unit square centred at the site of |x|²/2 = 1/12.
    EXPECT_NEAR(result.transport_cost, 1.0 / 12, 1e-14);
    for (int label : result.diagram.cells[0].neighbors) EXPECT_EQ(label, 0);
  }
  {
    const std::vector<Point> two{{0.1, 0.5}, {0.6, 0.5}};
    Eigen::VectorXd masses(2);
    masses << 0.3, 0.7;
    const auto result = solve(torus, UniformDensity{}, std::span<const Point>(two), masses, tight(1e-13));
    ASSERT_TRUE(result.summary.converged()) << result.summary.message;
    EXPECT_NEAR(result.masses[0], 0.3, 1e-13);
    // Two strips: the cell of site 0 is [0.1 − 0.15, 0.1 + 0.15] wide, centred on it.
    EXPECT_LT(torus_distance(result.centroids[0], Point(0.1, 0.5)), 1e-12);
    EXPECT_LT(torus_distance(result.centroids[1], Point(0.6, 0.5)), 1e-12);
    const double error = hessian_fd_error(torus, UniformDensity{}, std::span<const Point>(two), result.weights);
    EXPECT_LT(error, 1e-6);
  }
  {
    const std::vector<Point> three{{0.1, 0.2}, {0.5, 0.9}, {0.8, 0.4}};
    const auto result =
        solve(torus, UniformDensity{}, std::span<const Point>(three), random_masses(3, 15, 3, 1), tight(1e-12));
    ASSERT_TRUE(result.summary.converged()) << result.summary.message;
    EXPECT_NEAR(result.masses.sum(), 1, 1e-13);
    const double error = hessian_fd_error(torus, UniformDensity{}, std::span<const Point>(three), result.weights);
    EXPECT_LT(error, 1e-6);
  }
}

TEST(Torus, HessianMatchesFiniteDifferencesWithOnePeriodicAxis) {
  const Torus cylinder(Eigen::AlignedBox2d(Point(0, 0), Point(2, 1)), {true, false});
  auto sites = random_points(40, 16, 0, 1);
  for (auto& s : sites) s.x() *= 2;
  const Eigen::VectorXd masses = random_masses(40, 17, 10, 2);
  const auto result = solve(cylinder, UniformDensity{}, std::span<const Point>(sites), masses);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_LT(hessian_fd_error(cylinder, UniformDensity{}, std::span<const Point>(sites), result.weights), 1e-6);
  // Along y the cells are clipped to the box, with the rectangle's labels (0 bottom, 2 top).
  bool bottom = false, top = false;
  for (const auto& cell : result.diagram.cells)
    for (int label : cell.neighbors) {
      EXPECT_TRUE(!is_boundary(label) || label == boundary_label(0) || label == boundary_label(2)) << label;
      bottom = bottom || label == boundary_label(0);
      top = top || label == boundary_label(2);
    }
  EXPECT_TRUE(bottom && top);
  for (const auto& c : result.centroids) EXPECT_TRUE(c.x() >= 0 && c.x() < 2 && c.y() >= 0 && c.y() <= 1);
}

// x periodic only: a 3 × 1 tiling of a symmetric configuration is the same problem.
TEST(Torus, OnePeriodicAxisAgreesWithTheTiledStrip) {
  const auto half = random_points(25, 18, 0.02, 0.98);
  std::vector<Point> sites;
  Eigen::VectorXd masses = random_masses(50, 19, 8, 1);
  for (std::size_t i = 0; i < 25; ++i) {
    sites.emplace_back(half[i].x() / 2, half[i].y());
    sites.emplace_back(1 - half[i].x() / 2, half[i].y());
    masses[static_cast<Eigen::Index>(2 * i + 1)] = masses[static_cast<Eigen::Index>(2 * i)];
  }
  masses /= masses.sum();
  const Torus cylinder(Eigen::AlignedBox2d(Point(0, 0), Point(1, 1)), {true, false});
  const auto periodic = solve(cylinder, UniformDensity{}, std::span<const Point>(sites), masses, tight(1e-12));
  ASSERT_TRUE(periodic.summary.converged()) << periodic.summary.message;
  std::vector<Point> tiled;
  Eigen::VectorXd tiled_masses(150);
  for (int tile = 0; tile < 3; ++tile)
    for (std::size_t i = 0; i < 50; ++i) {
      tiled_masses[static_cast<Eigen::Index>(tiled.size())] = masses[static_cast<Eigen::Index>(i)];
      tiled.push_back(sites[i] + Point(tile, 0));
    }
  const auto flat = solve(Plane(ConvexPolygon::rectangle(0, 0, 3, 1)), UniformDensity{}, std::span<const Point>(tiled),
                          tiled_masses, tight(1e-12));
  ASSERT_TRUE(flat.summary.converged()) << flat.summary.message;
  const double offset = flat.weights[50] - periodic.weights[0];
  for (std::size_t i = 0; i < 50; ++i) {
    EXPECT_NEAR(flat.weights[static_cast<Eigen::Index>(50 + i)] - offset,
                periodic.weights[static_cast<Eigen::Index>(i)], 1e-10);
    EXPECT_LT((flat.centroids[50 + i] - Point(1, 0) - periodic.centroids[i]).norm(), 1e-9);
  }
}

TEST(Torus, SitesOutsideTheBoxAlongANonPeriodicAxis) {
  const Torus cylinder(Eigen::AlignedBox2d(Point(0, 0), Point(1, 1)), {true, false});
  auto sites = random_points(100, 20, 0, 1);
  for (std::size_t i = 0; i < sites.size(); i += 3) sites[i].y() = 5 * sites[i].y() - 2;  // some far outside
  const auto result = solve(cylinder, UniformDensity{}, std::span<const Point>(sites), equal_masses(100));
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  for (const auto& c : result.centroids) EXPECT_TRUE(c.y() >= 0 && c.y() <= 1);
}

TEST(Torus, LargeProblemKeepsTheGhostsFew) {
  const Torus torus;
  const auto sites = torus.uniform_samples(20000, 1);
  const auto result = solve(torus, UniformDensity{}, std::span<const Point>(sites), equal_masses(20000));
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  GhostStatistics statistics;
  const auto diagram = torus.build_diagram(std::span<const Point>(sites), result.weights, statistics);
  std::printf("  N = 20000: %zu ghosts (%.1f%%), margin %.4f (%.1f spacings), %d build(s)\n", statistics.ghosts,
              100.0 * static_cast<double>(statistics.ghosts) / 20000, statistics.margin.x(), torus.margin_factor(),
              statistics.builds);
  EXPECT_EQ(statistics.builds, 1);  // the margin of the solve serves its final weights
  EXPECT_LE(torus.margin_factor(), 5);
  EXPECT_LT(statistics.ghosts, 20000 * 15 / 100);  // 4·4·√N at 4 spacings, 12% at this N
  EXPECT_FALSE(statistics.full_tiling);
}

// Weights far apart need a wider margin than the first one: the check finds the cells that
// images left out could cut, and the diagram is rebuilt until it is exact.
TEST(Torus, WideningMarginsKeepTheCellsExact) {
  const std::size_t n = 2000;
  const auto sites = random_points(n, 24);
  std::mt19937_64 random(25);
  std::uniform_real_distribution<double> uniform(-1, 1);
  for (const double spread : {1e-3, 1e-2, 1e-1}) {
    Eigen::VectorXd weights(static_cast<Eigen::Index>(n));
    for (auto& w : weights) w = spread * uniform(random);
    const Torus torus;
    GhostStatistics statistics;
    const auto diagram = torus.build_diagram(std::span<const Point>(sites), weights, statistics);
    std::printf("  weight spread %g: %d build(s), margin %.3f, %zu ghosts\n", spread, statistics.builds,
                statistics.margin.x(), statistics.ghosts);
    // The plane's diagram of the 3 × 3 tiling: its central tile is exact.
    std::vector<Point> tiled;
    Eigen::VectorXd tiled_weights(9 * static_cast<Eigen::Index>(n));
    for (int tile = 0; tile < 9; ++tile)
      for (std::size_t i = 0; i < n; ++i) {
        tiled_weights[static_cast<Eigen::Index>(tiled.size())] = weights[static_cast<Eigen::Index>(i)];
        tiled.push_back(sites[i] + Point(tile % 3 - 1, tile / 3 - 1));
      }
    const Plane plane(ConvexPolygon::rectangle(-1, -1, 2, 2));
    const auto reference = plane.build_diagram(std::span<const Point>(tiled), tiled_weights);
    for (std::size_t i = 0; i < n; ++i) {
      const auto& cell = diagram.cells[i];
      const auto& expected = reference.cells[4 * n + i];
      ASSERT_EQ(cell.empty(), expected.empty()) << i;
      if (cell.empty()) continue;
      EXPECT_NEAR(torus.integrate(cell, sites[i]).mass, plane.integrate(expected, sites[i]).mass, 1e-15) << i;
    }
    // The second diagram starts from the margin that worked.
    const auto again = torus.build_diagram(std::span<const Point>(sites), weights, statistics);
    EXPECT_EQ(statistics.builds, 1);
  }
}

// The line search's early stop: a diagram built with stop_at_empty_cell has an empty cell exactly
// when the full one does, and is the full one when it has none (the ghosts' cells, which the grown
// box may cut to nothing, do not stop it).
TEST(Torus, StopAtEmptyCellOnlyForEmptySites) {
  const std::size_t n = 3000;
  const auto sites = random_points(n, 31);
  std::mt19937_64 random(32);
  std::uniform_real_distribution<double> uniform(-1, 1);
  int with_empty = 0, without_empty = 0;
  for (const double spread : {0.0, 1e-8, 1e-6, 1e-4, 1e-2}) {
    Eigen::VectorXd weights(static_cast<Eigen::Index>(n));
    for (auto& w : weights) w = spread * uniform(random);
    const Torus torus;
    const auto full = torus.build_diagram(std::span<const Point>(sites), weights);
    const auto stopped = torus.build_diagram(std::span<const Point>(sites), weights, true);
    ASSERT_EQ(stopped.cells.size(), n);
    auto empty = [](const Cell<Point>& cell) { return cell.empty(); };
    const bool full_has_empty = std::any_of(full.cells.begin(), full.cells.end(), empty);
    EXPECT_EQ(std::any_of(stopped.cells.begin(), stopped.cells.end(), empty), full_has_empty) << spread;
    (full_has_empty ? with_empty : without_empty)++;
    if (!full_has_empty) {
      for (std::size_t i = 0; i < n; ++i)
        ASSERT_EQ(stopped.cells[i].vertices, full.cells[i].vertices) << "spread " << spread << ", cell " << i;
    }
  }
  EXPECT_GT(with_empty, 0);  // both cases were exercised
  EXPECT_GT(without_empty, 0);
  // A ghost cut to nothing: on a k × k grid (spacing h, the first margin 4h) column 3 sits 3.95h
  // from the right side, so its image at −3.95h is a ghost; weights shift its cell 0.6h to the
  // left, which puts the image's cell beyond the grown box's side at −4h. No cell is empty. (At
  // k ≥ 142 the triangulation is built in two halves, and that ghost's cell comes before the
  // right half's cells: a stop at it would leave those empty.)
  const int k = 150;
  const double h = 1.0 / k;
  std::vector<Point> grid;
  for (int row = 0; row < k; ++row)
    for (int column = 0; column < k; ++column) grid.emplace_back(1 - (column * h + 0.95 * h), (row + 0.5) * h);
  // Bisector shifts s_j between columns j and j + 1 (summing to 0 around the period); the power
  // weights 2ψ then fall by 2h·s_j from column j to j + 1.
  std::vector<double> shift(k, 0.0);
  const double ramp[] = {0.2, 0.4, 0.6, 0.6, 0.4, 0.2};
  for (int j = 0; j < 6; ++j) shift[static_cast<std::size_t>(j)] = ramp[j] * h;
  for (int j = 10; j < 34; ++j) shift[static_cast<std::size_t>(j)] = -0.1 * h;  // Σ shifts = 0
  std::vector<double> column_weight(k, 0.0);
  for (int j = 0; j + 1 < k; ++j)
    column_weight[static_cast<std::size_t>(j + 1)] =
        column_weight[static_cast<std::size_t>(j)] - h * shift[static_cast<std::size_t>(j)];  // ψ = power weight / 2
  Eigen::VectorXd grid_weights(k * k);
  for (int i = 0; i < k * k; ++i) grid_weights[i] = column_weight[static_cast<std::size_t>(i % k)];
  const Torus torus;
  const auto full = torus.build_diagram(std::span<const Point>(grid), grid_weights);
  const auto stopped = torus.build_diagram(std::span<const Point>(grid), grid_weights, true);
  for (std::size_t i = 0; i < grid.size(); ++i) {
    ASSERT_FALSE(full.cells[i].empty()) << i;
    ASSERT_EQ(stopped.cells[i].vertices, full.cells[i].vertices) << i;
  }
  // Column 3's cell is shifted as designed: its right side at 1 − (3.45h + 0.6h).
  double right = -INFINITY;
  for (const auto& v : full.cells[3].vertices) right = std::max(right, v.x());
  EXPECT_NEAR(right, 1 - 4.05 * h, 1e-12);
}

TEST(Torus, FunctionDensityGivenOnTheBox) {
  // ρ given on the box and not periodic (it jumps across x = 0 ≡ 1): the torus cuts the cells at
  // the box's sides, so the quadrature sees a smooth ρ on each part. PeriodicDensity over the
  // plane's FunctionDensity is the same computation.
  const Torus torus;
  const auto sites = random_points(50, 21);
  const Eigen::VectorXd masses = random_masses(50, 22, 5, 1);
  const ScalarField<Point> rho = [](const Point& x) { return 0.5 + x.x() * x.x() + 0.5 * std::sin(6 * x.y()); };
  Options options = tight(1e-10);
  options.rescale_masses = true;
  const auto direct = solve(torus, FunctionDensity<Point>{rho, 8}, std::span<const Point>(sites), masses, options);
  const auto wrapped =
      solve(torus, PeriodicDensity(FunctionDensity<Point>{rho, 8}), std::span<const Point>(sites), masses, options);
  ASSERT_TRUE(direct.summary.converged()) << direct.summary.message;
  ASSERT_TRUE(wrapped.summary.converged()) << wrapped.summary.message;
  EXPECT_NEAR(direct.summary.source_mass, 0.5 + 1.0 / 3 + 0.5 * (1 - std::cos(6.0)) / 6, 1e-12);
  EXPECT_LT((direct.weights - wrapped.weights).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT(hessian_fd_error(torus, FunctionDensity<Point>{rho, 8}, std::span<const Point>(sites), direct.weights),
            1e-6);
}

TEST(Torus, MeshDensityOnTheBox) {
  // A piecewise-linear ρ on a mesh of the box, through PeriodicDensity: masses and Hessian.
  const Torus torus;
  TriangleMesh<Point> mesh;
  std::vector<double> values;
  const int k = 6;
  for (int j = 0; j <= k; ++j)
    for (int i = 0; i <= k; ++i) {
      mesh.vertices.emplace_back(static_cast<double>(i) / k, static_cast<double>(j) / k);
      values.push_back(1 + 0.5 * std::sin(2 * std::numbers::pi * i / k) * std::cos(2 * std::numbers::pi * j / k));
    }
  for (int j = 0; j < k; ++j)
    for (int i = 0; i < k; ++i) {
      const int a = j * (k + 1) + i, b = a + 1, c = a + k + 1, d = c + 1;
      mesh.triangles.push_back({a, b, d});
      mesh.triangles.push_back({a, d, c});
    }
  const PeriodicDensity density(mesh_density(torus.plane(), std::span<const Point>(mesh.vertices),
                                             std::span<const std::array<int, 3>>(mesh.triangles),
                                             std::span<const double>(values)));
  const auto sites = random_points(30, 23);
  const auto result = solve(torus, density, std::span<const Point>(sites), equal_masses(30, 1));
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  EXPECT_NEAR(result.summary.source_mass, 1, 1e-12);  // the sine averages out on the grid
  EXPECT_LT(hessian_fd_error(torus, density, std::span<const Point>(sites), result.weights), 1e-6);
  // An edge along the box's side (sites mirrored across x = 0) takes both sides' densities.
  std::vector<Point> mirrored{{0.1, 0.3}, {0.9, 0.3}, {0.5, 0.8}, {0.3, 0.6}};
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(4);
  EXPECT_LT(hessian_fd_error(torus, density, std::span<const Point>(mirrored), zero), 1e-6);
}

TEST(TorusBadInput, DuplicatesModuloThePeriod) {
  std::vector<Point> sites{{0.3, 0.4}, {0.1, 0.1}, {0.5, 0.5}, {1.3, -0.6}};
  EXPECT_EQ(input_error([&] { solve(Torus(), UniformDensity{}, std::span<const Point>(sites), equal_masses(4)); }),
            "sites[3]: duplicate of sites[0] modulo the period");
  sites[3] = {0.3, 0.4};
  EXPECT_EQ(input_error([&] { solve(Torus(), UniformDensity{}, std::span<const Point>(sites), equal_masses(4)); }),
            "sites[3]: duplicate of sites[0] modulo the period");
  // Across the seam: 1 − 1e-17 wraps to just below 1, or to 0.
  sites[3] = {0.1 - 1e-17, 1.1};
  EXPECT_EQ(input_error([&] { solve(Torus(), UniformDensity{}, std::span<const Point>(sites), equal_masses(4)); }),
            "sites[3]: duplicate of sites[1] modulo the period");
  sites = {{0, 0.5}, {0.2, 0.2}, {1 - 1e-17, 0.5}};
  EXPECT_EQ(input_error([&] { solve(Torus(), UniformDensity{}, std::span<const Point>(sites), equal_masses(3)); }),
            "sites[2]: duplicate of sites[0] modulo the period");
  sites = {{0, 0.5}, {0.2, 0.2}, {-1e-16, 0.5}};
  EXPECT_EQ(input_error([&] { solve(Torus(), UniformDensity{}, std::span<const Point>(sites), equal_masses(3)); }),
            "sites[2]: duplicate of sites[0] modulo the period");
  // Along a non-periodic axis, the same x and y one period apart are different points.
  const Torus cylinder(Eigen::AlignedBox2d(Point(0, 0), Point(1, 1)), {true, false});
  sites = {{0.5, 0.2}, {0.5, 1.2}, {1.5, 0.2}};
  EXPECT_EQ(input_error([&] { cylinder.validate_sites(std::span<const Point>(sites)); }),
            "sites[2]: duplicate of sites[0] modulo the period");
  sites.pop_back();
  EXPECT_EQ(input_error([&] { cylinder.validate_sites(std::span<const Point>(sites)); }), "(no InputError)");
  // Distinct points close together (far above the rounding) are fine.
  sites = {{0.5, 0.5}, {0.5 + 1e-12, 0.5}};
  EXPECT_EQ(input_error([&] { Torus().validate_sites(std::span<const Point>(sites)); }), "(no InputError)");
}

TEST(TorusBadInput, NonFiniteSitesAndBadBoxes) {
  const std::vector<Point> sites{{0.3, 0.4}, {NAN, 0.1}};
  EXPECT_EQ(input_error([&] { solve(Torus(), UniformDensity{}, std::span<const Point>(sites), equal_masses(2)); }),
            "sites[1]: coordinate is not finite");
  EXPECT_EQ(input_error([] {
              Torus(Eigen::AlignedBox2d(Point(0, 0), Point(0, 1)), {true, true});
            }).rfind("domain:", 0),
            0u);
  EXPECT_EQ(input_error([] {
              Torus(Eigen::AlignedBox2d(Point(0, 0), Point(INFINITY, 1)), {true, true});
            }).rfind("domain:", 0),
            0u);
}

}  // namespace
}  // namespace sdot::testing
