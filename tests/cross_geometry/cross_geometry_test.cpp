// Cross-geometry convergence tests (math.md §4): they tie the plane, the sphere and the
// hyperbolic plane together and check the solver against answers that share no code with it.
// Every test prints the figures it checks as a table.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include "cross_geometry/discrete_ot.hpp"
#include "sdot/geometries/hyperbolic.hpp"
#include "sdot/geometries/plane.hpp"
#include "sdot/geometries/sphere.hpp"
#include "sdot/solver.hpp"

namespace sdot::testing {
namespace {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

Options tight(double tolerance = 1e-13) {
  Options options;
  options.tolerance = tolerance;
  return options;
}

Eigen::VectorXd centred(const Eigen::VectorXd& v) {
  return (v.array() - v.mean()).matrix();
}

double rate(double coarse, double fine) {
  return std::log2(coarse / fine);
}

// ---- 1. small-region limit -------------------------------------------------------------

Vec3 gnomonic(const Vec2& v) {
  return Vec3(v.x(), v.y(), 1).normalized();
}
Vec3 klein(const Vec2& k) {
  return Vec3(k.x(), k.y(), 1) / std::sqrt(1 - k.squaredNorm());
}

struct SmallRegionProblem {
  std::vector<Vec2> sites;   // z_i in Ω = [−1, 1]²
  std::vector<Vec2> domain;  // Ω's corners
  Eigen::VectorXd masses;
};

SmallRegionProblem small_region_problem() {
  std::mt19937_64 random(2024);
  std::uniform_real_distribution<double> uniform(-0.9, 0.9);
  SmallRegionProblem p;
  p.domain = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
  for (int i = 0; i < 12; ++i) p.sites.emplace_back(uniform(random), uniform(random));
  p.masses.resize(12);
  for (int i = 0; i < 12; ++i) p.masses[i] = 1 + 0.5 * std::sin(3.0 * i);
  return p;
}

// f on Ω for the non-uniform case; the curved problems use ρ(x) = f(chart(x) / ε).
double smooth_profile(const Vec2& z) {
  return 1 + 0.4 * std::cos(1.3 * z.x()) * std::sin(0.9 * z.y() + 0.4);
}

struct LimitRow {
  double epsilon, sphere_error, hyperbolic_error, average_error;
};

std::vector<LimitRow> small_region_limit(bool uniform) {
  const auto p = small_region_problem();
  const Plane plane{ConvexPolygon(p.domain)};
  const FunctionDensity<Vec2> plane_density{smooth_profile, 12};
  const auto euclidean = uniform ? solve(plane, UniformDensity{}, std::span(p.sites), p.masses, tight())
                                 : solve(plane, plane_density, std::span(p.sites), p.masses, tight());
  EXPECT_TRUE(euclidean.summary.usable()) << euclidean.summary.message;
  const Eigen::VectorXd psi = centred(euclidean.weights);
  std::vector<LimitRow> rows;
  for (double epsilon : {0.4, 0.2, 0.1, 0.05, 0.025}) {
    std::vector<Vec3> sphere_sites, sphere_domain, hyperbolic_sites, hyperbolic_domain;
    for (const auto& z : p.sites)
      sphere_sites.push_back(gnomonic(epsilon * z)), hyperbolic_sites.push_back(klein(epsilon * z));
    for (const auto& z : p.domain)
      sphere_domain.push_back(gnomonic(epsilon * z)), hyperbolic_domain.push_back(klein(epsilon * z));
    const Sphere sphere = Sphere::polygon(sphere_domain);
    const Hyperbolic hyperbolic(hyperbolic_domain);
    Eigen::VectorXd h_sphere, h_hyperbolic;
    if (uniform) {
      const auto s = solve(sphere, UniformDensity{}, std::span(std::as_const(sphere_sites)), p.masses, tight());
      const auto h = solve(hyperbolic, UniformDensity{}, std::span(std::as_const(hyperbolic_sites)), p.masses, tight());
      EXPECT_TRUE(s.summary.usable() && s.summary.max_relative_error < 1e-11) << s.summary.message;
      EXPECT_TRUE(h.summary.usable() && h.summary.max_relative_error < 1e-11) << h.summary.message;
      h_sphere = s.weights, h_hyperbolic = h.weights;
    } else {
      const FunctionDensity<Vec3> sphere_density{
          [epsilon](const Vec3& x) { return smooth_profile(x.head<2>() / x.z() / epsilon); }, 12};
      const FunctionDensity<Vec3> hyperbolic_density{
          [epsilon](const Vec3& x) { return smooth_profile(x.head<2>() / x.z() / epsilon); }, 12};
      const auto s = solve(sphere, sphere_density, std::span(std::as_const(sphere_sites)), p.masses, tight(1e-12));
      const auto h =
          solve(hyperbolic, hyperbolic_density, std::span(std::as_const(hyperbolic_sites)), p.masses, tight(1e-12));
      EXPECT_TRUE(s.summary.usable() && s.summary.max_relative_error < 1e-11) << s.summary.message;
      EXPECT_TRUE(h.summary.usable() && h.summary.max_relative_error < 1e-11) << h.summary.message;
      h_sphere = s.weights, h_hyperbolic = h.weights;
    }
    const Eigen::VectorXd scaled_sphere = centred(h_sphere) / (epsilon * epsilon);
    const Eigen::VectorXd scaled_hyperbolic = centred(h_hyperbolic) / (epsilon * epsilon);
    rows.push_back({epsilon, (scaled_sphere - psi).cwiseAbs().maxCoeff(),
                    (scaled_hyperbolic - psi).cwiseAbs().maxCoeff(),
                    ((scaled_sphere + scaled_hyperbolic) / 2 - psi).cwiseAbs().maxCoeff()});
  }
  return rows;
}

void check_small_region_limit(bool uniform) {
  const auto rows = small_region_limit(uniform);
  std::printf("  small-region limit, %s density (N = 12, Ω = [-1,1]²)\n", uniform ? "uniform" : "smooth non-uniform");
  std::printf("  %8s | %12s %6s | %12s %6s | %12s %6s\n", "epsilon", "|hS/e²-psi|", "rate", "|hH/e²-psi|", "rate",
              "|avg - psi|", "rate");
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const auto& r = rows[k];
    if (k == 0) {
      std::printf("  %8.4f | %12.3e %6s | %12.3e %6s | %12.3e %6s\n", r.epsilon, r.sphere_error, "", r.hyperbolic_error,
                  "", r.average_error, "");
      continue;
    }
    const auto& q = rows[k - 1];
    std::printf("  %8.4f | %12.3e %6.2f | %12.3e %6.2f | %12.3e %6.2f\n", r.epsilon, r.sphere_error,
                rate(q.sphere_error, r.sphere_error), r.hyperbolic_error, rate(q.hyperbolic_error, r.hyperbolic_error),
                r.average_error, rate(q.average_error, r.average_error));
  }
  // The observed rate over ε = 0.4 … 0.025 (a least-squares slope of log error against log ε).
  auto slope = [&](auto error) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (const auto& r : rows) {
      const double x = std::log(r.epsilon), y = std::log(error(r));
      sx += x, sy += y, sxx += x * x, sxy += x * y;
    }
    const double n = static_cast<double>(rows.size());
    return (n * sxy - sx * sy) / (n * sxx - sx * sx);
  };
  const double sphere_rate = slope([](const LimitRow& r) { return r.sphere_error; });
  const double hyperbolic_rate = slope([](const LimitRow& r) { return r.hyperbolic_error; });
  const double average_rate = slope([](const LimitRow& r) { return r.average_error; });
  std::printf("  observed rates: sphere %.3f, hyperbolic %.3f, average %.3f\n", sphere_rate, hyperbolic_rate,
              average_rate);
  EXPECT_NEAR(sphere_rate, 2.0, 0.25);
  EXPECT_NEAR(hyperbolic_rate, 2.0, 0.25);
  EXPECT_NEAR(average_rate, 4.0, 0.5);
}

TEST(SmallRegionLimit, UniformDensity) {
  check_small_region_limit(true);
}
TEST(SmallRegionLimit, SmoothNonUniformDensity) {
  check_small_region_limit(false);
}

// ---- per-geometry problems for tests 2, 3 and 5 ---------------------------------------------

struct PlaneCase {
  static Plane geometry() { return Plane(); }
  static std::vector<Vec2> sample(std::size_t m, std::mt19937_64& random) {
    std::uniform_real_distribution<double> uniform(0, 1);
    std::vector<Vec2> points(m);
    for (auto& p : points) p = {uniform(random), uniform(random)};
    return points;
  }
  static const char* name() { return "plane"; }
};

struct SphereCase {
  static Sphere geometry() { return Sphere(); }
  static std::vector<Vec3> sample(std::size_t m, std::mt19937_64& random) {
    std::normal_distribution<double> normal(0, 1);
    std::vector<Vec3> points(m);
    for (auto& p : points) p = Vec3(normal(random), normal(random), normal(random)).normalized();
    return points;
  }
  static const char* name() { return "sphere"; }
};

struct HyperbolicCase {
  static Hyperbolic geometry() { return Hyperbolic::regular_polygon(6, 1.2); }
  static std::vector<Vec3> sample(std::size_t m, std::mt19937_64& random) {
    return geometry().uniform_samples(m, random());
  }
  static const char* name() { return "hyperbolic"; }
};

template <class Case>
class CrossGeometry : public ::testing::Test {};
using Cases = ::testing::Types<PlaneCase, SphereCase, HyperbolicCase>;
TYPED_TEST_SUITE(CrossGeometry, Cases);

// ---- 2. an independent discrete OT check -------------------------------------------------------

TYPED_TEST(CrossGeometry, DiscreteTransportAgrees) {
  using Case = TypeParam;
  const auto geometry = Case::geometry();
  std::mt19937_64 random(77);
  const auto sites = Case::sample(20, random);
  Eigen::VectorXd masses(20);
  for (int i = 0; i < 20; ++i) masses[i] = 1 + 0.6 * std::cos(1.7 * i);
  const auto semi = solve(geometry, UniformDensity{}, std::span(std::as_const(sites)), masses, tight(1e-12));
  ASSERT_TRUE(semi.summary.converged()) << semi.summary.message;
  const Eigen::VectorXd h = centred(semi.weights);
  std::printf("  %s, N = 20: %6s | %10s %10s | %10s %10s | bound 6/sqrt(M)\n", Case::name(), "M", "differ", "",
              "|h_d - h|", "");
  for (int m : {500, 2000, 8000}) {
    std::mt19937_64 sampler(7000 + static_cast<unsigned>(m));
    const auto samples = Case::sample(static_cast<std::size_t>(m), sampler);
    Eigen::MatrixXd cost(m, 20);
    for (int s = 0; s < m; ++s)
      for (int i = 0; i < 20; ++i)
        cost(s, i) = geometry.cost(samples[static_cast<std::size_t>(s)], sites[static_cast<std::size_t>(i)]);
    const auto discrete = solve_discrete_transport(cost, integer_capacities(masses, m));
    int differ = 0;
    for (int s = 0; s < m; ++s) {
      Eigen::Index best = 0;
      (cost.row(s).transpose() - h).minCoeff(&best);
      differ += best != discrete.assignment[static_cast<std::size_t>(s)];
    }
    const double fraction = static_cast<double>(differ) / m;
    const double potential_error = (discrete.potentials - h).cwiseAbs().maxCoeff();
    const double bound = 6 / std::sqrt(static_cast<double>(m));
    std::printf("  %s %13d | %10.4f %10s | %10.4f %10s | %.4f\n", std::string(std::strlen(Case::name()), ' ').c_str(),
                m, fraction, "", potential_error, "", bound);
    EXPECT_LE(fraction, bound) << "M = " << m;
    EXPECT_LE(potential_error, bound) << "M = " << m;
  }
}

// ---- 3. Newton's local quadratic convergence --------------------------------------------------

TYPED_TEST(CrossGeometry, NewtonConvergesQuadratically) {
  using Case = TypeParam;
  const auto geometry = Case::geometry();
  std::mt19937_64 random(5);
  const auto sites = Case::sample(400, random);
  Eigen::VectorXd masses(400);
  for (int i = 0; i < 400; ++i) masses[i] = 1 + 3 * (i % 7) / 6.0;
  const auto result = solve(geometry, UniformDensity{}, std::span(std::as_const(sites)), masses, tight(1e-13));
  ASSERT_TRUE(result.summary.usable()) << result.summary.message;
  const auto& history = result.summary.history;
  std::printf("  %s, N = 400: iteration | max rel. error | step | e_{k+1}/e_k^2\n", Case::name());
  double worst_ratio = 0;
  int quadratic_steps = 0;
  for (std::size_t k = 0; k < history.size(); ++k) {
    const double e = history[k].max_relative_error;
    double ratio = NAN;
    if (k + 1 < history.size()) ratio = history[k + 1].max_relative_error / (e * e);
    std::printf("  %9d | %14.3e | %4g | %.3g\n", history[k].iteration, e, history[k].step, ratio);
    // Near the solution (e ≤ 0.05, full steps), and while the quadratic term e_k² stays well above
    // the round-off floor (~1e-12 in H²), the ratio must stay bounded.
    if (k + 1 < history.size() && e <= 0.05 && history[k + 1].step == 1 && e * e >= 1e-10) {
      worst_ratio = std::max(worst_ratio, ratio);
      ++quadratic_steps;
    }
  }
  std::printf("  worst e_{k+1}/e_k^2 near the solution: %.3g over %d steps\n", worst_ratio, quadratic_steps);
  EXPECT_GE(quadratic_steps, 1);
  EXPECT_LE(worst_ratio, 50.0);
}

// ---- 5. invariance ---------------------------------------------------------------------------

TEST(Invariance, PlaneRigidMotion) {
  std::mt19937_64 random(9);
  const auto sites = PlaneCase::sample(300, random);
  Eigen::VectorXd masses = Eigen::VectorXd::LinSpaced(300, 1, 4);
  const auto base = solve(Plane(), UniformDensity{}, std::span(sites), masses, tight(1e-12));
  const Eigen::Rotation2Dd rotation(0.7);
  const Vec2 translation(3, -2);
  auto move = [&](const Vec2& p) { return Vec2(rotation * p + translation); };
  std::vector<Vec2> moved_sites, moved_domain;
  for (const auto& s : sites) moved_sites.push_back(move(s));
  const Plane unit_square;
  for (const auto& v : unit_square.domain().vertices()) moved_domain.push_back(move(v));
  const auto moved = solve(Plane(ConvexPolygon(moved_domain)), UniformDensity{}, std::span(std::as_const(moved_sites)),
                           masses, tight(1e-12));
  ASSERT_TRUE(base.summary.converged() && moved.summary.converged());
  const double weight_change = (centred(base.weights) - centred(moved.weights)).cwiseAbs().maxCoeff();
  double centroid_change = 0;
  for (int i = 0; i < 300; ++i)
    centroid_change = std::max(centroid_change, (move(base.centroids[i]) - moved.centroids[i]).norm());
  std::printf("  plane rigid motion: max weight change %.2e, max centroid change %.2e, cost %.12f vs %.12f\n",
              weight_change, centroid_change, base.transport_cost, moved.transport_cost);
  EXPECT_LT(weight_change, 1e-10);
  EXPECT_LT(centroid_change, 1e-10);
  EXPECT_NEAR(base.transport_cost, moved.transport_cost, 1e-12);
}

TEST(Invariance, SphereRotation) {
  std::mt19937_64 random(9);
  const auto sites = SphereCase::sample(300, random);
  Eigen::VectorXd masses = Eigen::VectorXd::LinSpaced(300, 1, 4);
  const auto base = solve(Sphere(), UniformDensity{}, std::span(sites), masses, tight(1e-12));
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(1.1, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  std::vector<Vec3> rotated;
  for (const auto& s : sites) rotated.push_back(rotation * s);
  const auto moved = solve(Sphere(), UniformDensity{}, std::span(std::as_const(rotated)), masses, tight(1e-12));
  ASSERT_TRUE(base.summary.converged() && moved.summary.converged());
  const double weight_change = (centred(base.weights) - centred(moved.weights)).cwiseAbs().maxCoeff();
  double centroid_change = 0;
  for (int i = 0; i < 300; ++i)
    centroid_change = std::max(centroid_change, (rotation * base.centroids[i] - moved.centroids[i]).norm());
  std::printf("  sphere rotation: max weight change %.2e, max centroid change %.2e\n", weight_change, centroid_change);
  EXPECT_LT(weight_change, 1e-10);
  EXPECT_LT(centroid_change, 1e-10);
}

TEST(Invariance, HyperbolicLorentzBoost) {
  std::mt19937_64 random(9);
  const auto sites = HyperbolicCase::sample(300, random);
  Eigen::VectorXd masses = Eigen::VectorXd::LinSpaced(300, 1, 4);
  const auto domain = HyperbolicCase::geometry();
  const auto base = solve(domain, UniformDensity{}, std::span(sites), masses, tight(1e-12));
  const Eigen::Matrix3d boost = Hyperbolic::boost_to(Hyperbolic::polar(1.5, 0.8));
  std::vector<Vec3> boosted_sites, boosted_domain;
  for (const auto& s : sites) boosted_sites.push_back(boost * s);
  for (const auto& v : domain.domain()) boosted_domain.push_back(boost * v);
  const auto moved = solve(Hyperbolic(boosted_domain), UniformDensity{}, std::span(std::as_const(boosted_sites)),
                           masses, tight(1e-12));
  ASSERT_TRUE(base.summary.converged() && moved.summary.converged());
  const double weight_change = (centred(base.weights) - centred(moved.weights)).cwiseAbs().maxCoeff();
  double centroid_change = 0;
  for (int i = 0; i < 300; ++i)
    centroid_change = std::max(centroid_change, Hyperbolic::distance(boost * base.centroids[i], moved.centroids[i]));
  std::printf("  hyperbolic boost (distance 1.5): max weight change %.2e, max centroid distance %.2e\n", weight_change,
              centroid_change);
  EXPECT_LT(weight_change, 1e-9);
  EXPECT_LT(centroid_change, 1e-9);
}

// ---- 4. refinement --------------------------------------------------------------------------

template <class Case>
void check_refinement() {
  const auto geometry = Case::geometry();
  std::printf("  %s: N sites sampled from the source, equal masses\n  %6s | %14s | %s\n", Case::name(), "N",
              "transport cost", "rate");
  std::vector<double> counts, costs;
  for (std::size_t n : {250, 1000, 4000, 16000}) {
    std::mt19937_64 random(31 + n);
    const auto sites = Case::sample(n, random);
    const auto result =
        solve(geometry, UniformDensity{}, std::span(std::as_const(sites)), equal_masses(n), tight(1e-9));
    ASSERT_TRUE(result.summary.converged()) << result.summary.message;
    counts.push_back(static_cast<double>(n));
    costs.push_back(result.transport_cost);
    const std::size_t k = costs.size() - 1;
    if (k == 0)
      std::printf("  %6zu | %14.6e |\n", n, result.transport_cost);
    else
      std::printf("  %6zu | %14.6e | %.3f\n", n, result.transport_cost,
                  std::log(costs[k - 1] / costs[k]) / std::log(counts[k] / counts[k - 1]));
  }
  const double observed = std::log(costs.front() / costs.back()) / std::log(counts.back() / counts.front());
  std::printf("  observed rate (cost ~ N^-rate): %.3f (quantisation theory in 2-D: 1)\n", observed);
  EXPECT_NEAR(observed, 1.0, 0.15);
}

TEST(Refinement, PlaneTransportCostConverges) {
  check_refinement<PlaneCase>();
}
TEST(Refinement, SphereTransportCostConverges) {
  check_refinement<SphereCase>();
}

// The discrete checker itself, against brute force on tiny problems.
TEST(DiscreteTransport, MatchesBruteForce) {
  std::mt19937_64 random(3);
  std::uniform_real_distribution<double> uniform(0, 1);
  for (int trial = 0; trial < 20; ++trial) {
    const int m = 6, n = 3;
    Eigen::MatrixXd cost(m, n);
    for (auto& c : cost.reshaped()) c = uniform(random);
    const std::vector<int> capacity{1, 2, 3};
    const auto result = solve_discrete_transport(cost, capacity);
    // Brute force over all assignments with the right counts.
    double best = INFINITY;
    std::vector<int> a(m, 0);
    for (int code = 0; code < 729; ++code) {
      int c = code;
      std::vector<int> count(n, 0);
      double total = 0;
      for (int s = 0; s < m; ++s) a[s] = c % 3, c /= 3, ++count[a[s]], total += cost(s, a[s]);
      if (count == capacity) best = std::min(best, total);
    }
    EXPECT_NEAR(result.cost * m, best, 1e-12) << "trial " << trial;
    // Complementary slackness: each sample's site minimises c − ψ.
    for (int s = 0; s < m; ++s) {
      const double own = cost(s, result.assignment[s]) - result.potentials[result.assignment[s]];
      for (int i = 0; i < n; ++i) EXPECT_LE(own, cost(s, i) - result.potentials[i] + 1e-12);
    }
  }
}

}  // namespace
}  // namespace sdot::testing
