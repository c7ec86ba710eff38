#pragma once
// The typed conformance suite of partial transport (sdot/partial.hpp). A geometry with ball cuts
// instantiates it next to GeometryConformance:
//
//   template <> struct sdot::testing::PartialTraits<MyGeometry> { ... see below ... };
//   INSTANTIATE_TYPED_TEST_SUITE_P(MyGeometry, PartialConformance, ::testing::Types<MyGeometry>);
//
// PartialTraits<G> provides (ConformanceTraits<G> supplies geometry() and random_sites()):
//   static double disc_area(double radius);          // area of a ball of this radius
//   static std::vector<Point> separate_sites();      // a few sites far apart, well inside the domain
//   static Point arc_point(const Point& site, const Point& a, const Point& b, double t);
//                                                    // the point at fraction t of the arc a → b
#include "conformance/conformance.hpp"
#include "sdot/partial.hpp"

namespace sdot::testing {

template <class G>
struct PartialTraits;

template <class G>
class PartialConformance : public ::testing::Test {
 protected:
  using Traits = ConformanceTraits<G>;
  using Partial = PartialTraits<G>;
  using Point = typename G::Point;
  std::mt19937_64 random{2024};

  /// Weights at which the balls cut most cells: the solution for masses of `fraction` of the source.
  Eigen::VectorXd solved(const G& geometry, const std::vector<Point>& sites, double fraction) {
    Options options;
    options.partial = true;
    const double source =
        evaluate(geometry, UniformDensity{}, std::span(sites), geometry.default_weights(sites), false).masses.sum();
    const auto result =
        solve(geometry, UniformDensity{}, std::span(sites), equal_masses(sites.size(), fraction * source), options);
    EXPECT_TRUE(result.summary.converged()) << result.summary.message;
    return result.weights;
  }
};

TYPED_TEST_SUITE_P(PartialConformance);

TYPED_TEST_P(PartialConformance, SeparateSitesGetTheDiscsOfTheirMasses) {
  using P = typename TestFixture::Partial;
  const auto geometry = TestFixture::Traits::geometry();
  const auto sites = P::separate_sites();
  const auto n = static_cast<Eigen::Index>(sites.size());
  Options options;
  options.partial = true;
  options.tolerance = 1e-12;
  const double source =
      evaluate(geometry, UniformDensity{}, std::span(sites), geometry.default_weights(sites), false).masses.sum();
  const Eigen::VectorXd masses = Eigen::VectorXd::LinSpaced(n, 0.01, 0.02) * source / static_cast<double>(n);
  const auto result = solve(geometry, UniformDensity{}, std::span(sites), masses, options);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double radius = result.ball_radii[i];
    EXPECT_NEAR(P::disc_area(radius), masses[i], 1e-12 * masses[i]) << "site " << i;
    EXPECT_LT((result.centroids[static_cast<std::size_t>(i)] - sites[static_cast<std::size_t>(i)]).norm(),
              1e-10 * radius);
    // Every vertex of the cell is on the circle: the whole disc.
    for (const auto& v : result.diagram.cells[static_cast<std::size_t>(i)].vertices)
      EXPECT_NEAR(geometry.cost(v, sites[static_cast<std::size_t>(i)]), result.weights[i], 1e-12);
  }
}

TYPED_TEST_P(PartialConformance, ArcIntegralsMatchFinePolygons) {
  // Each cut cell against the same cell with its arcs replaced by 4000 chords each, integrated
  // with the exact polygon formulas: the chords' error is O(1/4000²).
  using P = typename TestFixture::Partial;
  const auto geometry = TestFixture::Traits::geometry();
  const auto sites = TestFixture::Traits::random_sites(40, this->random);
  const Eigen::VectorXd weights = this->solved(geometry, sites, 0.5);
  const auto evaluation =
      evaluate(geometry, UniformDensity{}, std::span(sites), weights, false, nullptr, true, false, true);
  int arcs = 0;
  for (std::size_t i = 0; i < sites.size(); ++i) {
    const auto& cell = evaluation.diagram.cells[i];
    Cell<typename TestFixture::Point> fine;
    for (std::size_t k = 0; k < cell.size(); ++k) {
      fine.vertices.push_back(cell.vertices[k]);
      fine.neighbors.push_back(is_ball_arc(cell.neighbors[k]) ? 0 : cell.neighbors[k]);
      if (!is_ball_arc(cell.neighbors[k])) continue;
      ++arcs;
      constexpr int chords = 4000;
      for (int m = 1; m < chords; ++m) {
        fine.vertices.push_back(
            P::arc_point(sites[i], cell.vertices[k], cell.vertices[(k + 1) % cell.size()], double(m) / chords));
        fine.neighbors.push_back(0);
      }
    }
    if (cell.empty()) continue;
    const auto exact = geometry.integrate(cell, sites[i], true);
    const auto chords = geometry.integrate(fine, sites[i], true);
    const double scale = exact.mass;
    EXPECT_NEAR(exact.mass, chords.mass, 1e-6 * scale) << "cell " << i;
    EXPECT_LT((exact.first_moment - chords.first_moment).norm(), 1e-6 * scale) << "cell " << i;
    EXPECT_NEAR(exact.cost, chords.cost, 1e-6 * std::abs(exact.cost) + 1e-14) << "cell " << i;
  }
  EXPECT_GT(arcs, 20);
}

TYPED_TEST_P(PartialConformance, HessianWithArcsMatchesFiniteDifferences) {
  const auto geometry = TestFixture::Traits::geometry();
  const auto sites = TestFixture::Traits::random_sites(30, this->random);
  for (double fraction : {0.3, 0.8}) {
    const Eigen::VectorXd weights = this->solved(geometry, sites, fraction);
    const auto at = evaluate(geometry, UniformDensity{}, std::span(sites), weights, true, nullptr, false, false, true);
    Eigen::MatrixXd h = dense_hessian(at);
    h.diagonal() += at.arc_weights;
    EXPECT_LT((h - h.transpose()).cwiseAbs().maxCoeff(), 1e-14 * h.cwiseAbs().maxCoeff());
    EXPECT_GT(at.arc_weights.sum(), 0);
    double worst = 0;
    const double delta = 1e-6;
    for (Eigen::Index j = 0; j < h.cols(); ++j) {
      Eigen::VectorXd plus = weights, minus = weights;
      plus[j] += delta, minus[j] -= delta;
      const auto up = evaluate(geometry, UniformDensity{}, std::span(sites), plus, false, nullptr, false, false, true);
      const auto down =
          evaluate(geometry, UniformDensity{}, std::span(sites), minus, false, nullptr, false, false, true);
      const Eigen::VectorXd fd = (up.masses - down.masses) / (2 * delta);
      worst = std::max(worst, (h.col(j) - fd).cwiseAbs().maxCoeff() / h.cwiseAbs().maxCoeff());
    }
    std::printf("  partial transport (%.0f%% of the mass): Hessian vs finite differences, relative error %.2e\n",
                100 * fraction, worst);
    EXPECT_LT(worst, 1e-6);
  }
}

TYPED_TEST_P(PartialConformance, SolutionCellsLieInTheirBalls) {
  const auto geometry = TestFixture::Traits::geometry();
  for (std::size_t n : {10, 300, 3000}) {
    const auto sites = TestFixture::Traits::random_sites(n, this->random);
    Options options;
    options.partial = true;
    const double source =
        evaluate(geometry, UniformDensity{}, std::span(sites), geometry.default_weights(sites), false).masses.sum();
    const Eigen::VectorXd masses = log_uniform_masses(n, 10, this->random);
    const Eigen::VectorXd targets = masses * (0.6 * source / masses.sum());
    const auto result = solve(geometry, UniformDensity{}, std::span(sites), targets, options);
    std::printf("  N = %4zu: %s in %d iterations, max relative error %.2e\n", n,
                std::string(to_string(result.summary.status)).c_str(), result.summary.iterations,
                result.summary.max_relative_error);
    ASSERT_TRUE(result.summary.converged()) << result.summary.message;
    EXPECT_EQ(result.summary.mass_scale, 1);
    EXPECT_LT((result.masses - targets).cwiseQuotient(targets).cwiseAbs().maxCoeff(), 1e-9);
    for (std::size_t i = 0; i < n; ++i) {
      for (const auto& v : result.diagram.cells[i].vertices)
        ASSERT_LE(geometry.cost(v, sites[i]), result.weights[static_cast<Eigen::Index>(i)] * (1 + 1e-9) + 1e-15)
            << "site " << i;
      EXPECT_NEAR(geometry.ball_radius(result.weights[static_cast<Eigen::Index>(i)]),
                  result.ball_radii[static_cast<Eigen::Index>(i)], 0);
    }
  }
}

TYPED_TEST_P(PartialConformance, BadInputIsNamed) {
  const auto geometry = TestFixture::Traits::geometry();
  const auto sites = TestFixture::Traits::random_sites(20, this->random);
  Options options;
  options.partial = true;
  const double source =
      evaluate(geometry, UniformDensity{}, std::span(sites), geometry.default_weights(sites), false).masses.sum();
  EXPECT_NE(input_error([&] {
              (void)solve(geometry, UniformDensity{}, std::span(sites), equal_masses(20, 1.001 * source), options);
            }).find("masses: partial transport needs masses that sum to less than the source mass"),
            std::string::npos);
  const FunctionDensity<typename TestFixture::Point> density{TestFixture::Traits::smooth_density(), 4};
  EXPECT_NE(input_error([&] {
              (void)solve(geometry, density, std::span(sites), equal_masses(20, source / 2), options);
            }).find("density: partial transport is implemented for the uniform density only"),
            std::string::npos);
  // Initial weights that leave a cut cell empty (negative weights: empty balls) are named.
  EXPECT_NE(input_error([&] {
              (void)solve(geometry, UniformDensity{}, std::span(sites), equal_masses(20, source / 2), options,
                          Eigen::VectorXd::Constant(20, -1.0));
            }).find("weights["),
            std::string::npos);
}

REGISTER_TYPED_TEST_SUITE_P(PartialConformance, SeparateSitesGetTheDiscsOfTheirMasses, ArcIntegralsMatchFinePolygons,
                            HessianWithArcsMatchesFiniteDifferences, SolutionCellsLieInTheirBalls, BadInputIsNamed);

}  // namespace sdot::testing
