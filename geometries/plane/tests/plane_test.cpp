// The plane: conformance suite plus plane-specific cases (degenerate sites, sites outside the
// domain, densities, bad input).
#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <numbers>
#include <random>

#include "conformance/conformance.hpp"
#include "conformance/partial_conformance.hpp"
#include "sdot/geometries/plane.hpp"
#include "sdot/solver.hpp"

namespace sdot::testing {

template <>
struct ConformanceTraits<Plane> {
  static Plane geometry() { return Plane(ConvexPolygon({{0, 0}, {2, 0}, {2.4, 1.2}, {1, 2}, {-0.3, 1}})); }
  static std::vector<Plane::Point> random_sites(std::size_t n, std::mt19937_64& random) {
    std::uniform_real_distribution<double> uniform(-0.3, 2.4);
    std::vector<Plane::Point> sites;
    const auto g = geometry();
    while (sites.size() < n) {
      const Plane::Point p(uniform(random), uniform(random));
      if (g.domain().contains(p)) sites.push_back(p);
    }
    return sites;
  }
  static TwoSiteCase<Plane> two_site_case() {
    const double a = 1, s = 0.3, c = 0.27;
    Eigen::VectorXd masses(2);
    masses << 2 * a * (a - c), 2 * a * (a + c);
    return {Plane(ConvexPolygon::rectangle(-a, -a, a, a)), {{s, 0}, {-s, 0}}, masses, -2 * c * s};
  }
  static ScalarField<Plane::Point> smooth_density() {
    return [](const Plane::Point& x) { return 1 + 0.8 * std::sin(2 * x.x()) * std::cos(3 * x.y()); };
  }
};

INSTANTIATE_TYPED_TEST_SUITE_P(Plane, GeometryConformance, ::testing::Types<Plane>);

template <>
struct PartialTraits<Plane> {
  static double disc_area(double radius) { return std::numbers::pi * radius * radius; }
  static std::vector<Plane::Point> separate_sites() { return {{1.0, 0.9}, {0.2, 0.5}, {1.8, 0.4}, {1.2, 1.6}}; }
  static Plane::Point arc_point(const Plane::Point& site, const Plane::Point& a, const Plane::Point& b, double t) {
    const Plane::Point u = a - site, v = b - site;
    double angle = std::atan2(u.x() * v.y() - u.y() * v.x(), u.dot(v));
    if (angle < 0) angle += 2 * std::numbers::pi;
    const double c = std::cos(t * angle), s = std::sin(t * angle);
    return site + Plane::Point(c * u.x() - s * u.y(), s * u.x() + c * u.y());
  }
};

INSTANTIATE_TYPED_TEST_SUITE_P(Plane, PartialConformance, ::testing::Types<Plane>);

namespace {

std::vector<Plane::Point> random_unit_square(std::size_t n, unsigned seed) {
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> uniform(0, 1);
  std::vector<Plane::Point> sites(n);
  for (auto& s : sites) s = {uniform(random), uniform(random)};
  return sites;
}

TEST(Plane, ExactIntegralsOfASquareCell) {
  const Plane plane;
  Cell<Plane::Point> cell{{{0, 0}, {1, 0}, {1, 1}, {0, 1}}, {-1, -2, -3, -4}};
  const auto integrals = plane.integrate(cell, Plane::Point(0.25, 0.5));
  EXPECT_NEAR(integrals.mass, 1, 1e-15);
  EXPECT_NEAR((integrals.first_moment - Plane::Point(0.5, 0.5)).norm(), 0, 1e-15);
  // ∫|x − y|²/2 over the unit square = (1/12 + 1/12 + 0.25²)/2.
  EXPECT_NEAR(integrals.cost, (1.0 / 6 + 0.0625) / 2, 1e-15);
}

TEST(Plane, QuadratureMatchesExactFormulas) {
  const Plane plane;
  Cell<Plane::Point> cell{{{0.1, 0}, {1, 0.2}, {0.8, 0.9}, {0.2, 0.7}}, {-1, -2, -3, -4}};
  const Plane::Point site(0.3, 0.4);
  const auto exact = plane.integrate(cell, site);
  const auto quadrature = plane.integrate(
      cell, site, [](const Plane::Point&) { return 1.0; }, 3);
  EXPECT_NEAR(quadrature.mass, exact.mass, 1e-15);
  EXPECT_NEAR((quadrature.first_moment - exact.first_moment).norm(), 0, 1e-15);
  EXPECT_NEAR(quadrature.cost, exact.cost, 1e-15);
  // ρ = 1 + x: mass = area + first moment x.
  const auto linear = plane.integrate(
      cell, site, [](const Plane::Point& x) { return 1 + x.x(); }, 2);
  EXPECT_NEAR(linear.mass, exact.mass + exact.first_moment.x(), 1e-15);
}

TEST(Plane, SingleSiteOwnsTheDomain) {
  const Plane plane;
  const std::vector<Plane::Point> sites{{3, 4}};
  const auto result = solve(plane, UniformDensity{}, std::span(sites), equal_masses(1));
  ASSERT_TRUE(result.summary.converged());
  EXPECT_NEAR(result.masses[0], 1, 1e-15);
  EXPECT_NEAR((result.centroids[0] - Plane::Point(0.5, 0.5)).norm(), 0, 1e-14);
}

TEST(Plane, SitesOutsideTheDomainConverge) {
  std::mt19937_64 random(3);
  std::uniform_real_distribution<double> uniform(-2, 3);
  std::vector<Plane::Point> sites(200);
  for (auto& s : sites) s = {uniform(random), uniform(random)};
  const auto result = solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(200));
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  for (const auto& c : result.centroids) EXPECT_TRUE(Plane().domain().contains(c, 1e-12));
}

TEST(Plane, CollinearSites) {
  std::vector<Plane::Point> sites;
  for (int i = 0; i < 50; ++i) sites.emplace_back(0.1 + 0.016 * i, 0.5);
  Eigen::VectorXd masses(50);
  for (int i = 0; i < 50; ++i) masses[i] = 1 + i;
  const auto result = solve(Plane(), UniformDensity{}, std::span(sites), masses);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  // Cells are vertical strips: the x-extent of strip i is proportional to its mass.
  EXPECT_NEAR(result.masses.sum(), 1, 1e-13);
  const double error = hessian_fd_error(Plane(), UniformDensity{}, std::span(sites), result.weights);
  EXPECT_LT(error, 1e-6);
}

TEST(Plane, CoCircularSitesHaveAnExactHessian) {
  // A regular grid is maximally degenerate: every 4 neighbouring sites are co-circular.
  std::vector<Plane::Point> sites;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) sites.emplace_back((i + 0.5) / 6, (j + 0.5) / 6);
  // Plus points on a circle around the centre.
  for (int k = 0; k < 12; ++k)
    sites.emplace_back(0.5 + 0.31 * std::cos(2 * std::numbers::pi * (k + 0.5) / 12),
                       0.5 + 0.31 * std::sin(2 * std::numbers::pi * (k + 0.5) / 12));
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(sites.size()));
  const double error = hessian_fd_error(Plane(), UniformDensity{}, std::span(sites), zero, 1e-7);
  std::printf("  co-circular: Hessian vs finite differences %.2e\n", error);
  EXPECT_LT(error, 1e-6);
  const auto result = solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(sites.size()));
  EXPECT_TRUE(result.summary.converged()) << result.summary.message;
}

TEST(Plane, LineSearchHandlesEmptyCells) {
  // Masses varying 1000× from Voronoi: the full Newton step empties cells; KMT halves it.
  const auto sites = random_unit_square(400, 5);
  Eigen::VectorXd masses(400);
  for (int i = 0; i < 400; ++i) masses[i] = sites[i].x() < 0.5 ? 1 : 1000;
  const auto result = solve(Plane(), UniformDensity{}, std::span(sites), masses);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  bool damped = false;
  for (const auto& r : result.summary.history) damped = damped || (r.iteration > 0 && r.step < 1);
  EXPECT_TRUE(damped) << "expected at least one damped step";
  for (Eigen::Index i = 0; i < 400; ++i) EXPECT_GT(result.masses[i], 0);
}

TEST(Plane, FunctionDensityConverges) {
  const auto sites = random_unit_square(500, 9);
  const FunctionDensity<Plane::Point> density{[](const Plane::Point& x) { return 0.2 + 4 * x.x() * x.x(); }, 6};
  Options options;
  options.tolerance = 1e-9;
  const auto result = solve(Plane(), density, std::span(sites), equal_masses(500), options);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  // Total mass ∫(0.2 + 4x²) over the unit square = 0.2 + 4/3.
  EXPECT_NEAR(result.summary.source_mass, 0.2 + 4.0 / 3, 1e-12);
}

TEST(Plane, FunctionDensityEqualToOneMatchesUniform) {
  const auto sites = random_unit_square(100, 4);
  const auto uniform = solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(100));
  const FunctionDensity<Plane::Point> one{[](const Plane::Point&) { return 1.0; }, 2};
  const auto function = solve(Plane(), one, std::span(sites), equal_masses(100));
  EXPECT_LT((uniform.weights - function.weights).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_NEAR(uniform.transport_cost, function.transport_cost, 1e-12);
}

TEST(Plane, ConjugateGradientAgreesWithCholesky) {
  const auto sites = random_unit_square(300, 11);
  Options options;
  options.linear_solver = LinearSolverKind::conjugate_gradient;
  const auto cg = solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(300), options);
  const auto ldlt = solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(300));
  ASSERT_TRUE(cg.summary.converged()) << cg.summary.message;
  EXPECT_LT((cg.weights - ldlt.weights).cwiseAbs().maxCoeff(), 1e-8);
}

TEST(Plane, SymbolicFactorisationIsReusedWhileThePatternHolds) {
  const auto sites = random_unit_square(200, 2);
  const auto evaluation = evaluate(Plane(), UniformDensity{}, std::span(sites), Eigen::VectorXd::Zero(200), true);
  const SparseMatrix hessian = detail::assemble_hessian(200, evaluation.facet_weights);
  detail::NewtonLinearSolver<DefaultLinearSolver> linear{Options{}};
  Eigen::VectorXd rhs = Eigen::VectorXd::LinSpaced(200, -1, 1), direction;
  rhs.array() -= rhs.mean();
  ASSERT_TRUE(linear.solve(hessian, rhs, direction));
  ASSERT_TRUE(linear.solve(SparseMatrix(2 * hessian), rhs, direction));
  EXPECT_EQ(linear.analyses(), 1);
  EXPECT_LT((hessian * direction * 2 - rhs).norm(), 1e-10 * rhs.norm());
  // A changed pattern needs a new analysis.
  auto weights = evaluation.facet_weights;
  weights.emplace_back(0, 199, 0.5);
  const SparseMatrix larger = detail::assemble_hessian(200, weights);
  ASSERT_TRUE(linear.solve(larger, rhs, direction));
  EXPECT_EQ(linear.analyses(), 2);
  EXPECT_LT((larger * direction - rhs).norm(), 1e-10 * rhs.norm());
}

TEST(Plane, ConjugateGradientSolverKeepsItsMatrixAlive) {
  const auto sites = random_unit_square(100, 6);
  const auto evaluation = evaluate(Plane(), UniformDensity{}, std::span(sites), Eigen::VectorXd::Zero(100), true);
  detail::NewtonLinearSolver<ConjugateGradientSolver> linear{Options{}};
  Eigen::VectorXd rhs = Eigen::VectorXd::LinSpaced(100, -1, 1), direction;
  rhs.array() -= rhs.mean();
  const SparseMatrix hessian = detail::assemble_hessian(100, evaluation.facet_weights);
  ASSERT_TRUE(linear.solve(hessian, rhs, direction));
  EXPECT_LT((hessian * direction - rhs).norm(), 1e-8 * rhs.norm());
}

TEST(Plane, IterationLimitIsAStatusNotAnError) {
  const auto sites = random_unit_square(300, 8);
  Options options;
  options.max_iterations = 1;
  Eigen::VectorXd masses = Eigen::VectorXd::LinSpaced(300, 1, 100);
  const auto result = solve(Plane(), UniformDensity{}, std::span(sites), masses, options);
  EXPECT_EQ(result.summary.status, Status::iteration_limit);
  EXPECT_NE(result.summary.message.find("iteration limit"), std::string::npos);
}

TEST(Plane, PrecisionFloorIsAStatusNotAFailure) {
  const auto sites = random_unit_square(2000, 12);
  Options options;
  options.tolerance = 1e-17;  // below double precision
  const auto result = solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(2000), options);
  EXPECT_EQ(result.summary.status, Status::precision_floor) << result.summary.message;
  EXPECT_TRUE(result.summary.usable());
  EXPECT_FALSE(result.summary.converged());
  EXPECT_LT(result.summary.max_relative_error, 1e-11);
  EXPECT_NE(result.summary.message.find("precision floor"), std::string::npos);
}

// Counts the cells it integrates: a solve's diagram evaluations are the count over the sites.
struct CountingDensity : UniformDensity {
  std::shared_ptr<std::atomic<long>> cells = std::make_shared<std::atomic<long>>(0);
  template <class G>
  [[nodiscard]] CellIntegrals<typename G::Point> integrate_cell(const G& geometry, const Cell<typename G::Point>& cell,
                                                                const typename G::Point& site,
                                                                bool with_cost = true) const {
    ++*cells;
    return UniformDensity::integrate_cell(geometry, cell, site, with_cost);
  }
};

TEST(Plane, PrecisionFloorStopsTheLineSearchEarly) {
  // At the floor no step decreases the error, and each halving costs a diagram (57 diagrams here
  // with all 40 halvings): near the floor the line search stops at step 2⁻¹⁰.
  const auto sites = random_unit_square(2000, 12);
  Options options;
  options.tolerance = 1e-17;  // below double precision
  const CountingDensity density;
  const auto result = solve(Plane(), density, std::span(sites), equal_masses(2000), options);
  ASSERT_EQ(result.summary.status, Status::precision_floor) << result.summary.message;
  const long evaluations = *density.cells / 2000;
  // the start, the trials of each accepted step (step 2⁻ᵏ after k rejected ones), those of the last
  // line search (at most 11), the restored diagram and the transport cost's pass
  long accepted_trials = 0;
  for (const auto& record : result.summary.history)
    if (record.iteration > 0) accepted_trials += 1 + std::lround(-std::log2(record.step));
  std::printf("  %d iterations, %ld diagram evaluations, %ld for the accepted steps\n", result.summary.iterations,
              evaluations, accepted_trials);
  EXPECT_LE(evaluations, 1 + accepted_trials + 11 + 1 + 1);
}

TEST(Plane, LargeProblemsReachTightTolerances) {
  // Summation round-off of Σν − Σμ (~1e-13 at 10⁴ cells) must not land on one site: that
  // capped the pinned site at 1.3e-9. The floor is now ~1e-12, so ask for 1e-11.
  const auto sites = random_unit_square(16000, 13);
  Options options;
  options.tolerance = 1e-11;
  const auto result = solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(16000), options);
  EXPECT_TRUE(result.summary.converged()) << result.summary.message;
}

TEST(Plane, CallbackSeesEveryIteration) {
  const auto sites = random_unit_square(100, 1);
  std::vector<IterationRecord> seen;
  Options options;
  options.callback = [&](const IterationRecord& r) { seen.push_back(r); };
  const auto result = solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(100), options);
  ASSERT_EQ(seen.size(), result.summary.history.size());
  EXPECT_EQ(seen.back().iteration, result.summary.iterations);
  EXPECT_LE(seen.back().max_relative_error, 1e-9);
}

// ---- bad input -------------------------------------------------------------------------

TEST(PlaneBadInput, NonFiniteCoordinates) {
  std::vector<Plane::Point> sites{{0.1, 0.1}, {NAN, 0.5}, {0.9, 0.9}};
  EXPECT_EQ(input_error([&] { solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(3)); }),
            "sites[1]: coordinate is not finite");
  sites[1] = {0.5, INFINITY};
  EXPECT_EQ(input_error([&] { solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(3)); }),
            "sites[1]: coordinate is not finite");
}

TEST(PlaneBadInput, NonPositiveMasses) {
  const auto sites = random_unit_square(3, 1);
  Eigen::VectorXd masses(3);
  masses << 1, 0, 1;
  EXPECT_EQ(input_error([&] { solve(Plane(), UniformDensity{}, std::span(sites), masses); }).rfind("masses[1]:", 0),
            0u);
  masses << 1, 1, -2;
  EXPECT_EQ(input_error([&] { solve(Plane(), UniformDensity{}, std::span(sites), masses); }).rfind("masses[2]:", 0),
            0u);
  masses << 1, NAN, 1;
  EXPECT_EQ(input_error([&] { solve(Plane(), UniformDensity{}, std::span(sites), masses); }).rfind("masses[1]:", 0),
            0u);
  EXPECT_NE(input_error([&] {
              solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(2));
            }).find("2 masses for 3 sites"),
            std::string::npos);
}

TEST(PlaneBadInput, DuplicateSites) {
  std::vector<Plane::Point> sites{{0.1, 0.1}, {0.5, 0.5}, {0.9, 0.2}, {0.5, 0.5}};
  EXPECT_EQ(input_error([&] { solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(4)); }),
            "sites[3]: duplicate of sites[1]");
}

TEST(PlaneBadInput, DegenerateDomains) {
  EXPECT_EQ(input_error([] { ConvexPolygon({{0, 0}, {1, 0}}); }).rfind("domain:", 0), 0u);
  EXPECT_EQ(input_error([] { ConvexPolygon({{0, 0}, {1, 0}, {2, 0}}); }), "domain: polygon is degenerate (zero area)");
  EXPECT_EQ(input_error([] {
              ConvexPolygon({{0, 0}, {1, 0}, {1, 0}, {0, 1}});
            }),
            "domain[2]: vertex coincides with the previous one");
  EXPECT_EQ(input_error([] {
              ConvexPolygon({{0, 0}, {2, 0}, {1, 0.2}, {1, 2}});
            }),
            "domain[2]: polygon is not convex at this vertex");
  EXPECT_EQ(input_error([] { ConvexPolygon({{0, 0}, {1, NAN}, {0, 1}}); }), "domain[1]: vertex is not finite");
}

TEST(PlaneBadInput, MassesNotSummingToTheSourceMass) {
  const auto sites = random_unit_square(50, 3);
  const Eigen::VectorXd masses = Eigen::VectorXd::Constant(50, 1.0);  // sum 50, source mass 1
  // Documented default: rescaled, with the factor reported.
  const auto result = solve(Plane(), UniformDensity{}, std::span(sites), masses);
  ASSERT_TRUE(result.summary.converged());
  EXPECT_NEAR(result.summary.mass_scale, 1.0 / 50, 1e-15);
  EXPECT_NEAR(result.masses.sum(), 1, 1e-12);
  // With rescaling off they are rejected.
  Options strict;
  strict.rescale_masses = false;
  const auto message = input_error([&] { solve(Plane(), UniformDensity{}, std::span(sites), masses, strict); });
  EXPECT_EQ(message.rfind("masses: they sum to 50", 0), 0u) << message;
}

TEST(PlaneBadInput, InvalidOptions) {
  const auto sites = random_unit_square(5, 3);
  Options options;
  options.tolerance = -1;
  EXPECT_EQ(input_error([&] {
              solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(5), options);
            }).rfind("options.tolerance:", 0),
            0u);
  options = {};
  options.max_step_halvings = 0;
  EXPECT_EQ(options.validation_error().rfind("options.max_step_halvings:", 0), 0u);
}

TEST(PlaneBadInput, InitialWeightsThatEmptyACell) {
  const std::vector<Plane::Point> sites{{0.2, 0.5}, {0.8, 0.5}};
  Eigen::VectorXd weights(2);
  weights << 10, 0;  // site 0 takes everything
  EXPECT_EQ(input_error([&] {
              solve(Plane(), UniformDensity{}, std::span(sites), equal_masses(2), {}, weights);
            }).rfind("weights[1]: the initial weights leave the cell of site 1 empty", 0),
            0u);
}

}  // namespace
}  // namespace sdot::testing
