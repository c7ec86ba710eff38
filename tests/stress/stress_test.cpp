// The stress test (ctest label `stress`; built with -DSDOT_STRESS_TESTS=ON, run by
// scripts/stress.sh): 1000 random problems per geometry, N uniform in [1, 2000], sites in
// clusters from loose to far below double precision plus a few uniform ones, masses log-uniform
// over 2–3 decades, solved with the default options. Every solve must converge or stop with a
// documented status and a message, or throw sdot::InputError (e.g. duplicate sites from a tight
// cluster); anything else (another exception, a NaN or an infinity in the result, a converged
// status with a mass off its target, a usable status for masses that provably admit no solution)
// fails, naming the problem.
//
// Problem k is drawn from std::mt19937_64(k): SDOT_STRESS_PROBLEM=k runs only problem k, and
// SDOT_STRESS_COUNT=n the first n problems (default 1000); SDOT_STRESS_VERBOSE=1 prints each
// problem as it starts (to find one that hangs) and its outcome. Each geometry prints a summary
// (lines starting with `stress[<geometry>]`) to stdout.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <map>
#include <numbers>
#include <numeric>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "sdot/error.hpp"
#include "sdot/geometries/hyperbolic.hpp"
#include "sdot/geometries/plane.hpp"
#include "sdot/geometries/sphere.hpp"
#include "sdot/solver.hpp"

namespace sdot::testing {
namespace {

constexpr int default_problem_count = 1000;
constexpr int max_sites = 2000;

/// How each geometry makes a random domain and valid sites in it. `size` is the domain's
/// extent, the unit of the clusters' spreads.
template <class G>
struct StressTraits;

template <>
struct StressTraits<Plane> {
  using Point = Plane::Point;
  static Plane geometry(std::mt19937_64&) { return Plane(); }  // the unit square, the default
  static double size(const Plane&) { return 1; }
  static double source_mass(const Plane& plane) { return plane.domain().area(); }
  static std::vector<Point> uniform(const Plane& plane, std::size_t count, std::mt19937_64& random) {
    return plane.uniform_samples(count, random());
  }
  static Point near(const Plane&, const Point& centre, double spread, std::mt19937_64& random) {
    std::normal_distribution<double> normal;
    const double dx = normal(random), dy = normal(random);
    return centre + spread * Point(dx, dy);
  }
};

template <>
struct StressTraits<Sphere> {
  using Point = Sphere::Point;
  static Sphere geometry(std::mt19937_64&) { return Sphere(); }  // the whole sphere, the default
  static double size(const Sphere&) { return 1; }
  static double source_mass(const Sphere& sphere) { return sphere.domain_area(); }
  static std::vector<Point> uniform(const Sphere&, std::size_t count, std::mt19937_64& random) {
    return Sphere::uniform_samples(count, random());
  }
  /// A Gaussian step of `spread` radians in the tangent plane at `centre`, back onto the sphere.
  static Point near(const Sphere&, const Point& centre, double spread, std::mt19937_64& random) {
    std::normal_distribution<double> normal;
    const double x = normal(random), y = normal(random), z = normal(random);
    const Point step(x, y, z);
    return (centre + spread * (step - step.dot(centre) * centre)).normalized();
  }
};

template <>
struct StressTraits<Hyperbolic> {
  using Point = Hyperbolic::Point;
  /// A regular polygon of 3–8 sides and radius 0.3–3 (log-uniform) around a point up to
  /// distance 3 from the origin: small and nearly flat to large and far out in the Klein chart.
  static Hyperbolic geometry(std::mt19937_64& random) {
    std::uniform_int_distribution<int> sides(3, 8);
    std::uniform_real_distribution<double> unit;
    const int side_count = sides(random);
    const double radius = 0.3 * std::pow(10.0, unit(random));
    const double centre_distance = 3 * unit(random), centre_angle = 2 * std::numbers::pi * unit(random);
    return Hyperbolic::regular_polygon(side_count, radius, Hyperbolic::polar(centre_distance, centre_angle));
  }
  static double size(const Hyperbolic& h) { return Hyperbolic::distance(h.center(), h.domain().front()); }
  static double source_mass(const Hyperbolic& h) { return h.domain_area(); }
  static std::vector<Point> uniform(const Hyperbolic& h, std::size_t count, std::mt19937_64& random) {
    return h.uniform_samples(count, random());
  }
  /// A Gaussian step of `spread` in the tangent plane at `centre`: exactly a point of H² (a
  /// polar point at the origin, moved to `centre` by a Lorentz boost).
  static Point near(const Hyperbolic&, const Point& centre, double spread, std::mt19937_64& random) {
    std::normal_distribution<double> normal;
    const double x = normal(random), y = normal(random);
    return Hyperbolic::boost_to(centre) * Hyperbolic::polar(spread * std::hypot(x, y), std::atan2(y, x));
  }
};

/// A cluster of sites, or one uniform site.
template <class Point>
struct Group {
  Point centre;
  std::vector<std::size_t> sites;  // indices into Problem::sites
};

template <class G>
struct Problem {
  G geometry;
  std::vector<typename G::Point> sites;
  Eigen::VectorXd masses;
  std::vector<Group<typename G::Point>> groups;
  double tightest_spread = 1;  // of the clusters with two sites or more, in domain sizes
};

/// On the plane and H² the cost is finite everywhere: every problem has a solution.
template <class G>
bool certified_infeasible(const Problem<G>&, const Eigen::VectorXd*) {
  return false;
}

/// Replaces `points`, which all lie in the open hemisphere around `c`, by the vertices of their
/// spherical convex hull (the planar hull of their gnomonic images at c, by monotone chain) and
/// returns the hull's perimeter (great-circle arcs; twice the length for a single arc).
double convex_hull_perimeter(std::vector<Sphere::Point>& points, const Sphere::Point& c) {
  const Sphere::Point t1 = c.unitOrthogonal(), t2 = c.cross(t1);
  std::vector<std::pair<Eigen::Vector2d, Sphere::Point>> charted;
  for (const auto& p : points) charted.emplace_back(Eigen::Vector2d(p.dot(t1), p.dot(t2)) / p.dot(c), p);
  std::sort(charted.begin(), charted.end(), [](const auto& a, const auto& b) {
    return a.first.x() < b.first.x() || (a.first.x() == b.first.x() && a.first.y() < b.first.y());
  });
  auto turns_left = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& p) {
    return (b - a).x() * (p - a).y() - (b - a).y() * (p - a).x() > 0;
  };
  std::vector<std::pair<Eigen::Vector2d, Sphere::Point>> hull;
  for (int chain = 0; chain < 2; ++chain) {  // lower, then upper (the points reversed)
    const std::size_t first = hull.size();
    for (const auto& p : charted) {
      while (hull.size() >= first + 2 && !turns_left(hull[hull.size() - 2].first, hull.back().first, p.first))
        hull.pop_back();
      hull.push_back(p);
    }
    hull.pop_back();  // the chain's last point starts the other chain
    std::reverse(charted.begin(), charted.end());
  }
  if (hull.empty()) hull = charted;  // a single point
  points.clear();
  double perimeter = 0;
  for (std::size_t k = 0; k < hull.size(); ++k) {
    const auto& a = hull[k].second;
    const auto& b = hull[(k + 1) % hull.size()].second;
    perimeter += std::atan2(a.cross(b).norm(), a.dot(b));
    points.push_back(a);
  }
  return perimeter;
}

/// A direction c with ⟨p, c⟩ > 10⁻³ for all `points` (perceptron iterations from `start`), or
/// nothing: then the points may not lie in an open hemisphere.
std::optional<Sphere::Point> open_hemisphere_centre(const std::vector<Sphere::Point>& points, Sphere::Point start) {
  for (int pass = 0; pass < 100; ++pass) {
    bool inside = true;
    for (const auto& p : points)
      if (!(p.dot(start.normalized()) > 1e-3)) start += p, inside = false;
    if (inside) return start.normalized();
  }
  return std::nullopt;
}

/// On the whole sphere a cell lies in its site's closed hemisphere (the cost is infinite beyond),
/// so sites S in an open hemisphere can hold at most the area of the union of their hemispheres:
/// 4π minus the area of the polar of their convex hull, i.e. 2π + the hull's perimeter. True when
/// S (`points`, replaced by their hull's vertices; total target mass `mass`) asks for more, which
/// no weights can give (Hall's condition).
bool exceeds_hemispheres(std::vector<Sphere::Point>& points, double mass, const Sphere::Point& start) {
  const auto centre = open_hemisphere_centre(points, start);  // the hull's chart needs one
  // The margin keeps rounding in the perimeter from certifying a problem at the limit.
  return centre && mass > (2 * std::numbers::pi + convex_hull_perimeter(points, *centre)) * (1 + 1e-9);
}

/// True when some set of sites provably asks for more than its hemispheres hold (see
/// exceeds_hemispheres), trying the unions of the groups (clusters, uniform sites) nearest a
/// group's centre, its antipode or the mass-weighted mean of all sites, nearest first (with the
/// antipodes, all the sites but one group); and, given the heights a solve stopped at, the sites
/// above each of the first gaps of more than 5 in the heights (a failed solve drives the heights
/// of the sites that must take the excess far below the others).
template <>
bool certified_infeasible(const Problem<Sphere>& problem, const Eigen::VectorXd* heights) {
  auto mass_of = [&](std::size_t i) { return problem.masses[static_cast<Eigen::Index>(i)]; };
  std::vector<Sphere::Point> starts;
  Sphere::Point mean = Sphere::Point::Zero();
  for (std::size_t i = 0; i < problem.sites.size(); ++i) mean += mass_of(i) * problem.sites[i];
  if (mean.norm() > 0) starts.push_back(mean.normalized());
  for (const auto& group : problem.groups) starts.push_back(group.centre), starts.push_back(-group.centre);
  for (const auto& start : starts) {
    std::vector<const Group<Sphere::Point>*> nearest;
    for (const auto& group : problem.groups) nearest.push_back(&group);
    std::sort(nearest.begin(), nearest.end(),
              [&](auto* a, auto* b) { return a->centre.dot(start) > b->centre.dot(start); });
    std::vector<Sphere::Point> hull;  // of the union so far: its vertices are all the next one needs
    Sphere::Point moment = Sphere::Point::Zero();
    double mass = 0;
    for (const auto* group : nearest) {
      for (std::size_t i : group->sites) {
        hull.push_back(problem.sites[i]);
        moment += mass_of(i) * problem.sites[i];
        mass += mass_of(i);
      }
      if (exceeds_hemispheres(hull, mass, moment)) return true;
    }
  }
  if (!heights) return false;
  std::vector<std::size_t> highest(problem.sites.size());
  std::iota(highest.begin(), highest.end(), 0);
  std::sort(highest.begin(), highest.end(), [&](auto a, auto b) { return (*heights)[a] > (*heights)[b]; });
  int gaps = 0;
  for (std::size_t k = 0; k + 1 < highest.size() && gaps < 3; ++k) {
    if ((*heights)[highest[k]] - (*heights)[highest[k + 1]] <= 5) continue;
    ++gaps;
    std::vector<Sphere::Point> points;
    Sphere::Point moment = Sphere::Point::Zero();
    double mass = 0;
    for (std::size_t r = 0; r <= k; ++r) {
      const std::size_t i = highest[r];
      points.push_back(problem.sites[i]);
      moment += mass_of(i) * problem.sites[i];
      mass += mass_of(i);
    }
    if (exceeds_hemispheres(points, mass, moment)) return true;
  }
  return false;
}

/// Problem `index`, drawn from std::mt19937_64(index) alone: N uniform in [1, 2000]; 0–8 uniform
/// sites (they keep the sphere's sites from lying in one hemisphere, mostly); the others in 1–20
/// clusters of random sizes, each with a uniform centre and a Gaussian spread between 10⁻¹² and
/// 10⁻¹ domain sizes (from loose clusters to ones below double precision, where sites may even
/// coincide); masses log-uniform over 2–3 decades, scaled to the source's mass.
template <class G>
Problem<G> make_problem(int index) {
  using Traits = StressTraits<G>;
  std::mt19937_64 random(static_cast<std::uint64_t>(index));
  std::uniform_real_distribution<double> unit;
  Problem<G> problem{Traits::geometry(random), {}, {}, {}};
  const G& g = problem.geometry;
  const auto n = std::uniform_int_distribution<std::size_t>(1, max_sites)(random);
  const auto uniform_count = std::min(n, std::uniform_int_distribution<std::size_t>(0, 8)(random));
  const auto cluster_count = std::uniform_int_distribution<std::size_t>(1, 20)(random);
  const std::vector<typename G::Point> centres = Traits::uniform(g, cluster_count, random);
  // The tightest spread is log-uniform per problem (so every decade gets as many problems), the
  // others log-uniform between it and 10⁻¹.
  const double tightest_exponent = -12 + 11 * unit(random);
  std::vector<double> spreads(cluster_count), shares(cluster_count);
  for (std::size_t c = 0; c < cluster_count; ++c) {
    spreads[c] = Traits::size(g) * std::pow(10.0, tightest_exponent + (-1 - tightest_exponent) * unit(random));
    shares[c] = unit(random) + 0.01;  // cluster sizes from a few sites to most of them
  }
  problem.sites = Traits::uniform(g, uniform_count, random);
  for (std::size_t i = 0; i < uniform_count; ++i) problem.groups.push_back({problem.sites[i], {i}});
  std::vector<Group<typename G::Point>> clusters;
  for (const auto& centre : centres) clusters.push_back({centre, {}});
  std::discrete_distribution<std::size_t> pick_cluster(shares.begin(), shares.end());
  while (problem.sites.size() < n) {
    const std::size_t c = pick_cluster(random);
    clusters[c].sites.push_back(problem.sites.size());
    problem.sites.push_back(Traits::near(g, centres[c], spreads[c], random));
    if (clusters[c].sites.size() >= 2)
      problem.tightest_spread = std::min(problem.tightest_spread, spreads[c] / Traits::size(g));
  }
  for (auto& cluster : clusters)
    if (!cluster.sites.empty()) problem.groups.push_back(std::move(cluster));
  const double decades = 2 + unit(random);
  problem.masses.resize(static_cast<Eigen::Index>(n));
  for (auto& m : problem.masses) m = std::pow(10.0, decades * unit(random));
  problem.masses *= Traits::source_mass(g) / problem.masses.sum();
  return problem;
}

/// One problem's outcome.
struct Outcome {
  int index = 0;
  std::size_t sites = 0;
  std::string status;   // a Status name, or "input_error"
  std::string reason;   // the message (InputError's or the summary's) with its numbers replaced by #
  int iterations = -1;  // Newton iterations (-1 for an input error)
  double seconds = 0;
  double tightest_spread = 1;
  bool infeasible = false;  // certified_infeasible()
};

std::string without_numbers(const std::string& message) {
  std::string out;
  for (char c : message)
    if (!std::isdigit(static_cast<unsigned char>(c)))
      out += c;
    else if (out.empty() || out.back() != '#')
      out += '#';
  return out;
}

int environment_int(const char* name, int fallback) {
  const char* value = std::getenv(name);
  return value ? std::atoi(value) : fallback;
}

template <class T, class Key>
const T& largest_by(const std::vector<T>& items, Key key) {
  return *std::max_element(items.begin(), items.end(), [&](const T& a, const T& b) { return key(a) < key(b); });
}

template <class T>
T median(std::vector<T> values) {
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

/// Prints the figures of one geometry, every line starting with `stress[<geometry>]`: outcome
/// counts, the distinct messages of the outcomes other than convergence (numbers replaced by #),
/// times, Newton iterations, and the outcomes by the decade of the tightest cluster spread.
void print_summary(std::string_view geometry, const std::vector<Outcome>& outcomes) {
  const std::string tag = "stress[" + std::string(geometry) + "] ";
  const char* prefix = tag.c_str();
  std::map<std::string, int> by_status, by_reason, infeasible_by_status;
  std::map<std::string, double> seconds_by_status;
  std::string unexplained;  // failures of loose, feasible-looking problems: worth a look
  std::vector<double> seconds;
  std::vector<int> iterations;
  double total = 0;
  for (const auto& o : outcomes) {
    ++by_status[o.status];
    seconds_by_status[o.status] += o.seconds;
    if (o.status != "converged") ++by_reason[o.status + ": " + o.reason];
    if (o.status != "converged" && o.status != "precision_floor" && o.status != "input_error" && !o.infeasible &&
        o.tightest_spread >= 1e-3)
      unexplained += " " + std::to_string(o.index) + " (" + o.status + ")";
    if (o.infeasible) ++infeasible_by_status[o.status];
    if (o.iterations >= 0) iterations.push_back(o.iterations);
    seconds.push_back(o.seconds);
    total += o.seconds;
  }
  std::printf("%sproblems %zu\n", prefix, outcomes.size());
  for (const auto& [status, count] : by_status)
    std::printf("%s%s %d (%.1f s)\n", prefix, status.c_str(), count, seconds_by_status[status]);
  for (const auto& [reason, count] : by_reason) std::printf("%s  ×%d %s\n", prefix, count, reason.c_str());
  for (const auto& [status, count] : infeasible_by_status)
    std::printf("%scertified infeasible (no solution exists): %s %d\n", prefix, status.c_str(), count);
  std::printf("%sunusable, tightest spread >= 1e-3, not certified infeasible:%s\n", prefix,
              unexplained.empty() ? " none" : unexplained.c_str());
  const auto& slowest = largest_by(outcomes, [](const Outcome& o) { return o.seconds; });
  std::printf("%stime total %.1f s, median %.3f s, max %.2f s (problem %d, N = %zu)\n", prefix, total, median(seconds),
              slowest.seconds, slowest.index, slowest.sites);
  if (!iterations.empty()) {
    const auto& most = largest_by(outcomes, [](const Outcome& o) { return o.iterations; });
    std::printf("%sNewton iterations (solves that ran) median %d, max %d (problem %d)\n", prefix, median(iterations),
                most.iterations, most.index);
  }
  std::printf("%slargest N %zu\n", prefix, largest_by(outcomes, [](const Outcome& o) { return o.sites; }).sites);

  // Where precision runs out: outcomes by the decade of the problem's tightest cluster spread.
  const std::vector<std::string> columns{"converged",           "precision_floor",      "iteration_limit",
                                         "line_search_failure", "linear_solve_failure", "input_error"};
  const bool any_infeasible = !infeasible_by_status.empty();
  std::map<int, std::vector<const Outcome*>> by_decade;  // 0: no cluster of two sites
  for (const auto& o : outcomes)
    by_decade[o.tightest_spread < 1 ? static_cast<int>(std::floor(std::log10(o.tightest_spread))) : 0].push_back(&o);
  std::printf("%s| tightest spread | problems |", prefix);
  for (const auto& column : columns) std::printf(" %s |", column.c_str());
  std::printf(any_infeasible ? " certified infeasible |\n" : "\n");
  for (const auto& [decade, members] : by_decade) {
    if (decade == 0)
      std::printf("%s| no cluster | %zu |", prefix, members.size());
    else
      std::printf("%s| 1e%d – 1e%d | %zu |", prefix, decade, decade + 1, members.size());
    for (const auto& column : columns)
      std::printf(" %zd |",
                  std::count_if(members.begin(), members.end(), [&](auto* o) { return o->status == column; }));
    if (any_infeasible)
      std::printf(" %zd |", std::count_if(members.begin(), members.end(), [](auto* o) { return o->infeasible; }));
    std::printf("\n");
  }
  std::fflush(stdout);
}

template <class Point>
bool all_finite(const std::vector<Point>& points) {
  return std::all_of(points.begin(), points.end(), [](const Point& p) { return p.allFinite(); });
}

/// Solves problem `index` and checks its result; failures name the problem.
template <class G>
Outcome run_problem(int index) {
  const Problem<G> problem = make_problem<G>(index);
  const auto n = problem.sites.size();
  const std::string name = "problem " + std::to_string(index) + " (N = " + std::to_string(n) + ")";
  Outcome outcome{index, n, "", "", -1, 0, problem.tightest_spread, false};
  const Options options;  // the defaults, tolerance included
  const bool verbose = environment_int("SDOT_STRESS_VERBOSE", 0) != 0;
  if (verbose)
    std::printf("%s %s, tightest spread %.1e: ", std::string(G::name()).c_str(), name.c_str(), problem.tightest_spread);
  std::fflush(stdout);
  const auto start = std::chrono::steady_clock::now();
  std::optional<Result<typename G::Point>> result;
  try {
    result = solve(problem.geometry, UniformDensity{}, std::span(problem.sites), problem.masses, options);
  } catch (const InputError& e) {
    outcome.status = "input_error";
    outcome.reason = without_numbers(e.what());
  } catch (const std::exception& e) {
    ADD_FAILURE() << name << ": escaped exception (not sdot::InputError): " << e.what();
    outcome.status = "escaped_exception";
  } catch (...) {
    ADD_FAILURE() << name << ": escaped exception of an unknown type";
    outcome.status = "escaped_exception";
  }
  outcome.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  outcome.infeasible = certified_infeasible(problem, result ? &result->weights : nullptr);
  if (verbose)
    std::printf("%.2f s, %d iterations,%s %s\n", outcome.seconds, result ? result->summary.iterations : -1,
                outcome.infeasible ? " infeasible," : "",
                result ? (std::string(to_string(result->summary.status)) + ", " + result->summary.message).c_str()
                       : outcome.status.c_str());
  if (!result) return outcome;

  const Summary& summary = result->summary;
  outcome.status = to_string(summary.status);
  outcome.iterations = summary.iterations;
  outcome.reason = without_numbers(summary.message);
  EXPECT_FALSE(summary.message.empty()) << name << ": status " << outcome.status << " without a message";
  const auto size = static_cast<Eigen::Index>(n);
  if (result->weights.size() != size || result->masses.size() != size || result->target_masses.size() != size ||
      result->centroids.size() != n) {
    ADD_FAILURE() << name << ": result sizes differ from N";
    return outcome;
  }
  EXPECT_TRUE(result->weights.allFinite()) << name << ": non-finite weight; " << summary.message;
  EXPECT_TRUE(result->masses.allFinite()) << name << ": non-finite mass; " << summary.message;
  EXPECT_TRUE(all_finite(result->centroids)) << name << ": non-finite centroid; " << summary.message;
  EXPECT_TRUE(std::isfinite(result->transport_cost)) << name << ": non-finite transport cost; " << summary.message;
  EXPECT_FALSE(outcome.infeasible && summary.usable())
      << name << ": status " << outcome.status << " for masses that admit no solution";
  if (summary.converged()) {
    const double error =
        ((result->masses - result->target_masses).array().abs() / result->target_masses.array()).maxCoeff();
    EXPECT_LE(error, options.tolerance) << name << ": converged, but max relative mass error " << error;
  }
  return outcome;
}

template <class G>
void run_stress() {
  const int only = environment_int("SDOT_STRESS_PROBLEM", -1);
  const int count = environment_int("SDOT_STRESS_COUNT", default_problem_count);
  std::vector<Outcome> outcomes;
  for (int index = only >= 0 ? only : 0; index < (only >= 0 ? only + 1 : count); ++index)
    outcomes.push_back(run_problem<G>(index));
  print_summary(G::name(), outcomes);
}

TEST(Stress, Plane) {
  run_stress<Plane>();
}
TEST(Stress, Sphere) {
  run_stress<Sphere>();
}
TEST(Stress, Hyperbolic) {
  run_stress<Hyperbolic>();
}

}  // namespace
}  // namespace sdot::testing
