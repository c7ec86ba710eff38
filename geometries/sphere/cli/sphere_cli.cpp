// The sdot command's adapter for the sphere: problem fields, SVG picture (Mollweide projection),
// benchmark, demo.
#include <cmath>
#include <numbers>
#include <random>

#include "common.hpp"
#include "registry.hpp"
#include "sdot/geometries/sphere.hpp"
#include "sdot/geometries/sphere_densities.hpp"
#include "sdot/solver.hpp"

namespace sdot::cli {
namespace {

using Point = Sphere::Point;
constexpr double pi = std::numbers::pi;

std::vector<Point> to_points(const std::vector<Eigen::VectorXd>& points) {
  std::vector<Point> result;
  result.reserve(points.size());
  for (const auto& p : points) result.emplace_back(p[0], p[1], p[2]);
  return result;
}

Point read_direction(const json& value, const std::string& field) {
  if (!value.is_array() || value.size() != 3) throw InputError(field, "must be an array of 3 numbers");
  return Point(read_number(value[0], field + "[0]"), read_number(value[1], field + "[1]"),
               read_number(value[2], field + "[2]"));
}

Sphere read_domain(const json& problem) {
  if (!problem.contains("domain")) return Sphere();
  const json& domain = problem["domain"];
  if (!domain.is_object() || !domain.contains("type") || !domain["type"].is_string())
    throw InputError("domain.type", "missing (\"sphere\", \"cap\" or \"polygon\")");
  const std::string type = domain["type"].get<std::string>();
  if (type == "sphere") {
    check_known_fields(domain, "domain", {"type"});
    return Sphere();
  }
  if (type == "cap") {
    check_known_fields(domain, "domain", {"type", "center", "angle"});
    if (!domain.contains("center")) throw InputError("domain.center", "missing");
    if (!domain.contains("angle")) throw InputError("domain.angle", "missing");
    return Sphere::cap(read_direction(domain["center"], "domain.center"), read_number(domain["angle"], "domain.angle"));
  }
  if (type == "polygon") {
    check_known_fields(domain, "domain", {"type", "vertices"});
    if (!domain.contains("vertices")) throw InputError("domain.vertices", "missing");
    try {
      return Sphere::polygon(to_points(read_points(domain["vertices"], "domain.vertices", 3)));
    } catch (const InputError& e) {
      // Sphere::polygon names "domain[k]"; the file's field is domain.vertices[k].
      std::string field = e.field();
      if (field.rfind("domain", 0) == 0 && field.rfind("domain.", 0) != 0) field = "domain.vertices" + field.substr(6);
      throw InputError(field, std::string(e.what()).substr(e.field().size() + 2));
    }
  }
  throw InputError("domain.type", "unknown domain type '" + type + "' (supported: \"sphere\", \"cap\", \"polygon\")");
}

// ---- picture: Mollweide (equal-area) projection ------------------------------------------

Eigen::Vector2d mollweide(double longitude, double latitude) {
  double theta = latitude;
  const double target = pi * std::sin(latitude);
  for (int iteration = 0; iteration < 50; ++iteration) {
    const double f = 2 * theta + std::sin(2 * theta) - target;
    const double df = 2 + 2 * std::cos(2 * theta);
    if (std::abs(df) < 1e-12) break;
    const double step = f / df;
    theta -= step;
    if (std::abs(step) < 1e-12) break;
  }
  return {2 * std::sqrt(2.0) / pi * longitude * std::cos(theta), std::sqrt(2.0) * std::sin(theta)};
}

double longitude_of(const Point& x) {
  return std::atan2(x.y(), x.x());
}
double latitude_of(const Point& x) {
  return std::asin(std::clamp(x.z(), -1.0, 1.0));
}

/// A polyline on the sphere as projected polylines, cut where it crosses the seam (longitude ±π):
/// the crossing point is interpolated and each piece ends on its side of the map.
std::vector<std::vector<Eigen::Vector2d>> project(const std::vector<Point>& points) {
  std::vector<std::vector<Eigen::Vector2d>> pieces(1);
  for (std::size_t m = 0; m < points.size(); ++m) {
    const double lon = longitude_of(points[m]), lat = latitude_of(points[m]);
    if (m > 0) {
      const double previous_lon = longitude_of(points[m - 1]), previous_lat = latitude_of(points[m - 1]);
      if (std::abs(lon - previous_lon) > pi) {
        // Unwrap, find where the longitude reaches ±π, split there.
        const double unwrapped = lon + (lon < previous_lon ? 2 * pi : -2 * pi);
        const double edge = unwrapped > previous_lon ? pi : -pi;
        const double t = (edge - previous_lon) / (unwrapped - previous_lon);
        const double crossing_lat = previous_lat + t * (lat - previous_lat);
        pieces.back().push_back(mollweide(edge, crossing_lat));
        pieces.emplace_back();
        pieces.back().push_back(mollweide(-edge, crossing_lat));
      }
    }
    pieces.back().push_back(mollweide(lon, lat));
  }
  return pieces;
}

std::string draw(const Sphere& sphere, std::span<const Point> sites, const Result<Point>& result) {
  const double width = 2 * std::sqrt(2.0), height = std::sqrt(2.0);
  Svg svg(-width - 0.05, -height - 0.05, width + 0.05, height + 0.05, 1000);
  std::vector<Eigen::Vector2d> outline;
  for (int k = 0; k <= 180; ++k) {
    const double t = 2 * pi * k / 180;
    outline.emplace_back(width * std::cos(t), height * std::sin(t));
  }
  svg.polygon(outline, "fill=\"#f4f4f4\" stroke=\"black\" stroke-width=\"1.5\"");
  const double stroke = std::clamp(3.0 / std::sqrt(static_cast<double>(sites.size())), 0.2, 1.0);
  const std::string cell_style = fmt::format("stroke=\"#3060a0\" stroke-width=\"{:.2f}\"", stroke);
  const std::string boundary_style = "stroke=\"black\" stroke-width=\"1.5\"";
  for (std::size_t i = 0; i < result.diagram.cells.size(); ++i) {
    const auto cell = sphere.with_sampled_arcs(result.diagram.cells[i], sites[i], 24);
    for (std::size_t k = 0; k < cell.size(); ++k) {
      const int j = cell.neighbors[k];
      if (!is_boundary(j) && static_cast<std::size_t>(j) < i) continue;  // each edge once
      const Point& a = cell.vertices[k];
      const Point& b = cell.vertices[(k + 1) % cell.size()];
      const double angle = std::acos(std::clamp(a.dot(b), -1.0, 1.0));
      const int count = 2 + static_cast<int>(angle / 0.01);
      for (const auto& piece : project(sphere.edge_points(cell, k, count)))
        if (piece.size() >= 2) svg.polyline(piece, is_domain_boundary(j) ? boundary_style : cell_style);
    }
  }
  const double r = dot_radius_px(sites.size());
  for (const auto& c : result.centroids)
    svg.circle(mollweide(longitude_of(c), latitude_of(c)), r * 0.8, "fill=\"#20a040\"");
  for (const auto& s : sites) {
    const Point p = s.normalized();
    svg.circle(mollweide(longitude_of(p), latitude_of(p)), r, "fill=\"#d03020\"");
  }
  return svg.str();
}

// ---- commands --------------------------------------------------------------------------

SolveOutput solve_sphere(const json& problem, const RunContext& context) {
  check_known_fields(problem, "",
                     {"geometry", "sites", "masses", "domain", "density", "tolerance", "max_iterations", "weights",
                      "partial", "linear_solver", "builder"});
  if (!problem.contains("sites")) throw InputError("sites", "missing");
  const auto sites = to_points(read_points(problem["sites"], "sites", 3));
  if (sites.empty()) throw InputError("sites", "at least one site is needed");
  Sphere sphere = read_domain(problem);
  if (problem.contains("builder")) {
    if (!problem["builder"].is_string()) throw InputError("builder", "must be \"automatic\", \"clipping\" or \"hull\"");
    sphere.set_builder(Sphere::builder_from_name(problem["builder"].get<std::string>()));
  }
  const auto density = read_density(
      sphere, problem, context,
      [](const json& value, const std::string& field) {
        const Point p = read_direction(value, field);
        if (!(p.norm() > 0)) throw InputError(field, "is the zero vector");
        return Point(p.normalized());
      },
      [&](const GrayImage& image, const json& density_json) {
        const std::string interpolation =
            read_choice(density_json, "interpolation", "density.interpolation", {"constant", "linear"}, "linear");
        if (density_json.contains("rectangle"))
          throw InputError("density.rectangle", "the sphere's image is equirectangular over the whole sphere");
        return equirectangular_density(
            sphere, image, interpolation == "constant" ? ImageInterpolation::constant : ImageInterpolation::linear,
            read_scale(density_json));
      });
  return solve_problem(sphere, density, std::span<const Point>(sites), problem, context,
                       [&](const Result<Point>& result) { return draw(sphere, sites, result); });
}

json bench_sphere(const BenchRequest& request) {
  const auto sites = Sphere::uniform_samples(request.n, request.seed);
  const Sphere sphere;
  return run_bench(
      sphere, std::span<const Point>(sites), equal_masses(request.n, 4 * pi), request, [&](std::size_t triangles) {
        // A 2H × H longitude–latitude image, linear on its 4H² triangles:
        // ρ = 1 + ½ cos(latitude) sin(3 longitude) at the pixel centres.
        const int height = std::max(2, static_cast<int>(std::lround(std::sqrt(static_cast<double>(triangles) / 4))));
        GrayImage image{2 * height, height, {}};
        for (int r = 0; r < height; ++r)
          for (int c = 0; c < 2 * height; ++c) {
            const double longitude = -pi + (c + 0.5) * pi / height;
            const double latitude = pi / 2 - (r + 0.5) * pi / height;
            image.values.push_back(1 + 0.5 * std::cos(latitude) * std::sin(3 * longitude));
          }
        return equirectangular_density(sphere, image, ImageInterpolation::linear);
      });
}

json demo_sphere() {
  // 1500 sites, uniform on the sphere; masses 10× larger in the north than in the south.
  const auto points = Sphere::uniform_samples(1500, 7);
  json sites = json::array(), masses = json::array();
  for (const auto& p : points) {
    sites.push_back({p.x(), p.y(), p.z()});
    masses.push_back(1 + 9 * std::pow((1 + p.z()) / 2, 2));
  }
  return {{"geometry", "sphere"}, {"sites", sites}, {"masses", masses}, {"tolerance", 1e-9}};
}

}  // namespace

void register_sphere(Registry& registry) {
  registry.add("sphere", {solve_sphere, bench_sphere, demo_sphere});
}

}  // namespace sdot::cli
