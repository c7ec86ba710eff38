// The sdot command's adapter for the periodic plane: problem fields (box, periodic axes),
// densities given on the box, the SVG picture with wrapped cells, benchmark, demo.
#include <cmath>
#include <numbers>
#include <random>

#include "common.hpp"
#include "registry.hpp"
#include "sdot/geometries/plane_densities.hpp"
#include "sdot/geometries/torus.hpp"
#include "sdot/geometries/torus_densities.hpp"
#include "sdot/solver.hpp"

namespace sdot::cli {
namespace {

using Point = Torus::Point;

std::vector<Point> to_points(const std::vector<Eigen::VectorXd>& points) {
  std::vector<Point> result;
  result.reserve(points.size());
  for (const auto& p : points) result.emplace_back(p[0], p[1]);
  return result;
}

/// "domain": [x0, y0, x1, y1], or the box's 4 corners as a polygon (axis-aligned, either
/// orientation); default the unit square.
Eigen::AlignedBox2d read_box(const json& problem) {
  if (!problem.contains("domain")) return {Point(0, 0), Point(1, 1)};
  const json& domain = problem["domain"];
  const std::string expected = "a periodic problem needs a rectangular box: [x0, y0, x1, y1] or its 4 corners";
  if (domain.is_array() && domain.size() == 4 && !domain[0].is_array()) {
    const Eigen::VectorXd r = read_vector(domain, "domain");
    return {Point(r[0], r[1]), Point(r[2], r[3])};
  }
  if (!domain.is_array() || domain.size() != 4) throw InputError("domain", expected);
  const auto corners = to_points(read_points(domain, "domain", 2));
  Eigen::AlignedBox2d box;
  for (const auto& c : corners) box.extend(c);
  // Each corner of an axis-aligned rectangle has both coordinates on the box's sides.
  for (std::size_t k = 0; k < 4; ++k) {
    const Point& c = corners[k];
    if (!((c.x() == box.min().x() || c.x() == box.max().x()) && (c.y() == box.min().y() || c.y() == box.max().y())))
      throw InputError(indexed("domain", k), expected + " (this corner is not one of an axis-aligned box)");
  }
  return box;
}

/// "periodic": true, false or [x, y] (booleans); default true (both axes).
std::array<bool, 2> read_periodic(const json& problem) {
  if (!problem.contains("periodic")) return {true, true};
  const json& value = problem["periodic"];
  if (value.is_boolean()) return {value.get<bool>(), value.get<bool>()};
  if (value.is_array() && value.size() == 2 && value[0].is_boolean() && value[1].is_boolean())
    return {value[0].get<bool>(), value[1].get<bool>()};
  throw InputError("periodic", "must be true, false or two booleans [x, y]");
}

/// Each cell drawn where it lies on the torus: moved by the periods that make it overlap the box,
/// and cut to the box.
std::string draw(const Torus& torus, std::span<const Point> sites, const Result<Point>& result) {
  const Eigen::AlignedBox2d& box = torus.box();
  const double margin = 0.03 * box.sizes().maxCoeff();
  Svg svg(box.min().x() - margin, box.min().y() - margin, box.max().x() + margin, box.max().y() + margin);
  const std::vector<Point> outline{box.corner(Eigen::AlignedBox2d::BottomLeft),
                                   box.corner(Eigen::AlignedBox2d::BottomRight),
                                   box.corner(Eigen::AlignedBox2d::TopRight), box.corner(Eigen::AlignedBox2d::TopLeft)};
  // Dashed sides wrap around; solid ones bound the domain.
  svg.polygon(outline, "fill=\"#f4f4f4\" stroke=\"none\"");
  for (int k = 0; k < 4; ++k) {
    const bool wraps = torus.periodic()[static_cast<std::size_t>(k % 2 == 0 ? 1 : 0)];
    svg.polyline({outline[static_cast<std::size_t>(k)], outline[static_cast<std::size_t>((k + 1) % 4)]},
                 wraps ? "stroke=\"black\" stroke-width=\"1.5\" stroke-dasharray=\"6 4\""
                       : "stroke=\"black\" stroke-width=\"1.5\"");
  }
  const double stroke = std::clamp(3.0 / std::sqrt(static_cast<double>(sites.size())), 0.2, 1.0);
  const std::string style = fmt::format("fill=\"none\" stroke=\"#3060a0\" stroke-width=\"{:.2f}\"", stroke);
  for (const auto& cell : result.diagram.cells) {
    if (cell.empty()) continue;
    torus.for_each_part_in_box(cell, [&](const Cell<Point>& part, const Point&) { svg.polygon(part.vertices, style); });
  }
  const double r = dot_radius_px(sites.size());
  for (const auto& c : result.centroids) svg.circle(c, r * 0.8, "fill=\"#20a040\"");
  for (const auto& s : sites) svg.circle(torus.wrap(s), r, "fill=\"#d03020\"");
  return svg.str();
}

template <class D>
SolveOutput solve_with_density(const Torus& torus, const D& density, std::span<const Point> sites, const json& problem,
                               const RunContext& context) {
  const Options options = read_options(problem, context.quiet);
  const auto masses = read_masses(problem, sites.size());
  const auto weights = read_weights(problem, sites.size());
  const auto result = solve(torus, density, sites, masses, options, weights);
  SolveOutput output;
  output.result = result_json(std::string(Torus::name()), result);
  output.converged = result.summary.usable();
  if (context.want_svg) output.svg = draw(torus, sites, result);
  return output;
}

SolveOutput solve_torus(const json& problem, const RunContext& context) {
  check_known_fields(problem, "",
                     {"geometry", "sites", "masses", "domain", "periodic", "density", "tolerance", "max_iterations",
                      "weights", "linear_solver"});
  if (!problem.contains("sites")) throw InputError("sites", "missing");
  const auto sites = to_points(read_points(problem["sites"], "sites", 2));
  if (sites.empty()) throw InputError("sites", "at least one site is needed");
  const Torus torus(read_box(problem), read_periodic(problem));
  // A density of the plane over the box (mesh or image), repeated with the periods.
  auto density = read_density(
      torus.plane(), problem, context,
      [](const json& value, const std::string& field) {
        return to_points(read_points(json::array({value}), field, 2))[0];
      },
      [&](const GrayImage& image, const json& density_json) {
        const std::string interpolation =
            read_choice(density_json, "interpolation", "density.interpolation", {"constant", "bilinear"}, "bilinear");
        Eigen::AlignedBox2d rectangle = torus.box();
        if (density_json.contains("rectangle")) {
          const Eigen::VectorXd r = read_vector(density_json["rectangle"], "density.rectangle");
          if (r.size() != 4) throw InputError("density.rectangle", "must be [x0, y0, x1, y1]");
          rectangle = Eigen::AlignedBox2d(Eigen::Vector2d(r[0], r[1]), Eigen::Vector2d(r[2], r[3]));
        }
        return image_density(torus.plane(), image, rectangle,
                             interpolation == "constant" ? ImageInterpolation::constant : ImageInterpolation::bilinear,
                             read_scale(density_json));
      });
  const std::span<const Point> site_span(sites);
  if (density) return solve_with_density(torus, PeriodicDensity(std::move(*density)), site_span, problem, context);
  return solve_with_density(torus, UniformDensity{}, site_span, problem, context);
}

json bench_torus(const BenchRequest& request) {
  // The plane's benchmark problem (the same sites in the unit square), on the torus.
  const Torus torus;
  const auto sites = torus.uniform_samples(request.n, request.seed);
  return run_bench(torus, std::span<const Point>(sites), equal_masses(request.n), request, [&](std::size_t triangles) {
    std::vector<double> values;  // the plane's bench density, repeated
    const auto mesh = unit_square_bench_mesh(triangles, values);
    return PeriodicDensity(mesh_density(torus.plane(), std::span<const Point>(mesh.vertices),
                                        std::span<const std::array<int, 3>>(mesh.triangles),
                                        std::span<const double>(values)));
  });
}

json demo_torus() {
  // 800 sites in a band across the seam of a 2 × 1 box periodic in x and y, masses growing with y.
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> uniform(0, 1);
  json sites = json::array(), masses = json::array();
  for (int i = 0; i < 800; ++i) {
    const double x = 1.6 + 0.8 * uniform(random), y = uniform(random);
    sites.push_back({x, y});
    masses.push_back(1 + 3 * y);
  }
  return {{"geometry", "torus"},    {"sites", sites},   {"masses", masses},
          {"domain", {0, 0, 2, 1}}, {"periodic", true}, {"tolerance", 1e-9}};
}

}  // namespace

void register_torus(Registry& registry) {
  registry.add("torus", {solve_torus, bench_torus, demo_torus});
}

}  // namespace sdot::cli
