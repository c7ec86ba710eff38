#pragma once
// Shared pieces of the sdot command: reading problem fields, writing results, progress, SVG.

#include <fmt/format.h>
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "registry.hpp"
#include "sdot/detail/runtime_settings.hpp"
#include "sdot/error.hpp"
#include "sdot/image.hpp"
#include "sdot/options.hpp"
#include "sdot/piecewise_density.hpp"
#include "sdot/resources.hpp"
#include "sdot/solver.hpp"

namespace sdot::cli {

using nlohmann::json;

/// A number field; InputError naming the field when it is not a finite number.
double read_number(const json& value, const std::string& field);
/// An integer field that fits an int; InputError naming the field ("must be " + `what`) otherwise.
int read_int(const json& value, const std::string& field, const std::string& what);
/// An array of points with `dimension` coordinates each.
std::vector<Eigen::VectorXd> read_points(const json& value, const std::string& field, int dimension);
/// An array of numbers.
Eigen::VectorXd read_vector(const json& value, const std::string& field);
/// Solver options of `sdot bench`: tolerance, linear solver, progress unless quiet.
Options bench_options(const struct BenchRequest& request);
/// Solver options from a problem: tolerance, max_iterations, linear_solver.
Options read_options(const json& problem, bool quiet);
/// Rejects fields of `object` that are not in `known` (catches typos in problem files).
void check_known_fields(const json& object, const std::string& where, const std::vector<std::string>& known);
/// The masses field (default equal masses).
Eigen::VectorXd read_masses(const json& problem, std::size_t site_count);
/// The optional initial weights.
std::optional<Eigen::VectorXd> read_weights(const json& problem, std::size_t site_count);

/// Reads and parses a JSON file; InputError naming the path (`what` says which file it is).
json read_json_file(const std::string& path, const std::string& what);
/// A file name from a problem, relative to the problem file's directory unless absolute.
std::string resolve_path(const RunContext& context, const std::string& file);
/// A string field of `object` (or `fallback` when absent), one of `allowed`.
std::string read_choice(const json& object, const std::string& key, const std::string& field,
                        const std::vector<std::string>& allowed, const std::string& fallback);
/// A density's image: `density.file` resolved and read.
GrayImage read_density_image(const json& density, const RunContext& context);
/// A density's "scale" (default 1).
double read_scale(const json& density);

/// The problem's "density" (docs/file-formats.md): empty for "uniform" (or none), else a
/// piecewise density. `read_vertex(value, field)` converts one mesh vertex of the geometry;
/// `image(image, density)` builds an image density (it throws for geometries without images).
template <class G, class ReadVertex, class ImageDensity>
std::optional<PiecewiseDensity<G>> read_density(const G& geometry, const json& problem, const RunContext& context,
                                                ReadVertex&& read_vertex, ImageDensity&& image) {
  if (!problem.contains("density")) return std::nullopt;
  const json& density = problem["density"];
  if (!density.is_object()) throw InputError("density", "must be an object such as {\"type\": \"uniform\"}");
  const std::string type = read_choice(density, "type", "density.type", {"uniform", "mesh", "image"}, "");
  if (type == "uniform") {
    check_known_fields(density, "density", {"type"});
    return std::nullopt;
  }
  if (type == "image") {
    check_known_fields(density, "density", {"type", "file", "interpolation", "rectangle", "scale"});
    return image(read_density_image(density, context), density);
  }
  check_known_fields(density, "density",
                     {"type", "file", "vertices", "triangles", "values", "triangle_values", "quadrature_order"});
  json file_content;
  const json* mesh = &density;
  std::string prefix = "density";
  if (density.contains("file")) {
    if (!density["file"].is_string()) throw InputError("density.file", "must be a file name");
    const std::string path = resolve_path(context, density["file"].get<std::string>());
    file_content = read_json_file(path, "the density mesh file");
    if (!file_content.is_object()) throw InputError(path, "must be a JSON object with vertices, triangles and values");
    check_known_fields(file_content, path, {"vertices", "triangles", "values", "triangle_values"});
    mesh = &file_content;
    prefix = path;
  }
  for (const char* key : {"vertices", "triangles"})
    if (!mesh->contains(key)) throw InputError(prefix + "." + key, "missing");
  const json& vertex_array = (*mesh)["vertices"];
  if (!vertex_array.is_array()) throw InputError(prefix + ".vertices", "must be an array of points");
  std::vector<typename G::Point> vertices;
  for (std::size_t i = 0; i < vertex_array.size(); ++i)
    vertices.push_back(read_vertex(vertex_array[i], indexed(prefix + ".vertices", i)));
  const json& triangle_array = (*mesh)["triangles"];
  if (!triangle_array.is_array()) throw InputError(prefix + ".triangles", "must be an array of [i, j, k]");
  std::vector<std::array<int, 3>> triangles;
  for (std::size_t t = 0; t < triangle_array.size(); ++t) {
    const json& tri = triangle_array[t];
    const std::string field = indexed(prefix + ".triangles", t);
    if (!(tri.is_array() && tri.size() == 3 && tri[0].is_number_integer() && tri[1].is_number_integer() &&
          tri[2].is_number_integer()))
      throw InputError(field, "must be an array of 3 vertex indices");
    std::array<int, 3> triangle{};
    for (int k = 0; k < 3; ++k) {  // checked before get<int>(), which would wrap 4294967296 to 0
      const json& v = tri[k];
      if (v.is_number_unsigned() ? v.get<std::uint64_t>() >= vertices.size()
                                 : v.get<std::int64_t>() < 0 || v.get<std::int64_t>() >= std::ssize(vertices))
        throw InputError(
            field, "vertex index " + v.dump() + " is out of range (" + std::to_string(vertices.size()) + " vertices)");
      triangle[static_cast<std::size_t>(k)] = v.get<int>();
    }
    triangles.push_back(triangle);
  }
  const bool per_vertex = mesh->contains("values"), per_triangle = mesh->contains("triangle_values");
  if (per_vertex == per_triangle)
    throw InputError(prefix, "give exactly one of \"values\" (per vertex) and \"triangle_values\" (per triangle)");
  const std::string values_key = per_vertex ? "values" : "triangle_values";
  const Eigen::VectorXd values = read_vector((*mesh)[values_key], prefix + "." + values_key);
  const std::span<const double> value_span(values.data(), static_cast<std::size_t>(values.size()));
  if (per_triangle)
    return mesh_density_per_triangle(geometry, std::span<const typename G::Point>(vertices),
                                     std::span<const std::array<int, 3>>(triangles), value_span, prefix);
  const int order = density.contains("quadrature_order")
                        ? read_int(density["quadrature_order"], "density.quadrature_order", "an integer in 1..64")
                        : 3;
  if (order < 1 || order > 64) throw InputError("density.quadrature_order", "must be an integer in 1..64");
  return mesh_density(geometry, std::span<const typename G::Point>(vertices),
                      std::span<const std::array<int, 3>>(triangles), value_span, order, prefix);
}

template <class Point>
json point_json(const Point& p) {
  json array = json::array();
  for (Eigen::Index d = 0; d < p.size(); ++d) array.push_back(p[d]);
  return array;
}

/// The RESULT file of `sdot solve` (docs/file-formats.md).
template <class Point>
json result_json(const std::string& geometry, const Result<Point>& result) {
  const Summary& s = result.summary;
  json out;
  out["geometry"] = geometry;
  out["status"] = std::string(to_string(s.status));
  out["message"] = s.message;
  out["iterations"] = s.iterations;
  out["max_relative_mass_error"] = s.max_relative_error;
  out["rms_relative_mass_error"] = s.rms_relative_error;
  out["mass_scale"] = s.mass_scale;
  out["source_mass"] = s.source_mass;
  out["weights"] = std::vector<double>(result.weights.data(), result.weights.data() + result.weights.size());
  out["masses"] = std::vector<double>(result.masses.data(), result.masses.data() + result.masses.size());
  json centroids = json::array();
  for (const auto& c : result.centroids) centroids.push_back(point_json(c));
  out["centroids"] = std::move(centroids);
  out["transport_cost"] = result.transport_cost;
  if (result.ball_radii.size() > 0)
    out["ball_radii"] =
        std::vector<double>(result.ball_radii.data(), result.ball_radii.data() + result.ball_radii.size());
  out["adjacency"] = result.adjacency();
  out["timings"] = {{"diagram_s", s.timings.diagram_s},
                    {"assembly_s", s.timings.assembly_s},
                    {"linear_solve_s", s.timings.linear_solve_s},
                    {"total_s", s.timings.total_s}};
  json history = json::array();
  for (const auto& r : s.history)
    history.push_back({{"iteration", r.iteration},
                       {"max_relative_error", r.max_relative_error},
                       {"rms_relative_error", r.rms_relative_error},
                       {"step", r.step},
                       {"elapsed_s", r.elapsed_s}});
  out["history"] = std::move(history);
  return out;
}

/// Solves a parsed problem with its density (uniform when empty), masses, options and initial
/// weights, and fills the command's output (the picture through `draw` when asked for).
template <class G, class Draw>
SolveOutput solve_problem(const G& geometry, const std::optional<PiecewiseDensity<G>>& density,
                          std::span<const typename G::Point> sites, const json& problem, const RunContext& context,
                          Draw&& draw) {
  const Options options = read_options(problem, context.quiet);
  const auto masses = read_masses(problem, sites.size());
  const auto weights = read_weights(problem, sites.size());
  const auto result = density ? solve(geometry, *density, sites, masses, options, weights)
                              : solve(geometry, UniformDensity{}, sites, masses, options, weights);
  SolveOutput output;
  output.result = result_json(std::string(G::name()), result);
  output.converged = result.summary.usable();
  if (context.want_svg) output.svg = draw(result);
  return output;
}

/// Sites from which the command has glibc map arrays of 1 MB and more straight from the system
/// (see use_malloc_policy_for).
inline constexpr std::size_t large_problem_sites = 500'000;

/// The M_MMAP_THRESHOLD the command sets for a problem of `sites` sites, in bytes; 0 keeps glibc's
/// own (dynamic) threshold.
std::size_t mmap_threshold_for(std::size_t sites);

/// Sets glibc's M_MMAP_THRESHOLD to mmap_threshold_for(sites) (nothing without glibc, or at 0).
void use_malloc_policy_for(std::size_t sites);

/// The threshold set by use_malloc_policy_for, 0 when none was set (for the bench line).
std::size_t chosen_mmap_threshold();

/// The one-line JSON of `sdot bench`.
template <class Point>
json bench_json(const std::string& geometry, std::size_t n, const Result<Point>& result) {
  const Summary& s = result.summary;
  return {{"geometry", geometry},
          {"n", n},
          {"status", std::string(to_string(s.status))},
          {"iterations", s.iterations},
          {"max_relative_mass_error", s.max_relative_error},
          {"time_s", s.timings.total_s},
          {"diagram_s", s.timings.diagram_s},
          {"assembly_s", s.timings.assembly_s},
          {"linear_solve_s", s.timings.linear_solve_s},
          {"peak_rss_mb", peak_resident_memory_mb()},
          {"omp_wait_policy", sdot::detail::omp_wait_policy_setting()},  // passive unless told otherwise
          {"mmap_threshold", chosen_mmap_threshold() ? json(chosen_mmap_threshold()) : json("default")},
          {"glibc_malloc_hugetlb", sdot::detail::heap_huge_pages_setting()}};
}

/// The bench density of the unit square (plane and torus): a k × k grid of squares, two triangles
/// each, about `triangles` in all, with per-vertex values ρ = 1 + ½ sin(2πx) sin(2πy) in `values`.
TriangleMesh<Eigen::Vector2d> unit_square_bench_mesh(std::size_t triangles, std::vector<double>& values);

/// The benchmark: the uniform density, or (request.density_triangles > 0) the mesh density that
/// `make_density(triangles)` builds; the line then also gives the mesh's size and build time.
template <class G, class MakeDensity>
json run_bench(const G& geometry, std::span<const typename G::Point> sites, const Eigen::VectorXd& masses,
               const BenchRequest& request, MakeDensity&& make_density) {
  const Options options = bench_options(request);
  if (request.density_triangles == 0)
    return bench_json(std::string(G::name()), request.n, solve(geometry, UniformDensity{}, sites, masses, options));
  const auto start = std::chrono::steady_clock::now();
  const auto density = make_density(request.density_triangles);
  const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  json line = bench_json(std::string(G::name()), request.n, solve(geometry, density, sites, masses, options));
  line["density_triangles"] = density.piece_count();
  line["density_build_s"] = build_s;
  return line;
}

/// A simple SVG canvas with a world-to-pixel map (y up in the world, down in the picture).
class Svg {
 public:
  Svg(double x0, double y0, double x1, double y1, double width_px = 800);
  void polygon(const std::vector<Eigen::Vector2d>& points, const std::string& style);
  void polyline(const std::vector<Eigen::Vector2d>& points, const std::string& style);
  void circle(const Eigen::Vector2d& center, double radius_px, const std::string& style);
  void world_circle(const Eigen::Vector2d& center, double radius, const std::string& style);
  void text(const Eigen::Vector2d& at, const std::string& text, double size_px = 14);
  [[nodiscard]] std::string str() const;
  [[nodiscard]] double height_px() const { return height_; }

 private:
  [[nodiscard]] std::string xy(const Eigen::Vector2d& p) const;
  double x0_, y1_, scale_, width_, height_;
  std::ostringstream body_;
};

/// A dot radius that keeps pictures readable from 10 to a few thousand sites.
double dot_radius_px(std::size_t count);

}  // namespace sdot::cli
