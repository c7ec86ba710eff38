// A custom OT problem with sdot: 200 sites in a hexagon, masses growing to the right, a
// non-uniform source density given as a function. Prints the solver's progress and summary.
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <sdot/geometries/plane.hpp>
#include <sdot/solver.hpp>

int main() {
  using Point = sdot::Plane::Point;
  std::vector<Point> hexagon;
  for (int k = 0; k < 6; ++k)
    hexagon.emplace_back(std::cos(k * std::numbers::pi / 3), std::sin(k * std::numbers::pi / 3));
  const sdot::Plane plane{sdot::ConvexPolygon(hexagon)};

  std::mt19937_64 random(42);
  std::uniform_real_distribution<double> uniform(-1, 1);
  std::vector<Point> sites;
  while (sites.size() < 200) {
    const Point p(uniform(random), uniform(random));
    if (plane.domain().contains(p)) sites.push_back(p);
  }
  Eigen::VectorXd masses(200);
  for (int i = 0; i < 200; ++i) masses[i] = 1 + sites[i].x() + 1.5;  // rescaled to the source mass

  // ρ(x) = 1 + 0.5 cos(3|x|), integrated with 6×6-point rules per triangle.
  const sdot::FunctionDensity<Point> density{[](const Point& x) { return 1 + 0.5 * std::cos(3 * x.norm()); }, 6};
  sdot::Options options;
  options.tolerance = 1e-10;
  options.callback = [](const sdot::IterationRecord& r) {
    std::printf("iteration %d: max relative mass error %.3e (step %g)\n", r.iteration, r.max_relative_error, r.step);
  };
  const auto result = sdot::solve(plane, density, std::span<const Point>(sites), masses, options);
  std::printf("%s\ntransport cost %.6f, source mass %.6f\n", result.summary.message.c_str(), result.transport_cost,
              result.summary.source_mass);
  return result.summary.converged() ? 0 : 1;
}
