// The shared cell builder against brute force (clipping by every other site).
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <tuple>

#include "power_predicate.hpp"
#include "regular_triangulation.hpp"
#include "sdot/chart_diagram.hpp"
#include "sdot/error.hpp"

namespace sdot {
namespace {

std::vector<ChartCell> brute_force(std::span<const Vec3> dual, const ConvexPolygon& domain) {
  std::vector<ChartCell> cells(dual.size());
  for (std::size_t i = 0; i < dual.size(); ++i) {
    auto& cell = cells[i];
    cell.vertices = domain.vertices();
    for (std::size_t k = 0; k < cell.vertices.size(); ++k)
      cell.neighbors.push_back(boundary_label(static_cast<int>(k)));
    for (std::size_t j = 0; j < dual.size(); ++j)
      if (j != i) {
        const Vec3 d = dual[i] - dual[j];
        clip(cell, d.head<2>(), d.z(), static_cast<int>(j));
      }
  }
  return cells;
}

double area(const ChartCell& cell) {
  double twice = 0;
  for (std::size_t k = 0; k < cell.size(); ++k) {
    const Vec2& a = cell.vertices[k];
    const Vec2& b = cell.vertices[(k + 1) % cell.size()];
    twice += a.x() * b.y() - a.y() * b.x();
  }
  return twice / 2;
}

TEST(ChartDiagram, MatchesBruteForceOnRandomPowerDiagrams) {
  std::mt19937_64 random(1);
  std::uniform_real_distribution<double> uniform(-1.5, 1.5);
  const ConvexPolygon domain({{-1, -1}, {1, -1}, {1.2, 0.5}, {0, 1}, {-1, 0.6}});
  for (int trial = 0; trial < 20; ++trial) {
    const std::size_t n = 1 + static_cast<std::size_t>(trial * 7);
    std::vector<Vec3> dual(n);
    for (auto& d : dual) d = Vec3(uniform(random), uniform(random), 0.3 * uniform(random));
    const auto fast = build_chart_diagram(dual, domain);
    const auto slow = brute_force(dual, domain);
    double total = 0;
    for (std::size_t i = 0; i < n; ++i) {
      EXPECT_NEAR(area(fast[i]), area(slow[i]), 1e-13) << "trial " << trial << " cell " << i;
      total += area(fast[i]);
    }
    EXPECT_NEAR(total, domain.area(), 1e-12);
  }
}

TEST(ChartDiagram, StopAtEmptyCellKeepsBuiltCellsExact) {
  // Many sites with spread heights: some cells are empty. Stopping at the first empty cell
  // leaves an empty cell (so a line search rejects the step) and every built cell exact.
  std::mt19937_64 random(3);
  std::uniform_real_distribution<double> uniform(-1, 1);
  const ConvexPolygon domain({{-1, -1}, {1, -1}, {1, 1}, {-1, 1}});
  std::vector<Vec2> centers(3000);
  std::vector<double> weights(centers.size());
  for (auto& c : centers) c = Vec2(uniform(random), uniform(random));
  for (auto& w : weights) w = 2e-4 * uniform(random);
  const auto full = build_power_diagram(centers, weights, domain);
  const auto stopped = build_power_diagram(centers, weights, domain, {}, true);
  std::size_t empty_full = 0, empty_stopped = 0;
  for (std::size_t i = 0; i < centers.size(); ++i) {
    empty_full += full[i].vertices.empty();
    empty_stopped += stopped[i].vertices.empty();
    if (!stopped[i].vertices.empty()) {
      EXPECT_NEAR(area(stopped[i]), area(full[i]), 1e-15) << i;
    }
  }
  ASSERT_GT(empty_full, 0u);
  EXPECT_GE(empty_stopped, empty_full);
  std::printf("  %zu empty cells; %zu left empty when stopping at the first\n", empty_full, empty_stopped);
}

TEST(ChartDiagram, CollinearAndSingleSites) {
  const auto domain = ConvexPolygon::rectangle(0, 0, 1, 1);
  std::vector<Vec3> one{{5, 5, 0}};
  EXPECT_NEAR(area(build_chart_diagram(one, domain)[0]), 1, 1e-15);
  std::vector<Vec3> line;
  for (int i = 0; i < 10; ++i) line.emplace_back(0.1 * i, 0, -0.005 * i * i);  // sites on y = 0
  const auto cells = build_chart_diagram(line, domain);
  // Voronoi strips of the points 0, 0.1, …, 0.9 on the x axis, cut to [0, 1].
  for (int i = 0; i < 10; ++i)
    EXPECT_NEAR(area(cells[i]), (i == 9 ? 1.0 : 0.1 * i + 0.05) - std::max(0.0, 0.1 * i - 0.05), 1e-13);
}

// ---------------------------------------------------------------- both power-diagram builders
std::vector<PowerDiagramMethod> builders() {
  std::vector<PowerDiagramMethod> methods{PowerDiagramMethod::kd_tree};
  if (has_regular_triangulation()) methods.push_back(PowerDiagramMethod::regular_triangulation);
  return methods;
}

const char* name(PowerDiagramMethod method) {
  return method == PowerDiagramMethod::kd_tree ? "kd-tree" : "regular triangulation";
}

std::vector<Vec3> dual_of(std::span<const Vec2> centers, std::span<const double> weights) {
  std::vector<Vec3> dual(centers.size());
  for (std::size_t i = 0; i < centers.size(); ++i)
    dual[i] = Vec3(centers[i].x(), centers[i].y(), (weights[i] - centers[i].squaredNorm()) / 2);
  return dual;
}

/// The neighbours across edges longer than `length` (degenerate inputs give zero-length edges,
/// which either builder may or may not report).
std::vector<int> long_edge_neighbors(const ChartCell& cell, double length = 1e-9) {
  std::vector<int> result;
  for (std::size_t k = 0; k < cell.size(); ++k)
    if (cell.neighbors[k] >= 0 && (cell.vertices[(k + 1) % cell.size()] - cell.vertices[k]).norm() > length)
      result.push_back(cell.neighbors[k]);
  std::sort(result.begin(), result.end());
  return result;
}

/// Every builder against brute force: areas to `tolerance`, and the same neighbours.
void expect_builders_exact(std::span<const Vec2> centers, std::span<const double> weights, const ConvexPolygon& domain,
                           double tolerance, const std::string& what) {
  const auto dual = dual_of(centers, weights);
  const auto slow = brute_force(dual, domain);
  for (const auto method : builders()) {
    const auto cells = build_power_diagram(centers, weights, domain, {}, false, method);
    ASSERT_EQ(cells.size(), centers.size());
    double total = 0;
    for (std::size_t i = 0; i < centers.size(); ++i) {
      EXPECT_NEAR(area(cells[i]), area(slow[i]), tolerance) << what << ", " << name(method) << ", cell " << i;
      EXPECT_EQ(long_edge_neighbors(cells[i]), long_edge_neighbors(slow[i]))
          << what << ", " << name(method) << ", cell " << i;
      total += area(cells[i]);
    }
    EXPECT_NEAR(total, domain.area(), 1e-12) << what << ", " << name(method);
  }
}

TEST(PowerDiagram, BuildersMatchBruteForceOnRandomInput) {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> uniform(-1.2, 1.2);
  const ConvexPolygon domain({{-1, -1}, {1, -1}, {1.2, 0.5}, {0, 1}, {-1, 0.6}});
  for (int trial = 0; trial < 12; ++trial) {
    const std::size_t n = 2 + static_cast<std::size_t>(trial * 41);
    std::vector<Vec2> centers(n);
    std::vector<double> weights(n);
    for (auto& c : centers) c = Vec2(uniform(random), uniform(random));
    for (auto& w : weights) w = 0.05 * uniform(random);  // some sites hidden, some cells outside
    expect_builders_exact(centers, weights, domain, 1e-13, "trial " + std::to_string(trial));
  }
}

TEST(PowerDiagram, ExactlyDegenerateInputs) {
  const auto square = ConvexPolygon::rectangle(0, 0, 1, 1);
  {  // a grid with equal weights: four cocircular sites around every cell corner
    const int k = 16;
    std::vector<Vec2> centers;
    for (int i = 0; i < k; ++i)
      for (int j = 0; j < k; ++j) centers.emplace_back((i + 0.5) / k, (j + 0.5) / k);
    const std::vector<double> weights(centers.size(), 0.0);
    expect_builders_exact(centers, weights, square, 1e-15, "grid");
    for (const auto method : builders()) {
      const auto cells = build_power_diagram(centers, weights, square, {}, false, method);
      for (std::size_t i = 0; i < cells.size(); ++i) EXPECT_NEAR(area(cells[i]), 1.0 / (k * k), 1e-15) << name(method);
    }
  }
  {  // sites on a circle, all cells meeting at its centre (a vertex of degree 4, then 8)
    const auto box = ConvexPolygon::rectangle(-1, -1, 1, 1);
    std::vector<Vec2> four{{1, 0}, {0, 1}, {-1, 0}, {0, -1}};
    expect_builders_exact(four, std::vector<double>(4, 0.3), box, 1e-15, "four cocircular");
    std::vector<Vec2> eight;
    for (int k = 0; k < 8; ++k) eight.emplace_back(0.5 * std::cos(k * M_PI / 4), 0.5 * std::sin(k * M_PI / 4));
    expect_builders_exact(eight, std::vector<double>(8, 0.0), box, 1e-14, "eight cocircular");
    for (const auto method : builders()) {  // the square's symmetries: two areas, 4 − 2√2 and 2√2 − 2 halved
      const auto cells = build_power_diagram(eight, std::vector<double>(8, 0.0), box, {}, false, method);
      for (std::size_t k = 0; k < 8; ++k)
        EXPECT_NEAR(area(cells[k]), k % 2 == 0 ? std::sqrt(2.0) - 1 : 2 - std::sqrt(2.0), 1e-14) << name(method);
    }
  }
  {  // equal centres with different weights: the lower weight's cell is empty
    std::vector<Vec2> centers{{0.3, 0.3}, {0.3, 0.3}, {0.7, 0.6}};
    std::vector<double> weights{0.01, 0.02, 0.0};
    expect_builders_exact(centers, weights, square, 1e-15, "equal centres");
    for (const auto method : builders())
      EXPECT_TRUE(build_power_diagram(centers, weights, square, {}, false, method)[0].empty()) << name(method);
  }
  {  // collinear sites with weights, and sites on the domain's corners and edges
    std::vector<Vec2> line;
    std::vector<double> weights;
    for (int i = 0; i < 12; ++i) line.emplace_back(0.1 * i - 0.05, 0.25), weights.push_back(0.002 * (i % 3));
    expect_builders_exact(line, weights, square, 1e-15, "collinear");
    std::vector<Vec2> boundary{{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.5, 0}, {1, 0.5}, {0.5, 1}, {0, 0.5}, {0.5, 0.5}};
    expect_builders_exact(boundary, std::vector<double>(boundary.size(), 0.0), square, 1e-15, "on the boundary");
  }
  {  // one site alone, and a site hidden by its neighbours' weights
    std::vector<Vec2> one{{5, 5}};
    expect_builders_exact(one, std::vector<double>{0.0}, square, 1e-15, "one site");
    std::vector<Vec2> hidden{{0.2, 0.5}, {0.5, 0.5}, {0.8, 0.5}};
    expect_builders_exact(hidden, std::vector<double>{0.2, -0.2, 0.2}, square, 1e-15, "hidden");
    for (const auto method : builders())
      EXPECT_TRUE(
          build_power_diagram(hidden, std::vector<double>{0.2, -0.2, 0.2}, square, {}, false, method)[1].empty());
  }
}

__extension__ using Int128 = __int128;  // GCC and Clang; no -Wpedantic warning

/// Four weighted points on a grid: coordinates k·2⁻ᵇ and weights m·2⁻²ᵇ, k and m integers (exact doubles
/// for |k|, |m| < 2⁵³).
struct GridQuadruple {
  std::array<std::array<std::int64_t, 3>, 4> points;  // x, y, weight of p, q, r, t
  int bits;
  [[nodiscard]] double value(int k, int d) const {
    return std::ldexp(static_cast<double>(points[static_cast<std::size_t>(k)][static_cast<std::size_t>(d)]),
                      d == 2 ? -2 * bits : -bits);
  }
  [[nodiscard]] std::optional<int> filtered() const {
    return detail::power_test_sign_by_filter(value(0, 0), value(0, 1), value(0, 2), value(1, 0), value(1, 1),
                                             value(1, 2), value(2, 0), value(2, 1), value(2, 2), value(3, 0),
                                             value(3, 1), value(3, 2));
  }
  /// The power test's determinant in units of 2⁻⁴ᵇ, exactly (every entry is an integer in units of
  /// 2⁻ᵇ or 2⁻²ᵇ; with coordinates below 2²⁷ units it fits in 128 bits).
  [[nodiscard]] Int128 determinant() const {
    const auto& t = points[3];
    Int128 rows[3][3];
    for (std::size_t k = 0; k < 3; ++k) {
      const std::int64_t dx = points[k][0] - t[0], dy = points[k][1] - t[1];
      rows[k][0] = dx, rows[k][1] = dy;
      rows[k][2] = static_cast<Int128>(dx) * dx + static_cast<Int128>(dy) * dy - (points[k][2] - t[2]);
    }
    return rows[0][2] * (rows[1][0] * rows[2][1] - rows[2][0] * rows[1][1]) +
           rows[1][2] * (rows[2][0] * rows[0][1] - rows[0][0] * rows[2][1]) +
           rows[2][2] * (rows[0][0] * rows[1][1] - rows[1][0] * rows[0][1]);
  }
};

/// Checks the filter against the exact sign; counts abstentions and exact zeros.
void expect_filter_exact(const GridQuadruple& quadruple, int& answered, int& degenerate, int& abstained) {
  const Int128 determinant = quadruple.determinant();
  const int exact = determinant > 0 ? 1 : (determinant < 0 ? -1 : 0);
  const auto filtered = quadruple.filtered();
  if (exact == 0) ++degenerate;
  if (!filtered) {
    ++abstained;
    return;
  }
  ++answered;
  ASSERT_EQ(*filtered, exact) << quadruple.value(3, 0) << ", " << quadruple.value(3, 1);
}

TEST(PowerPredicate, FilterGivesTheExactSignOrAbstains) {
  // Small integer ranges make exactly degenerate quadruples (cocircular, collinear, equal points,
  // equal powers) frequent; there the filter must abstain.
  std::mt19937_64 random(11);
  int answered = 0, degenerate = 0, abstained = 0;
  for (const std::int64_t range : {std::int64_t{3}, std::int64_t{40}}) {
    std::uniform_int_distribution<std::int64_t> coordinate(-range, range), weight(-range * range, range * range);
    for (int trial = 0; trial < 100000; ++trial) {
      GridQuadruple quadruple{{}, 20};
      for (auto& p : quadruple.points) p = {coordinate(random), coordinate(random), weight(random)};
      expect_filter_exact(quadruple, answered, degenerate, abstained);
    }
  }
  EXPECT_GT(degenerate, 1000);
  EXPECT_EQ(abstained, degenerate);  // on these small integers double precision is exact
  // Nearly degenerate: four points near a circle on a grid of 2⁻²⁶, then t's weight set so that
  // the determinant is within half of |orient(p, q, r)| of 0, below the determinant's rounding
  // error in double precision: a filter without its error bound gets signs wrong here.
  std::uniform_real_distribution<double> uniform(0, 1);
  const int bits = 26;
  const double unit = std::ldexp(1.0, bits);
  int wrong_in_double = 0;
  answered = degenerate = abstained = 0;
  for (int trial = 0; trial < 100000; ++trial) {
    const double cx = 0.6 * uniform(random) - 0.3, cy = 0.6 * uniform(random) - 0.3,
                 radius = 0.1 + 0.5 * uniform(random);
    GridQuadruple quadruple{{}, bits};
    for (auto& p : quadruple.points) {
      const double angle = 2 * M_PI * uniform(random);
      p = {std::llround((cx + radius * std::cos(angle)) * unit), std::llround((cy + radius * std::sin(angle)) * unit),
           0};
    }
    auto& t = quadruple.points[3];
    const auto& [p, q, r] = std::tie(quadruple.points[0], quadruple.points[1], quadruple.points[2]);
    // det is affine in t's weight m with slope orient(p, q, r) (the sum of the three minors).
    const Int128 orientation =
        static_cast<Int128>(q[0] - p[0]) * (r[1] - p[1]) - static_cast<Int128>(q[1] - p[1]) * (r[0] - p[0]);
    if (orientation == 0) continue;
    const Int128 at_zero = quadruple.determinant();
    t[2] = static_cast<std::int64_t>(-at_zero / orientation) + static_cast<std::int64_t>(trial % 3) - 1;
    const Int128 determinant = quadruple.determinant();
    // What a plain double-precision determinant says (the filter's own arithmetic, no bound).
    const double dx[3] = {quadruple.value(0, 0) - quadruple.value(3, 0), quadruple.value(1, 0) - quadruple.value(3, 0),
                          quadruple.value(2, 0) - quadruple.value(3, 0)};
    const double dy[3] = {quadruple.value(0, 1) - quadruple.value(3, 1), quadruple.value(1, 1) - quadruple.value(3, 1),
                          quadruple.value(2, 1) - quadruple.value(3, 1)};
    double dz[3];
    for (int k = 0; k < 3; ++k) dz[k] = dx[k] * dx[k] + dy[k] * dy[k] - (quadruple.value(k, 2) - quadruple.value(3, 2));
    const double plain = dz[0] * (dx[1] * dy[2] - dx[2] * dy[1]) + dz[1] * (dx[2] * dy[0] - dx[0] * dy[2]) +
                         dz[2] * (dx[0] * dy[1] - dx[1] * dy[0]);
    if ((plain > 0) != (determinant > 0) || (plain < 0) != (determinant < 0)) ++wrong_in_double;
    expect_filter_exact(quadruple, answered, degenerate, abstained);
  }
  EXPECT_GT(wrong_in_double, 1000);  // the cases are hard enough to matter
  EXPECT_GT(abstained, 1000);
  // Away from degeneracy the filter answers: random points on the same grid.
  answered = degenerate = abstained = 0;
  std::uniform_int_distribution<std::int64_t> coordinate(-(std::int64_t{1} << bits), std::int64_t{1} << bits),
      weight(-(std::int64_t{1} << 2 * bits), std::int64_t{1} << 2 * bits);
  for (int trial = 0; trial < 100000; ++trial) {
    GridQuadruple quadruple{{}, bits};
    for (auto& p : quadruple.points) p = {coordinate(random), coordinate(random), weight(random)};
    expect_filter_exact(quadruple, answered, degenerate, abstained);
  }
  EXPECT_LT(abstained, 100);
}

TEST(PowerPredicate, FilterAbstainsOutsideItsRange) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), huge = 1e200, tiny = 1e-200;
  EXPECT_FALSE(detail::power_test_sign_by_filter(0, 0, 0, 1, 0, 0, 0, 1, 0, nan, 0.3, 0).has_value());
  EXPECT_FALSE(detail::power_test_sign_by_filter(0, 0, 0, huge, 0, 0, 0, huge, 0, 0.3, 0.3, 0).has_value());
  EXPECT_FALSE(
      detail::power_test_sign_by_filter(0, 0, 0, tiny, 0, 0, 0, tiny, 0, 0.3 * tiny, 0.3 * tiny, 0).has_value());
  // Counter-clockwise p, q, r: inside their circle is the positive side.
  EXPECT_EQ(detail::power_test_sign_by_filter(0, 0, 0, 1, 0, 0, 0, 1, 0, 0.3, 0.3, 0), 1);
  EXPECT_EQ(detail::power_test_sign_by_filter(0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 2, 0), -1);
  EXPECT_EQ(detail::power_test_sign_by_filter(0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 2, 10), 1);  // a heavy t: positive
}

// A warm start (the last regular triangulation, then edge flips) gives the cells of a build from
// scratch, bit for bit on generic input: through a Newton-like sequence of weights, a step that
// hides a site (the flips cannot finish: from scratch), and steps far from the last.
TEST(PowerDiagram, WarmStartGivesTheCellsOfABuildFromScratch) {
  if (!has_regular_triangulation()) GTEST_SKIP() << "no regular triangulation in this build";
  std::mt19937_64 random(17);
  std::uniform_real_distribution<double> uniform(0, 1);
  const std::size_t n = 30000;  // above the size the triangulation is split in two halves from
  std::vector<Vec2> centers(n);
  for (auto& c : centers) c = Vec2(uniform(random), uniform(random));
  const auto square = ConvexPolygon::rectangle(0, 0, 1, 1);
  const double spacing2 = 1.0 / static_cast<double>(n);
  std::vector<std::vector<double>> steps;
  steps.emplace_back(n, 0.0);
  for (const double scale : {0.3, 0.3, 0.01, 1e-4, 1.0}) {  // relative to the mean spacing²
    std::vector<double> next = steps.back();
    for (auto& w : next) w += scale * spacing2 * (uniform(random) - 0.5);
    steps.push_back(std::move(next));
  }
  steps.push_back(steps.back());
  steps.back()[n / 2] -= 10 * spacing2;  // hidden by its neighbours
  steps.push_back(steps[3]);
  const auto warm_start = make_power_diagram_warm_start();
  int flipped = 0;
  for (std::size_t step = 0; step < steps.size(); ++step) {
    const auto cold = build_power_diagram(centers, steps[step], square);
    const auto warm = build_power_diagram(centers, steps[step], square, {}, false, PowerDiagramMethod::automatic, n,
                                          warm_start.get());
    std::size_t empty = 0;
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_EQ(warm[i].vertices, cold[i].vertices) << "step " << step << ", cell " << i;
      ASSERT_EQ(warm[i].neighbors, cold[i].neighbors) << "step " << step << ", cell " << i;
      empty += cold[i].empty();
    }
    if (step == 6) {
      EXPECT_GT(empty, 0u);
    }
    // The half-edge twins exist only once flips have run from the kept triangulation.
    flipped += !warm_start->surface.twins.empty();
  }
  EXPECT_GE(flipped, 4);
  // The kept triangulation applies to its own centres only.
  centers[7].x() += 1e-9;
  const auto moved =
      build_power_diagram(centers, steps[0], square, {}, false, PowerDiagramMethod::automatic, n, warm_start.get());
  const auto moved_cold = build_power_diagram(centers, steps[0], square);
  for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(moved[i].vertices, moved_cold[i].vertices) << i;
}

TEST(PowerDiagram, WarmStartOnExactlyDegenerateInput) {
  if (!has_regular_triangulation()) GTEST_SKIP() << "no regular triangulation in this build";
  // A grid (four cocircular sites at every cell corner) from a triangulation at perturbed
  // weights: the flips stop at one of the equally regular triangulations; the cells are the same.
  const int k = 40;
  std::vector<Vec2> centers;
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j) centers.emplace_back((i + 0.5) / k, (j + 0.5) / k);
  std::mt19937_64 random(5);
  std::uniform_real_distribution<double> uniform(-1, 1);
  std::vector<double> perturbed(centers.size());
  for (auto& w : perturbed) w = 0.05 * uniform(random) / (k * k);
  std::vector<double> equal(centers.size(), 0.0);
  const auto square = ConvexPolygon::rectangle(0, 0, 1, 1);
  const auto warm_start = make_power_diagram_warm_start();
  for (const std::vector<double>* weights : {&perturbed, &equal, &perturbed, &equal}) {
    const auto warm = build_power_diagram(centers, *weights, square, {}, false, PowerDiagramMethod::automatic,
                                          centers.size(), warm_start.get());
    const auto cold = build_power_diagram(centers, *weights, square);
    for (std::size_t i = 0; i < centers.size(); ++i) {
      EXPECT_NEAR(area(warm[i]), area(cold[i]), 1e-15) << i;
      EXPECT_EQ(long_edge_neighbors(warm[i]), long_edge_neighbors(cold[i])) << i;
      if (weights == &equal) {
        EXPECT_NEAR(area(warm[i]), 1.0 / (k * k), 1e-15) << i;
      }
    }
  }
  EXPECT_FALSE(warm_start->surface.twins.empty());
}

TEST(PowerDiagram, WarmStartOnUglyInput) {
  if (!has_regular_triangulation()) GTEST_SKIP() << "no regular triangulation in this build";
  // Sites on a coarse grid (many collinear and cocircular ones, some on the domain's boundary and
  // some repeated), through sequences of weights with equal, zero and spread values: the warm
  // start gives the cells of a build from scratch every time.
  std::mt19937_64 random(23);
  const auto square = ConvexPolygon::rectangle(0, 0, 1, 1);
  int flipped = 0;
  for (int trial = 0; trial < 40; ++trial) {
    std::uniform_int_distribution<int> coordinate(0, 6 + trial % 5);
    const double scale = 1.0 / (6 + trial % 5);
    std::vector<Vec2> centers(20 + static_cast<std::size_t>(trial) * 7);
    for (auto& c : centers) c = Vec2(coordinate(random) * scale, coordinate(random) * scale);
    if (trial % 2 == 0) {  // distinct grid points only: every site can be a vertex, so flips run
      std::sort(centers.begin(), centers.end(),
                [](const Vec2& a, const Vec2& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
      centers.erase(std::unique(centers.begin(), centers.end()), centers.end());
      std::shuffle(centers.begin(), centers.end(), random);
    }
    const std::size_t n = centers.size();
    const auto warm_start = make_power_diagram_warm_start();
    std::uniform_real_distribution<double> uniform(-1, 1);
    for (int step = 0; step < 6; ++step) {
      std::vector<double> weights(n, 0.0);
      const double spread = step % 3 == 0 ? 0.0 : (step % 3 == 1 ? 1e-4 : 1e-2) * scale * scale;
      for (auto& w : weights) w = spread * uniform(random);
      const auto warm =
          build_power_diagram(centers, weights, square, {}, false, PowerDiagramMethod::automatic, n, warm_start.get());
      const auto cold = build_power_diagram(centers, weights, square);
      for (std::size_t i = 0; i < n; ++i) {
        ASSERT_NEAR(area(warm[i]), area(cold[i]), 1e-15) << "trial " << trial << ", step " << step << ", cell " << i;
        ASSERT_EQ(long_edge_neighbors(warm[i]), long_edge_neighbors(cold[i]))
            << "trial " << trial << ", step " << step << ", cell " << i;
      }
      flipped += !warm_start->surface.twins.empty();
    }
  }
  EXPECT_GT(flipped, 40);  // the flips ran on many of these
}

TEST(PowerDiagram, SameCellsToTheLastBitAtEveryRun) {
  // The triangulation's storage order follows memory addresses; the cells must not.
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> uniform(0, 1);
  std::vector<Vec2> centers(2000);
  std::vector<double> weights(centers.size());
  for (auto& c : centers) c = Vec2(uniform(random), uniform(random));
  for (auto& w : weights) w = 1e-4 * uniform(random);
  const auto square = ConvexPolygon::rectangle(0, 0, 1, 1);
  for (const auto method : builders()) {
    const auto first = build_power_diagram(centers, weights, square, {}, false, method);
    std::vector<std::vector<double>> noise;  // other heap addresses for the next runs
    for (int run = 0; run < 4; ++run) {
      noise.emplace_back(static_cast<std::size_t>(1000 + 7919 * run), 1.0);
      const auto again = build_power_diagram(centers, weights, square, {}, false, method);
      for (std::size_t i = 0; i < centers.size(); ++i) {
        ASSERT_EQ(again[i].vertices, first[i].vertices) << name(method) << ", run " << run << ", cell " << i;
        ASSERT_EQ(again[i].neighbors, first[i].neighbors) << name(method) << ", run " << run << ", cell " << i;
      }
    }
  }
}

// From 20,000 sites the triangulation is built as two halves side by side, each certified against
// the sites it leaves out; a half that cannot be certified falls back to one triangulation. Both
// must give the kd-tree builder's cells, whatever the number of threads.
TEST(PowerDiagram, SplitTriangulationMatchesTheKdTree) {
  if (!has_regular_triangulation()) GTEST_SKIP() << "no regular triangulation in this build";
  std::mt19937_64 random(23);
  std::uniform_real_distribution<double> uniform(0, 1);
  const auto square = ConvexPolygon::rectangle(0, 0, 1, 1);
  const std::size_t n = 30000;
  std::vector<Vec2> centers(n);
  std::vector<double> weights(n);
  for (auto& c : centers) c = Vec2(uniform(random), uniform(random));
  for (auto& w : weights) w = 2e-5 * uniform(random);  // some cells a few times others
  std::vector<double> wide = weights;                  // three cells across the split, wider than its margin
  for (int k = 0; k < 3; ++k)
    wide[static_cast<std::size_t>(k)] = 0.02, centers[static_cast<std::size_t>(k)] = Vec2(0.5, 0.2 + 0.3 * k);
  for (const auto& [case_weights, what] : {std::pair{&weights, "certified halves"}, std::pair{&wide, "fallback"}}) {
    const auto expected = build_power_diagram(centers, *case_weights, square, {}, false, PowerDiagramMethod::kd_tree);
    std::vector<ChartCell> by_threads[2];
    for (int threads : {1, 2}) {
      omp_set_num_threads(threads);
      by_threads[threads - 1] =
          build_power_diagram(centers, *case_weights, square, {}, false, PowerDiagramMethod::regular_triangulation);
    }
    omp_set_num_threads(omp_get_num_procs());
    double total = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const auto& cell = by_threads[1][i];
      ASSERT_NEAR(area(cell), area(expected[i]), 1e-14) << what << ", cell " << i;
      ASSERT_EQ(long_edge_neighbors(cell), long_edge_neighbors(expected[i])) << what << ", cell " << i;
      ASSERT_EQ(cell.vertices, by_threads[0][i].vertices) << what << ": 1 and 2 threads differ at cell " << i;
      ASSERT_EQ(cell.neighbors, by_threads[0][i].neighbors) << what << ": 1 and 2 threads differ at cell " << i;
      total += area(cell);
    }
    EXPECT_NEAR(total, 1.0, 1e-12) << what;
  }
  {  // a 160 × 160 grid with equal weights (cocircular everywhere) straddles the split exactly
    const int k = 160;
    std::vector<Vec2> grid;
    for (int i = 0; i < k; ++i)
      for (int j = 0; j < k; ++j) grid.emplace_back((i + 0.5) / k, (j + 0.5) / k);
    const auto cells = build_power_diagram(grid, std::vector<double>(grid.size(), 0.0), square, {}, false,
                                           PowerDiagramMethod::regular_triangulation);
    for (std::size_t i = 0; i < cells.size(); ++i)
      ASSERT_NEAR(area(cells[i]), 1.0 / (k * k), 1e-15) << "grid cell " << i;
  }
  {  // a step that hides a site on either side of the split is seen as such
    std::vector<double> hiding = weights;
    hiding[n - 1] = -0.01;
    const auto cells =
        build_power_diagram(centers, hiding, square, {}, true, PowerDiagramMethod::regular_triangulation);
    EXPECT_TRUE(std::any_of(cells.begin(), cells.end(), [](const ChartCell& cell) { return cell.empty(); }));
  }
}

TEST(PowerDiagram, RegularTriangulationOnlyWhenBuilt) {
  std::vector<Vec2> centers{{0.2, 0.2}, {0.8, 0.8}};
  std::vector<double> weights{0, 0};
  const auto square = ConvexPolygon::rectangle(0, 0, 1, 1);
  if (has_regular_triangulation()) {
    EXPECT_NEAR(
        area(build_power_diagram(centers, weights, square, {}, false, PowerDiagramMethod::regular_triangulation)[0]),
        0.5, 1e-15);
  } else {
    EXPECT_THROW(
        (void)build_power_diagram(centers, weights, square, {}, false, PowerDiagramMethod::regular_triangulation),
        InputError);
  }
}

TEST(ChartDiagram, ClipKeepsLabels) {
  ChartCell cell{{{0, 0}, {1, 0}, {1, 1}, {0, 1}}, {-1, -2, -3, -4}};
  clip(cell, Vec2(-1, 0), 0.5, 7);  // keep x ≤ 0.5
  ASSERT_EQ(cell.size(), 4u);
  EXPECT_NEAR(area(cell), 0.5, 1e-15);
  int sevens = 0;
  for (int label : cell.neighbors) sevens += label == 7;
  EXPECT_EQ(sevens, 1);
}

/// Random lines around a point, counter-clockwise (tangent to circles of radii 0.5–1.5 around
/// `center` at sorted angles with gaps below π, so that they bound a cell).
void random_ordered_lines(std::mt19937_64& random, const Vec2& center, std::vector<Vec2>& normals,
                          std::vector<double>& offsets) {
  std::uniform_real_distribution<double> unit(0, 1);
  const int count = 3 + static_cast<int>(unit(random) * 10);
  std::vector<double> angles;
  do {
    angles.clear();
    for (int k = 0; k < count; ++k) angles.push_back(2 * std::numbers::pi * unit(random));
    std::sort(angles.begin(), angles.end());
  } while ([&] {
    for (std::size_t k = 0; k < angles.size(); ++k)
      if ((k + 1 < angles.size() ? angles[k + 1] : angles[0] + 2 * std::numbers::pi) - angles[k] >=
          0.9 * std::numbers::pi)
        return true;
    return false;
  }());
  normals.clear(), offsets.clear();
  for (double angle : angles) {
    const Vec2 outward(std::cos(angle), std::sin(angle));
    normals.push_back(-outward);  // keep (v − center)·outward ≤ radius
    offsets.push_back(outward.dot(center) + 0.5 + unit(random));
  }
}

TEST(ChartDiagram, CellFromOrderedLinesIsTheClippedCell) {
  // Where it answers, the cell read off the ordered lines is the one clipping a large square by
  // them gives (same labels in the same cyclic order, same vertices); where it declines, one of
  // the lines does not bound the cell (so a triangulation could not have listed it).
  std::mt19937_64 random(5);
  std::vector<Vec2> normals;
  std::vector<double> offsets;
  int answered = 0, declined = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Vec2 center(std::uniform_real_distribution<double>(-3, 3)(random),
                      std::uniform_real_distribution<double>(-3, 3)(random));
    random_ordered_lines(random, center, normals, offsets);
    std::vector<int> labels(normals.size());
    for (std::size_t k = 0; k < labels.size(); ++k) labels[k] = static_cast<int>(10 * k + 3);
    ChartCell clipped{{{-100, -100}, {100, -100}, {100, 100}, {-100, 100}}, {-1, -2, -3, -4}};
    for (std::size_t k = 0; k < normals.size(); ++k) clip(clipped, normals[k], offsets[k], labels[k]);
    ASSERT_TRUE(std::none_of(clipped.neighbors.begin(), clipped.neighbors.end(), is_boundary));
    ChartCell cell;
    if (!cell_from_ordered_lines(cell, normals, offsets, labels, 50)) {
      ++declined;
      EXPECT_LT(clipped.size(), normals.size()) << "trial " << trial;
      continue;
    }
    ++answered;
    ASSERT_EQ(cell.size(), clipped.size()) << "trial " << trial;
    const auto shift = static_cast<std::size_t>(
        std::find(clipped.neighbors.begin(), clipped.neighbors.end(), cell.neighbors[0]) - clipped.neighbors.begin());
    ASSERT_LT(shift, clipped.size());
    for (std::size_t k = 0; k < cell.size(); ++k) {
      const std::size_t m = (k + shift) % clipped.size();
      EXPECT_EQ(cell.neighbors[k], clipped.neighbors[m]) << "trial " << trial << ", edge " << k;
      EXPECT_LT((cell.vertices[k] - clipped.vertices[m]).norm(), 1e-12) << "trial " << trial << ", vertex " << k;
    }
  }
  // both outcomes happen on these lines
  EXPECT_GT(answered, 300);
  EXPECT_GT(declined, 100);
}

/// The power form's bisectors for build_chart_diagram_with_fixed_centers: in u = v − c_i,
/// −2d·u + |d|² + w_i − w_j ≥ 0 with d = c_j − c_i.
ChartBisector power_bisector(std::span<const Vec2> centers, std::span<const double> weights) {
  return [centers, weights](std::size_t i, std::size_t j) {
    const Vec2 d = centers[j] - centers[i];
    return ChartLine{-2 * d, d.squaredNorm() + weights[i] - weights[j]};
  };
}

TEST(ChartDiagram, FixedCentresWithPowerBisectorsGiveThePowerDiagram) {
  if (!has_regular_triangulation()) GTEST_SKIP() << "built without CGAL";
  // With the power form's own bisectors, the fixed-centre builder is build_power_diagram's
  // triangulation path to the last bit, warm-started or not; with shuffled bisectors it is not.
  std::mt19937_64 random(5);
  std::uniform_real_distribution<double> uniform(-1.2, 1.2);
  const ConvexPolygon domain({{-1, -1}, {1, -1}, {1.2, 0.5}, {0, 1}, {-1, 0.6}});
  const std::size_t n = 3000;
  std::vector<Vec2> centers(n);
  for (auto& c : centers) c = Vec2(uniform(random), uniform(random));
  const auto warm = make_power_diagram_warm_start();
  for (int round = 0; round < 3; ++round) {
    std::vector<double> weights(n);
    for (auto& w : weights) w = 0.002 * uniform(random);
    const auto expected =
        build_power_diagram(centers, weights, domain, {}, false, PowerDiagramMethod::regular_triangulation);
    const auto cells = build_chart_diagram_with_fixed_centers(centers, weights, power_bisector(centers, weights),
                                                              domain, false, warm.get());
    ASSERT_EQ(cells.size(), n);
    double total = 0;
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_EQ(cells[i].neighbors, expected[i].neighbors) << "round " << round << " cell " << i;
      ASSERT_EQ(cells[i].vertices, expected[i].vertices) << "round " << round << " cell " << i;
      total += area(cells[i]);
    }
    EXPECT_NEAR(total, domain.area(), 1e-12);
  }
  // Bisectors with the wrong sign: no cell in the domain is the power cell.
  std::vector<double> zero(n, 0.0);
  const auto flipped = [&](std::size_t i, std::size_t j) {
    const ChartLine line = power_bisector(centers, zero)(i, j);
    return ChartLine{-line.normal, -line.offset};
  };
  const auto wrong = build_chart_diagram_with_fixed_centers(centers, zero, flipped, domain);
  const auto right = build_power_diagram(centers, zero, domain);
  std::size_t cells_in_domain = 0, same = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (!right[i].empty()) ++cells_in_domain, same += wrong[i].vertices == right[i].vertices;
  EXPECT_GT(cells_in_domain, n / 2);
  EXPECT_EQ(same, 0U);
}

TEST(ChartDiagram, FixedCentresNeedOneWeightEach) {
  const std::vector<Vec2> centers{{0, 0}, {1, 0}};
  const std::vector<double> weights{0, 0, 0};
  const auto square = ConvexPolygon::rectangle(-1, -1, 2, 2);
  try {
    (void)build_chart_diagram_with_fixed_centers(centers, weights, power_bisector(centers, weights), square);
    FAIL() << "no error";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("fixed_power_weights: there are 3 power weights for 2 fixed centres"),
              std::string::npos)
        << error.what();
  }
}

TEST(ChartDiagram, NonFiniteInputsGiveEmptyCells) {
  // A centre, power weight or bisector that overflowed: empty cells (which a line search
  // rejects), never an infinity handed to the exact predicates (CGAL aborts on those).
  const auto square = ConvexPolygon::rectangle(-1, -1, 2, 2);
  const std::vector<Vec2> centers{{0, 0}, {0.5, 0}, {0, 0.5}, {0.5, 0.5}};
  const double infinity = std::numeric_limits<double>::infinity();
  const std::vector<double> zero(4, 0.0);
  for (const PowerDiagramMethod method : builders())
    for (const double bad : {infinity, -infinity, std::numeric_limits<double>::quiet_NaN()}) {
      SCOPED_TRACE(name(method));
      std::vector<double> weights{0, 0.1, bad, 0};
      for (const auto& cell : build_power_diagram(centers, weights, square, {}, false, method))
        EXPECT_TRUE(cell.empty());
      std::vector<Vec2> far = centers;
      far[1].y() = bad;
      for (const auto& cell : build_power_diagram(far, zero, square, {}, false, method)) EXPECT_TRUE(cell.empty());
    }
  if (!has_regular_triangulation()) return;
  std::vector<double> lifted(4, 0.0);
  lifted[3] = infinity;
  for (const auto& cell :
       build_chart_diagram_with_fixed_centers(centers, lifted, power_bisector(centers, zero), square))
    EXPECT_TRUE(cell.empty());
  // A bisector of cell 0 that is not finite empties that cell only.
  const auto overflowed = [&](std::size_t i, std::size_t j) {
    ChartLine line = power_bisector(centers, zero)(i, j);
    if (i == 0) line.offset = infinity;
    return line;
  };
  const auto cells = build_chart_diagram_with_fixed_centers(centers, zero, overflowed, square);
  EXPECT_TRUE(cells[0].empty());
  for (std::size_t i = 1; i < 4; ++i) EXPECT_FALSE(cells[i].empty());
}

TEST(ChartDiagram, CellFromOrderedLinesDeclinesWhatItCannotCertify) {
  // the unit square's four sides, counter-clockwise: bottom, right, top, left
  const std::vector<Vec2> normals{{0, 1}, {-1, 0}, {0, -1}, {1, 0}};
  const std::vector<double> offsets{1, 1, 1, 1};
  const std::vector<int> labels{0, 1, 2, 3};
  ChartCell cell;
  ASSERT_TRUE(cell_from_ordered_lines(cell, normals, offsets, labels, 1));
  ASSERT_EQ(cell.size(), 4u);
  EXPECT_EQ(cell.vertices[0], Vec2(-1, -1));  // where the left side (line 3) meets the bottom (line 0)
  EXPECT_EQ(cell.neighbors, labels);
  EXPECT_FALSE(cell_from_ordered_lines(cell, normals, offsets, labels, 0.99));  // a vertex beyond the bound
  // clockwise order
  const std::vector<Vec2> reversed(normals.rbegin(), normals.rend());
  EXPECT_FALSE(cell_from_ordered_lines(cell, reversed, offsets, labels, 10));
  // two consecutive parallel lines
  std::vector<Vec2> parallel = normals;
  parallel[1] = parallel[0];
  EXPECT_FALSE(cell_from_ordered_lines(cell, parallel, offsets, labels, 10));
  // a line that misses the cell (y ≥ 0.1x − 3, below the bottom y ≥ −1): an edge of negative length
  const std::vector<Vec2> five{{0, 1}, {-0.1, 1}, {-1, 0}, {0, -1}, {1, 0}};
  const std::vector<double> five_offsets{1, 3, 1, 1, 1};
  const std::vector<int> five_labels{0, 1, 2, 3, 4};
  EXPECT_FALSE(cell_from_ordered_lines(cell, five, five_offsets, five_labels, 100));
  std::vector<double> touching = five_offsets;
  touching[1] = 1.05;  // y ≥ 0.1x − 1.05 cuts the corner (1, −1) off: five edges
  ASSERT_TRUE(cell_from_ordered_lines(cell, five, touching, five_labels, 100));
  EXPECT_EQ(cell.size(), 5u);
  // fewer than three lines, or lists of different lengths
  EXPECT_FALSE(cell_from_ordered_lines(cell, std::span(normals).first(2), std::span(offsets).first(2),
                                       std::span(labels).first(2), 10));
  EXPECT_FALSE(cell_from_ordered_lines(cell, normals, std::span(offsets).first(3), labels, 10));
}

}  // namespace
}  // namespace sdot

// ------------------------------------------------------------------ hull updated by flips
namespace {

/// Points e^{h_i} p_i with p_i on a Fibonacci spiral (evenly spaced, so small heights keep
/// every point a hull vertex) and h_i uniform in [0, spread].
std::vector<sdot::Vec3> lifted_sphere_points(std::size_t n, double spread, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> height(0, spread);
  std::vector<sdot::Vec3> q(n);
  const double golden = M_PI * (3 - std::sqrt(5.0));
  for (std::size_t i = 0; i < n; ++i) {
    const double z = 1 - (2 * static_cast<double>(i) + 1) / static_cast<double>(n), r = std::sqrt(1 - z * z);
    const double angle = golden * static_cast<double>(i);
    q[i] = sdot::Vec3(r * std::cos(angle), r * std::sin(angle), z) * std::exp(height(rng));
  }
  return q;
}

/// The points with each height moved by an amount uniform in [-change, change].
std::vector<sdot::Vec3> heights_moved(std::vector<sdot::Vec3> points, double change, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> amount(-change, change);
  for (auto& x : points) x *= std::exp(amount(rng));
  return points;
}

std::size_t differing_edges(const sdot::Adjacency& a, const sdot::Adjacency& b, std::size_t n) {
  std::size_t differ = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto x = a.of(i), y = b.of(i);
    if (!std::equal(x.begin(), x.end(), y.begin(), y.end())) ++differ;
  }
  return differ;
}

}  // namespace

TEST(HullByFlips, ReachesQhullsHullFromANearbyHull) {
  // Heights small against the squared spacing (4π/n), as in a Newton iterate where every cell is
  // non-empty: every point is a hull vertex before and after.
  const std::size_t n = 2000;
  const auto before = lifted_sphere_points(n, 2e-4, 1);
  const auto after = heights_moved(before, 2e-4, 2);  // heights move: the hull's edges change
  const sdot::Hull3 start = sdot::convex_hull_3d(before, true);
  const sdot::Hull3 reference = sdot::convex_hull_3d(after);
  ASSERT_FALSE(start.surface.triangles.empty());
  ASSERT_EQ(std::count(start.is_vertex.begin(), start.is_vertex.end(), 1), static_cast<long>(n));
  ASSERT_EQ(std::count(reference.is_vertex.begin(), reference.is_vertex.end(), 1), static_cast<long>(n));
  const std::size_t changed = differing_edges(start.edges, reference.edges, n);
  std::printf("vertices whose hull neighbours changed: %zu of %zu\n", changed, n);
  ASSERT_GT(changed, n / 20) << "the test needs a start that differs from the answer";
  const auto flipped = sdot::convex_hull_3d_by_flips(after, start.surface);
  ASSERT_TRUE(flipped.has_value());
  EXPECT_EQ(differing_edges(flipped->edges, reference.edges, n), 0u);
  EXPECT_NEAR(flipped->max_facet_offset, reference.max_facet_offset, 1e-12);
  EXPECT_EQ(std::count(flipped->is_vertex.begin(), flipped->is_vertex.end(), 1), static_cast<long>(n));
  // and again from its own result: nothing to flip, the same hull
  const auto again = sdot::convex_hull_3d_by_flips(after, flipped->surface);
  ASSERT_TRUE(again.has_value());
  EXPECT_EQ(differing_edges(again->edges, reference.edges, n), 0u);
}

TEST(HullByFlips, StopsAtTheFirstPointInsideAndKeepsAStart) {
  // A line search's trial: some point falls inside. With stop_at_inside the flips stop there,
  // and the part-grown surface is a start from which the hull is still reached.
  const std::size_t n = 2000;
  const auto before = lifted_sphere_points(n, 2e-4, 1);
  const sdot::Hull3 start = sdot::convex_hull_3d(before, true);
  ASSERT_EQ(std::count(start.is_vertex.begin(), start.is_vertex.end(), 1), static_cast<long>(n));
  auto after = before;
  after[n / 3] *= 0.9;  // deep inside
  const auto stopped = sdot::convex_hull_3d_by_flips(after, start.surface, true);
  ASSERT_TRUE(stopped.has_value());
  EXPECT_TRUE(stopped->stopped_at_inside);
  EXPECT_FALSE(stopped->is_vertex[n / 3]);
  ASSERT_FALSE(stopped->surface.triangles.empty());
  const sdot::Hull3 reference = sdot::convex_hull_3d(after);
  const auto resumed = sdot::convex_hull_3d_by_flips(after, stopped->surface);
  ASSERT_TRUE(resumed.has_value());
  EXPECT_FALSE(resumed->stopped_at_inside);
  EXPECT_EQ(resumed->is_vertex, reference.is_vertex);
  EXPECT_EQ(differing_edges(resumed->edges, reference.edges, n), 0u);
  // Without a point inside, the flag changes nothing.
  const auto plain = sdot::convex_hull_3d_by_flips(before, start.surface, true);
  ASSERT_TRUE(plain.has_value());
  EXPECT_FALSE(plain->stopped_at_inside);
  EXPECT_EQ(differing_edges(plain->edges, start.edges, n), 0u);
}

TEST(HullByFlips, RemovesPointsThatFallInsideAndInsertsThoseThatComeOut) {
  // Heights far larger than the squared spacing (4π/n ≈ 6e-3), as in a damped Newton trial step:
  // many points are inside the hull, and which ones changes between the two hulls.
  const std::size_t n = 2000;
  const auto before = lifted_sphere_points(n, 0.03, 4);
  const auto after = lifted_sphere_points(n, 0.03, 5);
  const sdot::Hull3 start = sdot::convex_hull_3d(before, true);
  const sdot::Hull3 reference = sdot::convex_hull_3d(after);
  ASSERT_FALSE(start.surface.triangles.empty());
  std::size_t leave = 0, enter = 0, inside = 0;
  for (std::size_t i = 0; i < n; ++i) {
    leave += start.is_vertex[i] && !reference.is_vertex[i];
    enter += !start.is_vertex[i] && reference.is_vertex[i];
    inside += !reference.is_vertex[i];
  }
  std::printf("points leaving the hull: %zu, entering: %zu, inside after: %zu of %zu\n", leave, enter, inside, n);
  ASSERT_GT(leave, n / 20) << "the test needs vertices that must be removed";
  ASSERT_GT(enter, n / 20) << "the test needs points that must be inserted";
  const auto flipped = sdot::convex_hull_3d_by_flips(after, start.surface);
  ASSERT_TRUE(flipped.has_value());
  EXPECT_EQ(flipped->is_vertex, reference.is_vertex);
  EXPECT_EQ(differing_edges(flipped->edges, reference.edges, n), 0u);
  EXPECT_NEAR(flipped->max_facet_offset, reference.max_facet_offset, 1e-12);
  // back to the first hull from the second one's surface
  const auto back = sdot::convex_hull_3d_by_flips(before, flipped->surface);
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->is_vertex, start.is_vertex);
  EXPECT_EQ(differing_edges(back->edges, start.edges, n), 0u);
  // one point pushed deep inside, and a start that misses a point (the hull of the others)
  auto pushed = after;
  const auto vertex = static_cast<std::size_t>(std::find(reference.is_vertex.begin(), reference.is_vertex.end(), 1) -
                                               reference.is_vertex.begin());
  pushed[vertex] *= 0.5;
  const auto without = sdot::convex_hull_3d_by_flips(pushed, flipped->surface);
  ASSERT_TRUE(without.has_value());
  EXPECT_FALSE(without->is_vertex[vertex]);
  EXPECT_EQ(without->is_vertex, sdot::convex_hull_3d(pushed).is_vertex);
  std::vector<sdot::Vec3> fewer(after.begin(), after.end() - 1);
  const auto grown = sdot::convex_hull_3d_by_flips(after, sdot::convex_hull_3d(fewer, true).surface);
  ASSERT_TRUE(grown.has_value());
  EXPECT_EQ(grown->is_vertex, reference.is_vertex);
  EXPECT_EQ(differing_edges(grown->edges, reference.edges, n), 0u);
}

TEST(HullByFlips, ALargeUpdateIsTheHullAndTheSameTriangulationOnAnyThreadCount) {
  // The start's edges are tested in parallel and only the edges that operations change are tested
  // again: with many parallel chunks and tens of thousands of flips, removals and insertions the
  // result is still Qhull's hull, triangle for triangle the same on 1 and 2 threads.
  const std::size_t n = 40000;
  const auto before = lifted_sphere_points(n, 1e-4, 8);
  auto after = heights_moved(before, 1e-4, 9);
  std::mt19937 rng(10);
  for (int k = 0; k < 200; ++k) after[rng() % n] *= 0.9995;  // pushed inside: removals
  const sdot::Hull3 start = sdot::convex_hull_3d(before, true);
  const sdot::Hull3 reference = sdot::convex_hull_3d(after);
  ASSERT_GT(differing_edges(start.edges, reference.edges, n), n / 4) << "the update must change many edges";
  ASSERT_GT(std::count(reference.is_vertex.begin(), reference.is_vertex.end(), 0), 50) << "and remove points";
  std::optional<sdot::Hull3> by_threads[2];
  for (int threads : {1, 2}) {
    omp_set_num_threads(threads);
    by_threads[threads - 1] = sdot::convex_hull_3d_by_flips(after, start.surface, false, true);
  }
  omp_set_num_threads(omp_get_num_procs());
  for (const auto& hull : by_threads) {
    ASSERT_TRUE(hull.has_value());
    EXPECT_EQ(hull->is_vertex, reference.is_vertex);
    EXPECT_EQ(differing_edges(hull->edges, reference.edges, n), 0u);
    EXPECT_NEAR(hull->max_facet_offset, reference.max_facet_offset, 1e-12);
  }
  EXPECT_EQ(by_threads[0]->surface.triangles, by_threads[1]->surface.triangles);
  EXPECT_EQ(by_threads[0]->surface.opposite, by_threads[1]->surface.opposite);
}

TEST(HullByFlips, FromScratchWhereTheUpdateGetsStuck) {
  // Flips from an arbitrary start can get stuck on a reflex edge whose reflex corner keeps a
  // degree above 3 (found by a search over seeds: 1 of 156 such configurations). The sphere's
  // builder then grows the hull from scratch, where insertion does not get stuck.
  const std::size_t n = 2000;
  auto before = lifted_sphere_points(n, 1e-3, 35);
  auto after = before;
  std::mt19937 rng(35);
  for (int k = 0; k < 20; ++k) after[rng() % n] *= std::exp(0.1);  // 20 cells grow and swallow neighbours
  for (int k = 0; k < 20; ++k) before[rng() % n] *= std::exp(0.1);
  const sdot::Hull3 reference = sdot::convex_hull_3d(after);
  const auto update = sdot::convex_hull_3d_by_flips(after, sdot::convex_hull_3d(before, true).surface);
  EXPECT_FALSE(update.has_value()) << "this start no longer gets stuck: find another one for this test";
  const auto scratch = sdot::convex_hull_3d_by_flips(after, {});
  ASSERT_TRUE(scratch.has_value());
  EXPECT_EQ(scratch->is_vertex, reference.is_vertex);
  EXPECT_EQ(differing_edges(scratch->edges, reference.edges, n), 0u);
}

TEST(HullByFlips, GivesUpWhereOnlyQhullCanAnswer) {
  const std::size_t n = 500;
  const auto points = lifted_sphere_points(n, 2e-4, 3);
  const sdot::Hull3 start = sdot::convex_hull_3d(points, true);
  ASSERT_FALSE(start.surface.triangles.empty());
  // a point moved across the sphere: its old triangles face the origin
  auto moved = points;
  moved[11] = -moved[11];
  EXPECT_FALSE(sdot::convex_hull_3d_by_flips(moved, start.surface).has_value());
  // a start that names a point that does not exist
  std::vector<sdot::Vec3> fewer(points.begin(), points.end() - 1);
  EXPECT_FALSE(sdot::convex_hull_3d_by_flips(fewer, start.surface).has_value());
  // no tetrahedron of the points holds the origin: all on one side of a plane
  std::vector<sdot::Vec3> cap;
  for (const auto& x : points)
    if (x.z() > 0.1) cap.push_back(x);
  EXPECT_FALSE(sdot::convex_hull_3d_by_flips(cap, {}).has_value());
}

TEST(HullByFlips, BuildsTheHullFromScratchByInsertion) {
  // No start: a tetrahedron, then every point inserted where it lies above the surface.
  for (const double spread : {0.0, 2e-4, 0.03}) {
    const std::size_t n = 5000;
    auto points = lifted_sphere_points(n, spread, 6);
    std::shuffle(points.begin(), points.end(), std::mt19937(7));  // no spatial order to help the walks
    const sdot::Hull3 reference = sdot::convex_hull_3d(points);
    const auto built = sdot::convex_hull_3d_by_flips(points, {});
    ASSERT_TRUE(built.has_value()) << "spread " << spread;
    EXPECT_EQ(built->is_vertex, reference.is_vertex) << "spread " << spread;
    EXPECT_EQ(differing_edges(built->edges, reference.edges, n), 0u) << "spread " << spread;
    EXPECT_NEAR(built->max_facet_offset, reference.max_facet_offset, 1e-12);
  }
}
