#include "common.hpp"
#include "sdot/input_file.hpp"

#include <filesystem>
#include <fstream>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <set>

namespace sdot::cli {

double read_number(const json& value, const std::string& field) {
  if (!value.is_number()) throw InputError(field, "must be a number");
  const double x = value.get<double>();
  if (!std::isfinite(x)) throw InputError(field, "must be finite");
  return x;
}

int read_int(const json& value, const std::string& field, const std::string& what) {
  // get<int>() would wrap a larger integer (4294967301 became 5) and cast a double out of range.
  constexpr auto low = std::numeric_limits<int>::min(), high = std::numeric_limits<int>::max();
  const bool fits = value.is_number_unsigned()  ? value.get<std::uint64_t>() <= std::uint64_t{high}
                    : value.is_number_integer() ? value.get<std::int64_t>() >= low && value.get<std::int64_t>() <= high
                                                : false;
  if (!fits) throw InputError(field, "must be " + what + ", got " + value.dump());
  return value.get<int>();
}

std::vector<Eigen::VectorXd> read_points(const json& value, const std::string& field, int dimension) {
  if (!value.is_array()) throw InputError(field, "must be an array of points");
  std::vector<Eigen::VectorXd> points;
  points.reserve(value.size());
  for (std::size_t i = 0; i < value.size(); ++i) {
    const json& p = value[i];
    const std::string name = indexed(field, i);
    if (!p.is_array() || p.size() != static_cast<std::size_t>(dimension))
      throw InputError(name, "must be an array of " + std::to_string(dimension) + " numbers");
    Eigen::VectorXd point(dimension);
    for (int d = 0; d < dimension; ++d) {
      if (!p[d].is_number()) throw InputError(name, "coordinate " + std::to_string(d) + " is not a number");
      point[d] = p[d].get<double>();
      if (!std::isfinite(point[d])) throw InputError(name, "coordinate is not finite");
    }
    points.push_back(point);
  }
  return points;
}

Eigen::VectorXd read_vector(const json& value, const std::string& field) {
  if (!value.is_array()) throw InputError(field, "must be an array of numbers");
  Eigen::VectorXd v(static_cast<Eigen::Index>(value.size()));
  for (std::size_t i = 0; i < value.size(); ++i)
    v[static_cast<Eigen::Index>(i)] = read_number(value[i], indexed(field, i));
  return v;
}

void check_known_fields(const json& object, const std::string& where, const std::vector<std::string>& known) {
  if (!object.is_object()) throw InputError(where.empty() ? "problem" : where, "must be a JSON object");
  for (const auto& [key, value] : object.items())
    if (std::find(known.begin(), known.end(), key) == known.end())
      throw InputError(where.empty() ? key : where + "." + key, "unknown field");
}

namespace {
std::size_t mmap_threshold_set = 0;
}  // namespace

// From large_problem_sites on, arrays of 1 MB and more come straight from the system and go back
// to it when freed. glibc otherwise raises that threshold to the size of each large array freed
// (up to 32 MB), and the vectors and triangulations rebuilt at every Newton step then fragment the
// heap: sphere, 10⁶ sites, peak RSS 1036–1076 MB against 954 MB (plane: about 1050 against 930).
// Below, glibc's own threshold keeps those arrays in the heap, where the next Newton step reuses
// their pages instead of faulting in and zeroing fresh ones, for a little more memory (sdot bench,
// interleaved runs, medians): sphere, 10⁵ sites, 0.69 s against 0.78 s (107–120 MB against
// 103–105 MB); 3·10⁵ sites, 2.45 s against 2.95 s (326–331 MB against 292 MB); plane, 10⁵ sites,
// 0.66 s against 0.73 s; H², 10⁵ sites, 0.97 s against 1.10 s.
std::size_t mmap_threshold_for(std::size_t sites) {
  return sites >= large_problem_sites ? std::size_t{1} << 20 : 0;
}

void use_malloc_policy_for(std::size_t sites) {
  const std::size_t threshold = mmap_threshold_for(sites);
  if (threshold == 0) return;
#if defined(__GLIBC__)
  if (mallopt(M_MMAP_THRESHOLD, static_cast<int>(threshold)) == 1) mmap_threshold_set = threshold;
#endif
}

std::size_t chosen_mmap_threshold() {
  return mmap_threshold_set;
}

namespace {
LinearSolverKind read_linear_solver(const json& solver) {
  if (!solver.is_string())
    throw InputError("linear_solver", "must be \"auto\", \"ldlt\", \"cg\", \"cholmod\" or \"multigrid\"");
  return linear_solver_from_name(solver.get<std::string>());
}

void print_progress(const IterationRecord& r) {
  std::fprintf(stderr, "  iteration %3d  max rel. error %9.3e  rms %9.3e  step %-9g %8.3f s\n", r.iteration,
               r.max_relative_error, r.rms_relative_error, r.step, r.elapsed_s);
}
}  // namespace

Options bench_options(const BenchRequest& request) {
  Options options;
  options.tolerance = request.tolerance;
  options.linear_solver = read_linear_solver(request.linear_solver);
  options.validate();
  if (!request.quiet) options.callback = print_progress;
  return options;
}

Options read_options(const json& problem, bool quiet) {
  Options options;
  if (problem.contains("tolerance")) options.tolerance = read_number(problem["tolerance"], "tolerance");
  if (problem.contains("max_iterations"))
    options.max_iterations = read_int(problem["max_iterations"], "max_iterations", "an integer");
  if (problem.contains("linear_solver")) options.linear_solver = read_linear_solver(problem["linear_solver"]);
  if (problem.contains("partial")) {
    if (!problem["partial"].is_boolean()) throw InputError("partial", "must be true or false");
    options.partial = problem["partial"].get<bool>();
  }
  try {
    options.validate();
  } catch (const InputError& e) {
    // Name the problem file's field, not the C++ one.
    std::string field = e.field();
    if (field.rfind("options.", 0) == 0) field = field.substr(8);
    throw InputError(field, std::string(e.what()).substr(e.field().size() + 2));
  }
  if (!quiet) options.callback = print_progress;
  return options;
}

Eigen::VectorXd read_masses(const json& problem, std::size_t site_count) {
  if (!problem.contains("masses")) return equal_masses(site_count);
  Eigen::VectorXd masses = read_vector(problem["masses"], "masses");
  if (static_cast<std::size_t>(masses.size()) != site_count)
    throw InputError("masses", "there are " + std::to_string(masses.size()) + " masses for " +
                                   std::to_string(site_count) + " sites");
  for (Eigen::Index i = 0; i < masses.size(); ++i)
    if (!(masses[i] > 0)) throw InputError(indexed("masses", static_cast<std::size_t>(i)), "must be positive");
  return masses;
}

std::optional<Eigen::VectorXd> read_weights(const json& problem, std::size_t site_count) {
  if (!problem.contains("weights")) return std::nullopt;
  Eigen::VectorXd weights = read_vector(problem["weights"], "weights");
  if (static_cast<std::size_t>(weights.size()) != site_count)
    throw InputError("weights", "there are " + std::to_string(weights.size()) + " weights for " +
                                    std::to_string(site_count) + " sites");
  return weights;
}

json read_json_file(const std::string& path, const std::string& what) {
  require_regular_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open " + what);
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  if (text.find_first_not_of(" \t\r\n") == std::string::npos)
    throw InputError(path, "empty file (" + what + " must hold a JSON object)");
  try {
    // Comments (// and /* */) are accepted: problem files are written and annotated by hand.
    return json::parse(text, nullptr, true, /*ignore_comments=*/true);
  } catch (const json::out_of_range& e) {  // 1e999: a number no double holds
    throw InputError(path, std::string("malformed JSON: a number out of the range of doubles (") + e.what() + ")");
  } catch (const json::exception& e) {
    throw InputError(path, std::string("malformed JSON: ") + e.what());
  }
}

std::string resolve_path(const RunContext& context, const std::string& file) {
  const std::filesystem::path path(file);
  if (path.is_absolute() || context.base_directory.empty()) return file;
  return (std::filesystem::path(context.base_directory) / path).string();
}

std::string read_choice(const json& object, const std::string& key, const std::string& field,
                        const std::vector<std::string>& allowed, const std::string& fallback) {
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "\"" : ", \"") + a + "\"";
  if (!object.contains(key)) {
    if (fallback.empty()) throw InputError(field, "missing (one of " + list + ")");
    return fallback;
  }
  const json& value = object[key];
  if (value.is_string())
    for (const auto& a : allowed)
      if (value.get<std::string>() == a) return a;
  throw InputError(field, "must be one of " + list + ", got " + value.dump());
}

GrayImage read_density_image(const json& density, const RunContext& context) {
  if (!density.contains("file") || !density["file"].is_string())
    throw InputError("density.file", "an image density needs a file name (PGM or PNG)");
  return read_image(resolve_path(context, density["file"].get<std::string>()));
}

double read_scale(const json& density) {
  if (!density.contains("scale")) return 1;
  const double scale = read_number(density["scale"], "density.scale");
  if (!(scale > 0)) throw InputError("density.scale", "must be positive");
  return scale;
}

Svg::Svg(double x0, double y0, double x1, double y1, double width_px)
    : x0_(x0), y1_(y1), scale_(width_px / (x1 - x0)), width_(width_px), height_((y1 - y0) * width_px / (x1 - x0)) {}

std::string Svg::xy(const Eigen::Vector2d& p) const {
  return fmt::format("{:.2f},{:.2f}", (p.x() - x0_) * scale_, (y1_ - p.y()) * scale_);
}

void Svg::polygon(const std::vector<Eigen::Vector2d>& points, const std::string& style) {
  body_ << "<polygon points=\"";
  for (const auto& p : points) body_ << xy(p) << ' ';
  body_ << "\" " << style << "/>\n";
}

void Svg::polyline(const std::vector<Eigen::Vector2d>& points, const std::string& style) {
  body_ << "<polyline points=\"";
  for (const auto& p : points) body_ << xy(p) << ' ';
  body_ << "\" fill=\"none\" " << style << "/>\n";
}

void Svg::circle(const Eigen::Vector2d& center, double radius_px, const std::string& style) {
  const auto c = xy(center);
  const auto comma = c.find(',');
  body_ << fmt::format("<circle cx=\"{}\" cy=\"{}\" r=\"{:.2f}\" {}/>\n", c.substr(0, comma), c.substr(comma + 1),
                       radius_px, style);
}

void Svg::world_circle(const Eigen::Vector2d& center, double radius, const std::string& style) {
  circle(center, radius * scale_, style);
}

void Svg::text(const Eigen::Vector2d& at, const std::string& text, double size_px) {
  const auto c = xy(at);
  const auto comma = c.find(',');
  body_ << fmt::format("<text x=\"{}\" y=\"{}\" font-family=\"sans-serif\" font-size=\"{}\">{}</text>\n",
                       c.substr(0, comma), c.substr(comma + 1), size_px, text);
}

std::string Svg::str() const {
  return fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{:.0f}\" height=\"{:.0f}\" viewBox=\"0 0 {:.0f} {:.0f}\">\n"
      "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n{}</svg>\n",
      width_, height_, width_, height_, body_.str());
}

double dot_radius_px(std::size_t count) {
  return std::clamp(40.0 / std::sqrt(static_cast<double>(std::max<std::size_t>(count, 1))), 0.6, 5.0);
}

TriangleMesh<Eigen::Vector2d> unit_square_bench_mesh(std::size_t triangles, std::vector<double>& values) {
  const int k = std::max(1, static_cast<int>(std::lround(std::sqrt(static_cast<double>(triangles) / 2))));
  TriangleMesh<Eigen::Vector2d> mesh;
  values.clear();
  for (int j = 0; j <= k; ++j)
    for (int i = 0; i <= k; ++i) {
      const Eigen::Vector2d p(static_cast<double>(i) / k, static_cast<double>(j) / k);
      mesh.vertices.push_back(p);
      values.push_back(1 + 0.5 * std::sin(2 * std::numbers::pi * p.x()) * std::sin(2 * std::numbers::pi * p.y()));
    }
  for (int j = 0; j < k; ++j)
    for (int i = 0; i < k; ++i) {
      const int a = j * (k + 1) + i, b = a + 1, c = a + k + 1, d = c + 1;
      mesh.triangles.push_back({a, b, d});
      mesh.triangles.push_back({a, d, c});
    }
  return mesh;
}

}  // namespace sdot::cli
