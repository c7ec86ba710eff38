// The sdot command's adapter for the plane: problem fields, SVG picture, benchmark, demo.
#include <cmath>
#include <numbers>
#include <random>

#include "common.hpp"
#include "registry.hpp"
#include "sdot/geometries/plane.hpp"
#include "sdot/geometries/plane_densities.hpp"
#include "sdot/solver.hpp"

namespace sdot::cli {
namespace {

using Point = Plane::Point;

std::vector<Point> to_points(const std::vector<Eigen::VectorXd>& points) {
  std::vector<Point> result;
  result.reserve(points.size());
  for (const auto& p : points) result.emplace_back(p[0], p[1]);
  return result;
}

/// A domain with holes: {"outer": […], "holes": [[…], …]} or {"polygons": [{"outer", "holes"}, …]}.
PlaneRegion read_region(const json& domain) {
  auto read_polygon = [](const json& object, const std::string& field) {
    check_known_fields(object, field, {"outer", "holes"});
    if (!object.contains("outer")) throw InputError(field + ".outer", "missing");
    PolygonWithHoles polygon;
    polygon.outer = to_points(read_points(object["outer"], field + ".outer", 2));
    if (object.contains("holes")) {
      const json& holes = object["holes"];
      if (!holes.is_array()) throw InputError(field + ".holes", "must be an array of rings");
      for (std::size_t h = 0; h < holes.size(); ++h)
        polygon.holes.push_back(to_points(read_points(holes[h], indexed(field + ".holes", h), 2)));
    }
    return polygon;
  };
  std::vector<PolygonWithHoles> polygons;
  if (domain.contains("polygons")) {
    check_known_fields(domain, "domain", {"polygons"});
    const json& list = domain["polygons"];
    if (!list.is_array() || list.empty()) throw InputError("domain.polygons", "must be a non-empty array");
    for (std::size_t i = 0; i < list.size(); ++i)
      polygons.push_back(read_polygon(list[i], indexed("domain.polygons", i)));
    return PlaneRegion(std::move(polygons), "domain");
  }
  polygons.push_back(read_polygon(domain, "domain"));
  try {
    return PlaneRegion(std::move(polygons), "domain");
  } catch (const InputError& e) {
    // The single-polygon form has no "polygons" list: name the fields as written.
    const std::string prefix = "domain.polygons[0]";
    std::string field = e.field();
    if (field.rfind(prefix, 0) == 0) field = "domain" + field.substr(prefix.size());
    const std::string message = e.what();
    throw InputError(field, message.substr(std::min(message.size(), e.field().size() + 2)));
  }
}

std::string draw(const Plane& plane, const std::optional<PlaneRegion>& region, std::span<const Point> sites,
                 const Result<Point>& result) {
  Eigen::Vector2d low = Eigen::Vector2d::Constant(INFINITY), high = -low;
  for (const auto& v : plane.domain().vertices()) low = low.cwiseMin(v), high = high.cwiseMax(v);
  const double margin = 0.03 * (high - low).maxCoeff();
  Svg svg(low.x() - margin, low.y() - margin, high.x() + margin, high.y() + margin);
  const double stroke = std::clamp(3.0 / std::sqrt(static_cast<double>(sites.size())), 0.2, 1.0);
  if (region) {
    for (const auto& polygon : region->polygons()) {
      svg.polygon(polygon.outer, "fill=\"#f4f4f4\" stroke=\"black\" stroke-width=\"1.5\"");
    }
  } else {
    svg.polygon(plane.domain().vertices(), "fill=\"#f4f4f4\" stroke=\"black\" stroke-width=\"1.5\"");
  }
  for (std::size_t i = 0; i < result.diagram.cells.size(); ++i)
    if (!result.diagram.cells[i].empty())
      svg.polygon(plane.with_sampled_arcs(result.diagram.cells[i], sites[i], 24).vertices,
                  fmt::format("fill=\"none\" stroke=\"#3060a0\" stroke-width=\"{:.2f}\"", stroke));
  if (region)  // holes over the cells, which extend over the domain's bounding box
    for (const auto& polygon : region->polygons())
      for (const auto& hole : polygon.holes) svg.polygon(hole, "fill=\"white\" stroke=\"black\" stroke-width=\"1.5\"");
  const double r = dot_radius_px(sites.size());
  for (const auto& c : result.centroids) svg.circle(c, r * 0.8, "fill=\"#20a040\"");
  for (const auto& s : sites) svg.circle(s, r, "fill=\"#d03020\"");
  return svg.str();
}

SolveOutput solve_plane(const json& problem, const RunContext& context) {
  check_known_fields(problem, "",
                     {"geometry", "sites", "masses", "domain", "density", "tolerance", "max_iterations", "weights",
                      "linear_solver", "partial"});
  if (!problem.contains("sites")) throw InputError("sites", "missing");
  const auto sites = to_points(read_points(problem["sites"], "sites", 2));
  if (sites.empty()) throw InputError("sites", "at least one site is needed");
  Plane plane;
  std::optional<PlaneRegion> region;
  if (problem.contains("domain") && problem["domain"].is_object()) {
    region = read_region(problem["domain"]);
    plane = Plane(
        ConvexPolygon::rectangle(region->lower().x(), region->lower().y(), region->upper().x(), region->upper().y()));
  } else if (problem.contains("domain")) {
    std::vector<Eigen::Vector2d> vertices = to_points(read_points(problem["domain"], "domain", 2));
    plane = Plane(ConvexPolygon(std::move(vertices), "domain"));
  }
  auto density = read_density(
      plane, problem, context,
      [](const json& value, const std::string& field) {
        return to_points(read_points(json::array({value}), field, 2))[0];
      },
      [&](const GrayImage& image, const json& density_json) {
        const std::string interpolation =
            read_choice(density_json, "interpolation", "density.interpolation", {"constant", "bilinear"}, "bilinear");
        Eigen::AlignedBox2d rectangle;
        for (const auto& v : plane.domain().vertices()) rectangle.extend(v);
        if (density_json.contains("rectangle")) {
          const Eigen::VectorXd r = read_vector(density_json["rectangle"], "density.rectangle");
          if (r.size() != 4) throw InputError("density.rectangle", "must be [x0, y0, x1, y1]");
          rectangle = Eigen::AlignedBox2d(Eigen::Vector2d(r[0], r[1]), Eigen::Vector2d(r[2], r[3]));
        }
        return image_density(plane, image, rectangle,
                             interpolation == "constant" ? ImageInterpolation::constant : ImageInterpolation::bilinear,
                             read_scale(density_json));
      });
  if (region) density = density ? density->restricted_to(region->convex_pieces()) : region_density(plane, *region);
  return solve_problem(plane, density, std::span<const Point>(sites), problem, context,
                       [&](const Result<Point>& result) { return draw(plane, region, sites, result); });
}

json bench_plane(const BenchRequest& request) {
  const Plane plane;
  const auto sites = plane.uniform_samples(request.n, request.seed);
  return run_bench(plane, std::span<const Point>(sites), equal_masses(request.n), request, [&](std::size_t triangles) {
    std::vector<double> values;
    const auto mesh = unit_square_bench_mesh(triangles, values);
    return mesh_density(plane, std::span<const Point>(mesh.vertices),
                        std::span<const std::array<int, 3>>(mesh.triangles), std::span<const double>(values));
  });
}

json demo_plane() {
  // 1500 sites clustered towards one corner, masses varying 10× across the square.
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> uniform(0, 1);
  json sites = json::array(), masses = json::array();
  for (int i = 0; i < 1500; ++i) {
    const double x = std::pow(uniform(random), 1.6), y = std::pow(uniform(random), 1.3);
    sites.push_back({x, y});
    masses.push_back(1 + 9 * x * y);
  }
  return {{"geometry", "plane"}, {"sites", sites}, {"masses", masses}, {"tolerance", 1e-9}};
}

}  // namespace

void register_plane(Registry& registry) {
  registry.add("plane", {solve_plane, bench_plane, demo_plane});
}

}  // namespace sdot::cli
