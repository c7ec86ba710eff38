#pragma once
// The typed conformance suite of the Geometry concept. Every geometry instantiates it once:
//
//   template <> struct sdot::testing::ConformanceTraits<MyGeometry> { ... see below ... };
//   INSTANTIATE_TYPED_TEST_SUITE_P(MyGeometry, GeometryConformance, ::testing::Types<MyGeometry>);
//
// ConformanceTraits<G> provides:
//   static G geometry();                                    // a source domain of moderate size
//   static std::vector<typename G::Point> random_sites(std::size_t n, std::mt19937_64& random);
//                                                           // sites spread over the domain
//   static TwoSiteCase<G> two_site_case();                  // math.md §4.3 closed form
//   static ScalarField<typename G::Point> smooth_density(); // a positive non-uniform ρ
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <vector>

#include "sdot/error.hpp"
#include "sdot/solver.hpp"

namespace sdot::testing {

/// Two sites whose exact weight difference is known.
template <class G>
struct TwoSiteCase {
  G geometry;
  std::vector<typename G::Point> sites;
  Eigen::VectorXd masses;
  double expected_weight_difference;  // w_0 − w_1
};

template <class G>
struct ConformanceTraits;

/// The message of the InputError that `f()` throws, or "(no InputError)".
template <class F>
std::string input_error(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

/// Central finite differences of the masses with respect to the weights, column j.
template <class G, class D>
Eigen::VectorXd mass_derivative(const G& geometry, const D& density, std::span<const typename G::Point> sites,
                                const Eigen::VectorXd& weights, Eigen::Index j, double delta) {
  Eigen::VectorXd plus = weights, minus = weights;
  plus[j] += delta;
  minus[j] -= delta;
  const auto up = evaluate(geometry, density, sites, plus, false);
  const auto down = evaluate(geometry, density, sites, minus, false);
  return (up.masses - down.masses) / (2 * delta);
}

/// Dense Hessian ∂μ(W_i)/∂w_j from the facet weights of an evaluation.
template <class Point>
Eigen::MatrixXd dense_hessian(const Evaluation<Point>& evaluation) {
  const auto n = evaluation.masses.size();
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(n, n);
  for (const auto& t : evaluation.facet_weights) {
    h(t.row(), t.col()) -= t.value();
    h(t.col(), t.row()) -= t.value();
    h(t.row(), t.row()) += t.value();
    h(t.col(), t.col()) += t.value();
  }
  return h;
}

/// Max over columns of |H_j − FD_j|∞ / |H|∞: the relative Hessian error against finite differences.
template <class G, class D>
double hessian_fd_error(const G& geometry, const D& density, std::span<const typename G::Point> sites,
                        const Eigen::VectorXd& weights, double delta = 1e-6) {
  const auto evaluation = evaluate(geometry, density, sites, weights, true);
  const Eigen::MatrixXd h = dense_hessian(evaluation);
  double worst = 0;
  const double scale = h.cwiseAbs().maxCoeff();
  for (Eigen::Index j = 0; j < h.cols(); ++j) {
    const Eigen::VectorXd fd = mass_derivative(geometry, density, sites, weights, j, delta);
    worst = std::max(worst, (h.col(j) - fd).cwiseAbs().maxCoeff() / scale);
  }
  return worst;
}

/// Weights of a converged solve, used as a generic non-trivial evaluation point.
template <class G, class D>
Eigen::VectorXd solved_weights(const G& geometry, const D& density, std::span<const typename G::Point> sites,
                               const Eigen::VectorXd& masses) {
  const auto result = solve(geometry, density, sites, masses);
  EXPECT_TRUE(result.summary.converged()) << result.summary.message;
  return result.weights;
}

/// n masses log-uniform in [1, ratio].
inline Eigen::VectorXd log_uniform_masses(std::size_t n, double ratio, std::mt19937_64& random) {
  std::uniform_real_distribution<double> uniform(0, 1);
  Eigen::VectorXd masses(static_cast<Eigen::Index>(n));
  for (auto& m : masses) m = std::pow(ratio, uniform(random));
  return masses;
}

template <class G>
class GeometryConformance : public ::testing::Test {
 protected:
  using Traits = ConformanceTraits<G>;
  using Point = typename G::Point;
  std::mt19937_64 random{12345};

  Eigen::VectorXd varying_masses(std::size_t n, double ratio) { return log_uniform_masses(n, ratio, random); }
};

TYPED_TEST_SUITE_P(GeometryConformance);

TYPED_TEST_P(GeometryConformance, MassesSumToSourceMass) {
  using T = typename TestFixture::Traits;
  const auto geometry = T::geometry();
  const auto sites = T::random_sites(200, this->random);
  const auto reference = evaluate(geometry, UniformDensity{}, std::span(sites), geometry.default_weights(sites), false);
  const double total = reference.masses.sum();
  std::normal_distribution<double> normal(0, 1);
  for (int trial = 0; trial < 3; ++trial) {
    Eigen::VectorXd weights = geometry.default_weights(sites);
    const double spread = 0.02 * total / 200;
    for (auto& w : weights) w += spread * normal(this->random);
    const auto evaluation = evaluate(geometry, UniformDensity{}, std::span(sites), weights, false);
    EXPECT_NEAR(evaluation.masses.sum(), total, 1e-11 * total);
    EXPECT_GE(evaluation.masses.minCoeff(), 0.0);
  }
}

TYPED_TEST_P(GeometryConformance, GradientIsMassMinusTarget) {
  // E(w) = ∫ min_i(c_i − w_i) dμ ... its derivative is μ(W_i) − ν_i: check E by FD of the
  // transport cost identity ∂/∂w_j [Σ_i ∫_{W_i} (c_i − w_i) dμ] = −μ(W_j).
  using T = typename TestFixture::Traits;
  const auto geometry = T::geometry();
  const auto sites = T::random_sites(40, this->random);
  const Eigen::VectorXd weights =
      solved_weights(geometry, UniformDensity{}, std::span(sites), this->varying_masses(40, 5));
  auto envelope = [&](const Eigen::VectorXd& w) {
    const auto e = evaluate(geometry, UniformDensity{}, std::span(sites), w, false);
    double value = 0;
    for (Eigen::Index i = 0; i < w.size(); ++i) value += e.integrals[i].cost - w[i] * e.masses[i];
    return value;
  };
  const auto at = evaluate(geometry, UniformDensity{}, std::span(sites), weights, false);
  const double delta = 1e-6;
  for (Eigen::Index j : {0, 7, 23}) {
    Eigen::VectorXd plus = weights, minus = weights;
    plus[j] += delta;
    minus[j] -= delta;
    const double derivative = (envelope(plus) - envelope(minus)) / (2 * delta);
    EXPECT_NEAR(derivative, -at.masses[j], 1e-7 * at.masses.sum()) << "site " << j;
  }
}

TYPED_TEST_P(GeometryConformance, HessianMatchesFiniteDifferences) {
  using T = typename TestFixture::Traits;
  const auto geometry = T::geometry();
  const auto sites = T::random_sites(30, this->random);
  const Eigen::VectorXd masses = this->varying_masses(30, 10);
  const Eigen::VectorXd weights = solved_weights(geometry, UniformDensity{}, std::span(sites), masses);
  const auto evaluation = evaluate(geometry, UniformDensity{}, std::span(sites), weights, true);
  const Eigen::MatrixXd h = dense_hessian(evaluation);
  EXPECT_LT((h - h.transpose()).cwiseAbs().maxCoeff(), 1e-14 * h.cwiseAbs().maxCoeff());
  EXPECT_LT(h.rowwise().sum().cwiseAbs().maxCoeff(), 1e-12 * h.cwiseAbs().maxCoeff());
  const double error = hessian_fd_error(geometry, UniformDensity{}, std::span(sites), weights);
  std::printf("  uniform density: Hessian vs finite differences, relative error %.2e\n", error);
  EXPECT_LT(error, 1e-6);
}

TYPED_TEST_P(GeometryConformance, FunctionDensityHessianMatchesFiniteDifferences) {
  using T = typename TestFixture::Traits;
  const auto geometry = T::geometry();
  const auto sites = T::random_sites(25, this->random);
  const FunctionDensity<typename TestFixture::Point> density{T::smooth_density(), 10};
  const Eigen::VectorXd weights = solved_weights(geometry, density, std::span(sites), this->varying_masses(25, 4));
  const double error = hessian_fd_error(geometry, density, std::span(sites), weights);
  std::printf("  function density: Hessian vs finite differences, relative error %.2e\n", error);
  EXPECT_LT(error, 1e-6);
}

TYPED_TEST_P(GeometryConformance, NewtonConvergesOnRandomProblems) {
  using T = typename TestFixture::Traits;
  const auto geometry = T::geometry();
  for (std::size_t n : {10, 100, 1000, 10000}) {
    const auto sites = T::random_sites(n, this->random);
    const Eigen::VectorXd masses = this->varying_masses(n, 100);
    const auto result = solve(geometry, UniformDensity{}, std::span(sites), masses);
    std::printf("  N = %5zu: %s in %d iterations, max relative error %.2e, %.3f s\n", n,
                std::string(to_string(result.summary.status)).c_str(), result.summary.iterations,
                result.summary.max_relative_error, result.summary.timings.total_s);
    ASSERT_TRUE(result.summary.converged()) << "N = " << n << ": " << result.summary.message;
    EXPECT_LE(result.summary.max_relative_error, 1e-9);
    const Eigen::VectorXd relative = (result.masses - result.target_masses).cwiseQuotient(result.target_masses);
    EXPECT_LE(relative.cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_NEAR(result.weights.mean(), 0, 1e-12 * (1 + result.weights.cwiseAbs().maxCoeff()));
  }
}

// The multigrid path solves each Newton system only as accurately as the step needs; the result
// must still meet the tolerance and agree with exact (LDLᵀ) Newton steps.
TYPED_TEST_P(GeometryConformance, MultigridNewtonAgreesWithLdlt) {
  using T = typename TestFixture::Traits;
  const auto geometry = T::geometry();
  const std::size_t n = 3000;
  const auto sites = T::random_sites(n, this->random);
  const Eigen::VectorXd masses = this->varying_masses(n, 100);
  Options options;
  options.linear_solver = LinearSolverKind::multigrid;
  const auto multigrid = solve(geometry, UniformDensity{}, std::span(sites), masses, options);
  options.linear_solver = LinearSolverKind::ldlt;
  const auto ldlt = solve(geometry, UniformDensity{}, std::span(sites), masses, options);
  std::printf("  multigrid: %d iterations, %.3f s of linear solves; LDLT: %d, %.3f s\n", multigrid.summary.iterations,
              multigrid.summary.timings.linear_solve_s, ldlt.summary.iterations, ldlt.summary.timings.linear_solve_s);
  ASSERT_TRUE(multigrid.summary.converged()) << multigrid.summary.message;
  ASSERT_TRUE(ldlt.summary.converged()) << ldlt.summary.message;
  EXPECT_LE(multigrid.summary.max_relative_error, options.tolerance);
  EXPECT_LE(multigrid.summary.iterations, ldlt.summary.iterations + 2);
  // Both meet the masses to 1e-9, so the weights agree to about 1e-9 over the Hessian's scale.
  const double scale = 1 + ldlt.weights.cwiseAbs().maxCoeff();
  EXPECT_LT((multigrid.weights - ldlt.weights).cwiseAbs().maxCoeff(), 1e-6 * scale);
}

// From the Voronoi diagram of uniform random sites some cells are far below their target; the
// Newton step that grows them to at most 4× their mass is taken in full, where the step towards
// the true targets emptied cells and was halved two or three times (plane, sphere, H², torus).
TYPED_TEST_P(GeometryConformance, FirstNewtonStepFromVoronoiIsFull) {
  using T = typename TestFixture::Traits;
  const auto geometry = T::geometry();
  const std::size_t n = 20000;
  const auto sites = T::random_sites(n, this->random);
  const auto voronoi = evaluate(geometry, UniformDensity{}, std::span(sites), geometry.default_weights(sites), false);
  const Eigen::VectorXd masses = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(n), voronoi.masses.mean());
  const double start_error = ((masses - voronoi.masses).cwiseQuotient(masses)).cwiseAbs().maxCoeff();
  // The cap's and the polygon's random sites leave cells 32× and 715× their target (this seed);
  // there the first step stays damped (½ and ⅛), as before the limit. Not this test's case.
  if (start_error > 10) GTEST_SKIP() << "a cell starts at " << 1 + start_error << "× its target mass";
  const auto result = solve(geometry, UniformDensity{}, std::span(sites), masses);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  ASSERT_GE(result.summary.history.size(), 2u);
  const auto& start = result.summary.history[0];
  const auto& first = result.summary.history[1];
  std::printf("  max relative error %.3f → %.3f with step %g\n", start.max_relative_error, first.max_relative_error,
              first.step);
  EXPECT_GT(start.max_relative_error, 3) << "the start no longer has a cell 4× off: the test checks nothing";
  EXPECT_EQ(first.step, 1);
  EXPECT_LT(first.max_relative_error, 0.5 * start.max_relative_error);
}

TYPED_TEST_P(GeometryConformance, TwoSiteClosedForm) {
  using T = typename TestFixture::Traits;
  const auto c = T::two_site_case();
  Options options;
  options.tolerance = 1e-13;
  const auto result = solve(c.geometry, UniformDensity{}, std::span(c.sites), c.masses, options);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  const double difference = result.weights[0] - result.weights[1];
  std::printf("  w0 - w1 = %.15f, closed form %.15f\n", difference, c.expected_weight_difference);
  EXPECT_NEAR(difference, c.expected_weight_difference, 2e-11);
}

TYPED_TEST_P(GeometryConformance, VoronoiTargetsGiveConstantWeights) {
  using T = typename TestFixture::Traits;
  const auto geometry = T::geometry();
  const auto sites = T::random_sites(300, this->random);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(300);
  const auto voronoi = evaluate(geometry, UniformDensity{}, std::span(sites), zero, false);
  ASSERT_GT(voronoi.masses.minCoeff(), 0);
  // From a random start, to 1e-12: the weights must come back to a constant.
  std::normal_distribution<double> normal(0, 1);
  Eigen::VectorXd start = geometry.default_weights(sites);
  const double scale = 0.005 * voronoi.masses.mean();
  for (auto& w : start) w += scale * normal(this->random);
  Options options;
  options.tolerance = 1e-12;
  const auto result = solve(geometry, UniformDensity{}, std::span(sites), voronoi.masses, options, start);
  ASSERT_TRUE(result.summary.converged()) << result.summary.message;
  const double spread = result.weights.maxCoeff() - result.weights.minCoeff();
  std::printf("  weight spread %.2e after %d iterations\n", spread, result.summary.iterations);
  EXPECT_LT(spread, 1e-10);
}

TYPED_TEST_P(GeometryConformance, CellsAreConsistent) {
  // Every Laguerre edge i→j has a matching edge j→i of the same length; centroids are finite.
  using T = typename TestFixture::Traits;
  const auto geometry = T::geometry();
  const auto sites = T::random_sites(500, this->random);
  const auto result = solve(geometry, UniformDensity{}, std::span(sites), this->varying_masses(500, 20));
  ASSERT_TRUE(result.summary.converged());
  const auto adjacency = result.adjacency();
  for (std::size_t i = 0; i < adjacency.size(); ++i)
    for (int j : adjacency[i]) {
      const auto& back = adjacency[static_cast<std::size_t>(j)];
      EXPECT_TRUE(std::binary_search(back.begin(), back.end(), static_cast<int>(i))) << i << " -> " << j;
    }
  for (const auto& c : result.centroids) EXPECT_TRUE(c.allFinite());
  EXPECT_TRUE(std::isfinite(result.transport_cost));
  EXPECT_GT(result.transport_cost, 0);
}

// The solver works on the sites in a space-filling-curve order of its own; the result must come
// back in the caller's order, cells and neighbour labels included, whatever that order is.
TYPED_TEST_P(GeometryConformance, ResultFollowsTheCallersSiteOrder) {
  using T = typename TestFixture::Traits;
  const auto geometry = T::geometry();
  const std::size_t n = 300;
  const auto sites = T::random_sites(n, this->random);
  const Eigen::VectorXd masses = this->varying_masses(n, 4);
  Options options;
  options.rescale_masses = true;
  options.tolerance = 1e-10;
  const auto forward = solve(geometry, UniformDensity{}, std::span(sites), masses, options);
  ASSERT_TRUE(forward.summary.converged()) << forward.summary.message;
  std::vector<std::size_t> shuffled(n);
  std::iota(shuffled.begin(), shuffled.end(), 0);
  std::shuffle(shuffled.begin(), shuffled.end(), this->random);
  std::vector<typename TestFixture::Point> permuted_sites(n);
  Eigen::VectorXd permuted_masses(static_cast<Eigen::Index>(n));
  for (std::size_t k = 0; k < n; ++k) {
    permuted_sites[k] = sites[shuffled[k]];
    permuted_masses[static_cast<Eigen::Index>(k)] = masses[static_cast<Eigen::Index>(shuffled[k])];
  }
  const auto permuted = solve(geometry, UniformDensity{}, std::span(permuted_sites), permuted_masses, options);
  ASSERT_TRUE(permuted.summary.converged()) << permuted.summary.message;
  const auto forward_adjacency = forward.adjacency(), permuted_adjacency = permuted.adjacency();
  for (std::size_t k = 0; k < n; ++k) {
    const auto i = static_cast<Eigen::Index>(shuffled[k]), j = static_cast<Eigen::Index>(k);
    EXPECT_NEAR(permuted.weights[j], forward.weights[i], 1e-8) << "site " << k;
    EXPECT_NEAR(permuted.masses[j], forward.masses[i], 1e-9 * forward.masses[i]) << "site " << k;
    EXPECT_LT((permuted.centroids[k] - forward.centroids[shuffled[k]]).norm(), 1e-8) << "site " << k;
    std::vector<int> mapped;
    for (int label : permuted_adjacency[k])
      mapped.push_back(static_cast<int>(shuffled[static_cast<std::size_t>(label)]));
    std::sort(mapped.begin(), mapped.end());
    EXPECT_EQ(mapped, forward_adjacency[shuffled[k]]) << "site " << k;
  }
}

REGISTER_TYPED_TEST_SUITE_P(GeometryConformance, MassesSumToSourceMass, GradientIsMassMinusTarget,
                            HessianMatchesFiniteDifferences, FunctionDensityHessianMatchesFiniteDifferences,
                            NewtonConvergesOnRandomProblems, MultigridNewtonAgreesWithLdlt,
                            FirstNewtonStepFromVoronoiIsFull, TwoSiteClosedForm, VoronoiTargetsGiveConstantWeights,
                            CellsAreConsistent, ResultFollowsTheCallersSiteOrder);

}  // namespace sdot::testing
