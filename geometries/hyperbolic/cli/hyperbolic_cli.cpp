// The sdot command's adapter for the hyperbolic plane: problem fields, SVG picture in the
// Poincaré disc, benchmark, demo. The problem format is documented in docs/hyperbolic.md.
#include <cmath>
#include <numbers>
#include <random>

#include "common.hpp"
#include "registry.hpp"
#include "sdot/geometries/hyperbolic.hpp"
#include "sdot/solver.hpp"

namespace sdot::cli {
namespace {

using Point = Hyperbolic::Point;
using Model = Hyperbolic::Model;

Model read_model(const json& value, const std::string& field) {
  if (value == "klein") return Model::klein;
  if (value == "poincare") return Model::poincare;
  if (value == "hyperboloid") return Model::hyperboloid;
  throw InputError(field, "must be \"klein\", \"poincare\" or \"hyperboloid\"");
}

const char* model_name(Model model) {
  switch (model) {
    case Model::klein:
      return "klein";
    case Model::poincare:
      return "poincare";
    case Model::hyperboloid:
    default:
      return "hyperboloid";
  }
}

int dimension(Model model) {
  return model == Model::hyperboloid ? 3 : 2;
}

std::vector<Point> to_points(const std::vector<Eigen::VectorXd>& points, Model model, const std::string& field) {
  std::vector<Point> result;
  result.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    result.push_back(Hyperbolic::from_model(model, points[i], indexed(field, i)));
  return result;
}

json point_in(Model model, const Point& x) {
  switch (model) {
    case Model::klein:
      return point_json(Eigen::Vector2d(Hyperbolic::to_klein(x)));
    case Model::poincare:
      return point_json(Eigen::Vector2d(Hyperbolic::to_poincare(x)));
    case Model::hyperboloid:
    default:
      return point_json(x);
  }
}

// ---- SVG in the Poincaré disc ------------------------------------------------------------

constexpr double kPixels = 800;

std::string px(const Eigen::Vector2d& p) {
  // World [−1.04, 1.04]² (y up) → pixels.
  const double scale = kPixels / 2.08;
  return fmt::format("{:.2f},{:.2f}", (p.x() + 1.04) * scale, (1.04 - p.y()) * scale);
}

/// SVG path data of the geodesic polygon through `vertices` (hyperboloid), each edge a circular
/// arc orthogonal to the unit circle (a straight segment when it passes through the centre).
std::string geodesic_path(const std::vector<Point>& vertices) {
  const double scale = kPixels / 2.08;
  std::string d;
  const std::size_t n = vertices.size();
  for (std::size_t k = 0; k <= n; ++k) {
    const Eigen::Vector2d q = Hyperbolic::to_poincare(vertices[k % n]);
    if (k == 0) {
      d += "M" + px(q);
      continue;
    }
    const Eigen::Vector2d p = Hyperbolic::to_poincare(vertices[k - 1]);
    // The circle through p and q orthogonal to the unit circle: c·p = (|p|² + 1)/2, c·q = (|q|² + 1)/2.
    const double det = p.x() * q.y() - p.y() * q.x();
    const double bp = (p.squaredNorm() + 1) / 2, bq = (q.squaredNorm() + 1) / 2;
    const Eigen::Vector2d c((bp * q.y() - bq * p.y()) / det, (p.x() * bq - q.x() * bp) / det);
    const double radius = std::sqrt(std::max(0.0, c.squaredNorm() - 1));
    if (!std::isfinite(radius) || radius * scale > 1e5 || std::abs(det) < 1e-12) {
      d += " L" + px(q);
      continue;
    }
    const Eigen::Vector2d u = p - c, v = q - c;
    // Counter-clockwise around c in the world is clockwise on the (y-down) screen: sweep 0.
    const int sweep = u.x() * v.y() - u.y() * v.x() > 0 ? 0 : 1;
    d += fmt::format(" A{:.2f},{:.2f} 0 0 {} {}", radius * scale, radius * scale, sweep, px(q));
  }
  return d + " Z";
}

std::string draw(const Hyperbolic& geometry, std::span<const Point> sites, const Result<Point>& result) {
  const double scale = kPixels / 2.08;
  std::string body;
  body += fmt::format(
      "<circle cx=\"{0:.2f}\" cy=\"{0:.2f}\" r=\"{1:.2f}\" fill=\"#fbfbfb\" stroke=\"black\" "
      "stroke-width=\"1.2\"/>\n",
      1.04 * scale, scale);
  body +=
      "<path d=\"" + geodesic_path(geometry.domain()) + "\" fill=\"#ececec\" stroke=\"black\" stroke-width=\"1.5\"/>\n";
  const double stroke = std::clamp(3.0 / std::sqrt(static_cast<double>(sites.size())), 0.2, 1.0);
  for (std::size_t i = 0; i < result.diagram.cells.size(); ++i)
    if (!result.diagram.cells[i].empty())
      body += fmt::format("<path d=\"{}\" fill=\"none\" stroke=\"#3060a0\" stroke-width=\"{:.2f}\"/>\n",
                          geodesic_path(geometry.with_sampled_arcs(result.diagram.cells[i], sites[i], 24).vertices),
                          stroke);
  const double r = dot_radius_px(sites.size());
  auto dot = [&](const Point& x, double radius, const char* color) {
    const auto c = px(Hyperbolic::to_poincare(x));
    const auto comma = c.find(',');
    body += fmt::format("<circle cx=\"{}\" cy=\"{}\" r=\"{:.2f}\" fill=\"{}\"/>\n", c.substr(0, comma),
                        c.substr(comma + 1), radius, color);
  };
  for (const auto& c : result.centroids) dot(c, 0.8 * r, "#20a040");
  for (const auto& s : sites) dot(s, r, "#d03020");
  body += fmt::format(
      "<text x=\"8\" y=\"20\" font-family=\"sans-serif\" font-size=\"14\">hyperbolic plane, "
      "Poincare disc: {} sites</text>\n",
      sites.size());
  return fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0:.0f}\" height=\"{0:.0f}\" "
      "viewBox=\"0 0 {0:.0f} {0:.0f}\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n{1}</svg>\n",
      kPixels, body);
}

// ---- solve -------------------------------------------------------------------------------

SolveOutput solve_hyperbolic(const json& problem, const RunContext& context) {
  check_known_fields(problem, "",
                     {"geometry", "sites", "sites_model", "masses", "domain", "density", "tolerance", "max_iterations",
                      "weights", "linear_solver", "partial"});
  if (!problem.contains("domain"))
    throw InputError("domain",
                     "missing: the hyperbolic plane needs a compact source domain, e.g. "
                     "{\"model\": \"klein\", \"vertices\": [[-0.5,-0.5], [0.5,-0.5], [0, 0.6]]}");
  const json& domain_json = problem["domain"];
  check_known_fields(domain_json, "domain", {"model", "vertices"});
  if (!domain_json.contains("model"))
    throw InputError("domain.model", "missing (\"klein\", \"poincare\" or \"hyperboloid\")");
  if (!domain_json.contains("vertices")) throw InputError("domain.vertices", "missing");
  const Model domain_model = read_model(domain_json["model"], "domain.model");
  const auto domain_vertices = read_points(domain_json["vertices"], "domain", dimension(domain_model));
  const Hyperbolic geometry = Hyperbolic::from_model(domain_model, domain_vertices);

  const Model sites_model =
      problem.contains("sites_model") ? read_model(problem["sites_model"], "sites_model") : domain_model;
  if (!problem.contains("sites")) throw InputError("sites", "missing");
  const auto sites = to_points(read_points(problem["sites"], "sites", dimension(sites_model)), sites_model, "sites");
  if (sites.empty()) throw InputError("sites", "at least one site is needed");
  // Mesh vertices are in the sites' model.
  const auto density = read_density(
      geometry, problem, context,
      [&](const json& value, const std::string& field) {
        const auto points = read_points(json::array({value}), field, dimension(sites_model));
        return Hyperbolic::from_model(sites_model, points[0], field);
      },
      [](const GrayImage&, const json&) -> PiecewiseDensity<Hyperbolic> {
        throw InputError("density.type", "image densities are available on the plane and the sphere; use a mesh");
      });
  SolveOutput output = solve_problem(geometry, density, std::span<const Point>(sites), problem, context,
                                     [&](const Result<Point>& result) { return draw(geometry, sites, result); });
  // Centroids are hyperboloid points; also give them in the sites' model.
  output.result["sites_model"] = model_name(sites_model);
  if (sites_model != Model::hyperboloid) {
    json centroids = json::array();
    for (const auto& c : output.result["centroids"])
      centroids.push_back(point_in(sites_model, Point(c[0].get<double>(), c[1].get<double>(), c[2].get<double>())));
    output.result[std::string("centroids_") + model_name(sites_model)] = std::move(centroids);
  }
  output.result["domain_area"] = geometry.domain_area();
  return output;
}

// ---- bench and demo ----------------------------------------------------------------------

/// The benchmark domain: the regular octagon of circumradius 1.5 centred at distance 2 from the
/// origin (on the positive x axis).
/// Built from the polygon's vertices, as `python -m sdot.bench` builds it, so that both solve
/// the same problem to the last bit.
Hyperbolic bench_domain() {
  const auto octagon = Hyperbolic::regular_polygon(8, 1.5, Hyperbolic::polar(2, 0)).domain();
  const std::vector<Eigen::VectorXd> vertices(octagon.begin(), octagon.end());
  return Hyperbolic::from_model(Model::hyperboloid, vertices);
}

json bench_hyperbolic(const BenchRequest& request) {
  const Hyperbolic geometry = bench_domain();
  const auto sites = geometry.uniform_samples(request.n, request.seed);
  return run_bench(
      geometry, std::span<const Point>(sites), equal_masses(request.n), request, [&](std::size_t triangles) {
        // The domain's fan from its centre, each domain edge split into m parts, then
        // subdivided L times: sides·m·4^L triangles, m and L chosen to come closest to
        // `triangles`. ρ = 1 + ½ sin(3 k₁) cos(2 k₂) in Klein coordinates at the vertices.
        const auto& domain = geometry.domain();
        const auto sides = static_cast<double>(domain.size());
        int levels = 0;
        while (sides * std::pow(4.0, levels + 1) <= static_cast<double>(triangles)) ++levels;
        const int parts = std::max(
            1, static_cast<int>(std::lround(static_cast<double>(triangles) / (sides * std::pow(4.0, levels)))));
        TriangleMesh<Point> mesh;
        mesh.vertices.push_back(geometry.center());
        for (std::size_t k = 0; k < domain.size(); ++k) {
          // Points along the geodesic edge: straight in the projective chart.
          const Eigen::Vector3d a = geometry.to_projective(domain[k]).normalized();
          const Eigen::Vector3d b = geometry.to_projective(domain[(k + 1) % domain.size()]).normalized();
          for (int j = 0; j < parts; ++j)
            mesh.vertices.push_back(geometry.from_projective(a + (b - a) * (static_cast<double>(j) / parts)));
        }
        const int rim = static_cast<int>(mesh.vertices.size()) - 1;
        for (int k = 0; k < rim; ++k) mesh.triangles.push_back({0, 1 + k, 1 + (k + 1) % rim});
        mesh = subdivide(geometry, mesh, levels);
        std::vector<double> values;
        for (const auto& v : mesh.vertices) {
          const Eigen::Vector2d k = Hyperbolic::to_klein(v);
          values.push_back(1 + 0.5 * std::sin(3 * k.x()) * std::cos(2 * k.y()));
        }
        return mesh_density(geometry, std::span<const Point>(mesh.vertices),
                            std::span<const std::array<int, 3>>(mesh.triangles), std::span<const double>(values));
      });
}

json demo_hyperbolic() {
  // A hexagon given in Poincaré coordinates; 800 sites uniform in hyperbolic area, masses
  // growing 10× from one side to the other.
  std::vector<Eigen::VectorXd> hexagon;
  for (int k = 0; k < 6; ++k) {
    const double angle = std::numbers::pi * k / 3 + 0.2;
    hexagon.push_back(Eigen::Vector2d(0.82 * std::cos(angle), 0.82 * std::sin(angle)));
  }
  const Hyperbolic geometry = Hyperbolic::from_model(Model::poincare, hexagon);
  const auto sites = geometry.uniform_samples(800, 7);
  json domain = json::array(), points = json::array(), masses = json::array();
  for (const auto& v : hexagon) domain.push_back(point_json(v));
  for (const auto& s : sites) {
    const Eigen::Vector2d p = Hyperbolic::to_poincare(s);
    points.push_back(point_json(p));
    masses.push_back(1 + 4.5 * (1 + p.x()));
  }
  return {{"geometry", "hyperbolic"},  {"domain", {{"model", "poincare"}, {"vertices", domain}}},
          {"sites_model", "poincare"}, {"sites", points},
          {"masses", masses},          {"tolerance", 1e-9}};
}

}  // namespace

void register_hyperbolic(Registry& registry) {
  registry.add("hyperbolic", {solve_hyperbolic, bench_hyperbolic, demo_hyperbolic});
}

}  // namespace sdot::cli
