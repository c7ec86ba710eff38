#pragma once
// Shared pieces of the sdot command: reading problem fields, writing results, progress, SVG.

#include <fmt/format.h>
#include <Eigen/Core>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "registry.hpp"
#include "sdot/error.hpp"
#include "sdot/options.hpp"
#include "sdot/solver.hpp"

namespace sdot::cli {

using nlohmann::json;

/// A number field; InputError naming the field when it is not a finite number.
double read_number(const json& value, const std::string& field);
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

/// Checks the optional "density" field; only {"type": "uniform"} is supported by the command.
void read_uniform_density(const json& problem, const std::string& supported = "\"uniform\"");

/// Peak resident set size of this process in MB.
double peak_rss_mb();

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

/// Solves a parsed problem with the uniform density, its masses, options and initial weights,
/// and fills the command's output (the picture through `draw` when asked for).
template <class G, class Draw>
SolveOutput solve_uniform_problem(const G& geometry, std::span<const typename G::Point> sites, const json& problem,
                                  const RunContext& context, Draw&& draw) {
  const Options options = read_options(problem, context.quiet);
  const auto result = solve(geometry, UniformDensity{}, sites, read_masses(problem, sites.size()), options,
                            read_weights(problem, sites.size()));
  SolveOutput output;
  output.result = result_json(std::string(G::name()), result);
  output.converged = result.summary.usable();
  if (context.want_svg) output.svg = draw(result);
  return output;
}

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
          {"peak_rss_mb", peak_rss_mb()}};
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
