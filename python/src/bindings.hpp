#pragma once
// Shared pieces of the Python module's geometry adapters (geometries/*/python): numpy arrays to
// points and vectors, densities from numpy (images, meshes, Python callables), the solve with the
// GIL released, and the result as numpy arrays.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "registry.hpp"
#include "sdot/error.hpp"
#include "sdot/image.hpp"
#include "sdot/piecewise_density.hpp"
#include "sdot/solver.hpp"

namespace sdot::python {

/// "(3, 2)" for an array of that shape.
std::string shape_string(const py::array& array);

/// A float64 C-contiguous array of shape (n, dimension); InputError naming `field` otherwise.
/// The pure-Python layer converts dtypes and copies non-contiguous arrays before calling in.
const double* checked_rows(const py::array_t<double>& array, const std::string& field, int dimension);

/// The rows of a (n, dimension) array, each made into a point by `convert(row, index)`.
template <class Point, class Convert>
std::vector<Point> read_points(const py::array_t<double>& array, const std::string& field, int dimension,
                               Convert&& convert) {
  const double* data = checked_rows(array, field, dimension);
  std::vector<Point> points;
  points.reserve(static_cast<std::size_t>(array.shape(0)));
  for (py::ssize_t i = 0; i < array.shape(0); ++i)
    points.push_back(convert(data + i * dimension, static_cast<std::size_t>(i)));
  return points;
}

/// The rows of a (n, Point::size) array as points, without a copy when the array's memory is laid
/// out and aligned as Points are (then `storage` stays empty); else copied into `storage`.
template <class Point>
std::span<const Point> view_points(const py::array_t<double>& array, const std::string& field,
                                   std::vector<Point>& storage) {
  constexpr int dimension = static_cast<int>(Point::SizeAtCompileTime);
  const double* data = checked_rows(array, field, dimension);
  const auto count = static_cast<std::size_t>(array.shape(0));
  if (sizeof(Point) == dimension * sizeof(double) && reinterpret_cast<std::uintptr_t>(data) % alignof(Point) == 0)
    return {reinterpret_cast<const Point*>(data), count};
  storage = read_points<Point>(array, field, dimension, [](const double* row, std::size_t) {
    Point p;
    for (int d = 0; d < dimension; ++d) p[d] = row[d];
    return p;
  });
  return storage;
}

/// A float64 vector of `count` entries, or nothing for None.
std::optional<Eigen::VectorXd> read_vector(const py::object& value, const std::string& field, std::size_t count);

/// Triangles from an int array of shape (m, 3).
std::vector<std::array<int, 3>> read_triangles(const py::object& value, const std::string& field);

/// A grayscale image from a 2-D float64 array (row 0 at the top), values as given (≥ 0).
GrayImage read_image_array(const py::object& value, const std::string& field);

// ---- a Python callable as a density --------------------------------------------------------

/// Calls a Python function on batches of points: one call with an (m, dimension) array, which
/// must return m finite values ≥ 0. Holds no reference: the caller keeps the function alive.
template <class Point>
class PythonFunction {
 public:
  using Coordinates = std::function<void(const Point&, double*)>;
  PythonFunction(py::handle function, int dimension, Coordinates coordinates)
      : function_(function), dimension_(dimension), coordinates_(std::move(coordinates)) {}

  /// Thread-safe: takes the GIL.
  [[nodiscard]] std::vector<double> operator()(const std::vector<Point>& points) const {
    py::gil_scoped_acquire gil;
    const auto m = static_cast<py::ssize_t>(points.size());
    py::array_t<double> x({m, static_cast<py::ssize_t>(dimension_)});
    double* out = x.mutable_data();
    for (py::ssize_t i = 0; i < m; ++i) coordinates_(points[static_cast<std::size_t>(i)], out + i * dimension_);
    const py::object returned = function_(x);
    const auto values = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(returned);
    if (!values || values.size() != m || (values.ndim() != 1 && !(values.ndim() == 2 && values.shape(1) == 1)))
      throw InputError("density", "the function must return one number per point: called on " + std::to_string(m) +
                                      " points, it returned " +
                                      (values ? "an array of shape " + shape_string(values)
                                              : std::string(py::str(returned.get_type().attr("__name__")))));
    std::vector<double> result(values.data(), values.data() + m);
    for (py::ssize_t i = 0; i < m; ++i)
      if (!(std::isfinite(result[static_cast<std::size_t>(i)]) && result[static_cast<std::size_t>(i)] >= 0)) {
        std::string where;
        for (int d = 0; d < dimension_; ++d) where += (d ? ", " : "") + std::to_string(out[i * dimension_ + d]);
        throw InputError("density", "the function returned " + std::to_string(result[static_cast<std::size_t>(i)]) +
                                        " at (" + where + "); it must be finite and >= 0");
      }
    return result;
  }

 private:
  py::handle function_;
  int dimension_;
  Coordinates coordinates_;
};

/// The field that an inner density integrates with: set per thread by BatchedFunctionDensity.
template <class Point>
inline thread_local const ScalarField<Point>* active_field = nullptr;

template <class Point>
double active_field_value(const Point& x) {
  return (*active_field<Point>)(x);
}

/// A density whose ρ is a Python function, evaluated once per cell (and once per facet) on all of
/// that cell's quadrature points in one vectorized call instead of one call per point. `Inner`
/// integrates with `active_field_value`: a first pass records the quadrature points, the function
/// is called on them, and a second pass integrates with the values (checking that the points are
/// the same).
template <class Inner, class Point>
class BatchedFunctionDensity {
 public:
  BatchedFunctionDensity(Inner inner, const PythonFunction<Point>& function)
      : inner_(std::move(inner)), function_(&function) {}

  template <class G>
  [[nodiscard]] CellIntegrals<Point> integrate_cell(const G& geometry, const Cell<Point>& cell, const Point& site,
                                                    bool with_cost = true) const {
    return batched([&] { return inner_.integrate_cell(geometry, cell, site, with_cost); });
  }
  template <class G>
  [[nodiscard]] double facet_weight(const G& geometry, const Point& a, const Point& b, const Point& site_i,
                                    double weight_i, const Point& site_j, double weight_j) const {
    return batched([&] { return inner_.facet_weight(geometry, a, b, site_i, weight_i, site_j, weight_j); });
  }

 private:
  struct Restore {
    ~Restore() { active_field<Point> = nullptr; }
  };

  template <class Integrate>
  auto batched(Integrate&& integrate) const {
    const Restore restore;
    std::vector<Point> points;
    const ScalarField<Point> record = [&](const Point& x) {
      points.push_back(x);
      return 1.0;
    };
    active_field<Point> = &record;
    auto result = integrate();
    if (points.empty()) return result;
    const std::vector<double> values = (*function_)(points);
    std::size_t next = 0;
    const ScalarField<Point> replay = [&](const Point& x) {
      if (next >= points.size() || !(points[next] == x))
        throw Error("internal error: the quadrature points differ between the two passes of a function density");
      return values[next++];
    };
    active_field<Point> = &replay;
    result = integrate();
    return result;
  }

  Inner inner_;
  const PythonFunction<Point>* function_;
};

/// The order of a function density's quadrature (request.density[2]), 1..64.
int read_quadrature_order(const py::object& value, const std::string& field);

/// Calls `run(density)` with the request's density for `geometry`:
/// - None: UniformDensity (or `uniform_on_region`'s density when the domain needs one);
/// - ("mesh", vertices, triangles, values, per_triangle, order): a piecewise density, vertices
///   read by `read_vertices(array, field)`;
/// - ("image", values, extent, interpolation, scale): `image(GrayImage, extent, interpolation,
///   scale)`;
/// - ("function", callable, order): a BatchedFunctionDensity over FunctionDensity, or over the
///   region's pieces when `region_pieces` is not empty (points passed to the callable through
///   `coordinates`, `dimension` numbers each).
/// `region_pieces`, when not empty, restricts every density to those convex pieces.
template <ProjectiveGeometry G, class ReadVertices, class Image, class Run>
auto with_density(const G& geometry, const SolveRequest& request, ReadVertices&& read_vertices, Image&& image,
                  const std::vector<std::vector<typename G::Point>>& region_pieces, int dimension,
                  typename PythonFunction<typename G::Point>::Coordinates coordinates, Run&& run) {
  using Point = typename G::Point;
  const auto restrict = [&](PiecewiseDensity<G> density) {
    return region_pieces.empty() ? density : density.restricted_to(region_pieces);
  };
  if (request.density.is_none()) {
    if (region_pieces.empty()) return run(UniformDensity{});
    std::vector<DensityPiece<Point>> pieces;
    for (const auto& polygon : region_pieces) pieces.push_back({polygon, PieceKind::constant, {1, 0, 0}});
    return run(PiecewiseDensity<G>(geometry, pieces, {}, 3, "domain"));
  }
  const auto spec = request.density.cast<py::tuple>();
  const auto kind = spec[0].cast<std::string>();
  if (kind == "mesh") {
    const std::vector<Point> vertices = read_vertices(spec[1].cast<py::array_t<double>>(), "density.vertices");
    const auto triangles = read_triangles(spec[2], "density.triangles");
    const bool per_triangle = spec[4].cast<bool>();
    const std::size_t count = per_triangle ? triangles.size() : vertices.size();
    const Eigen::VectorXd values =
        *read_vector(spec[3], per_triangle ? "density.triangle_values" : "density.values", count);
    const std::span<const double> value_span(values.data(), count);
    if (per_triangle)
      return run(restrict(mesh_density_per_triangle(geometry, std::span<const Point>(vertices),
                                                    std::span<const std::array<int, 3>>(triangles), value_span)));
    return run(restrict(mesh_density(geometry, std::span<const Point>(vertices),
                                     std::span<const std::array<int, 3>>(triangles), value_span,
                                     read_quadrature_order(spec[5], "density.quadrature_order"))));
  }
  if (kind == "image")
    return run(restrict(
        image(read_image_array(spec[1], "density"), spec[2], spec[3].cast<std::string>(), spec[4].cast<double>())));
  if (kind != "function") throw InputError("density", "unknown density kind '" + kind + "'");
  const int order = read_quadrature_order(spec[2], "density.quadrature_order");
  const PythonFunction<Point> function(spec[1], dimension, std::move(coordinates));
  if (region_pieces.empty())
    return run(BatchedFunctionDensity<FunctionDensity<Point>, Point>(
        FunctionDensity<Point>{active_field_value<Point>, order}, function));
  std::vector<DensityPiece<Point>> pieces;
  for (const auto& polygon : region_pieces) pieces.push_back({polygon, PieceKind::field, {}});
  return run(BatchedFunctionDensity<PiecewiseDensity<G>, Point>(
      PiecewiseDensity<G>(geometry, pieces, active_field_value<Point>, order, "domain"), function));
}

// ---- solve and result ----------------------------------------------------------------------

/// One set of coordinates in which points are returned: `centroids<suffix>`,
/// `cell_vertices<suffix>` (plane xy; sphere xyz; H² "" = hyperboloid, "_poincare" = disk).
template <class Point>
struct CoordinateView {
  std::string suffix;
  int dimension = 0;
  std::function<void(const Point&, double*)> write;
};

template <class Point>
py::array_t<double> points_array(const std::vector<const Point*>& points, const CoordinateView<Point>& view) {
  py::array_t<double> array({static_cast<py::ssize_t>(points.size()), static_cast<py::ssize_t>(view.dimension)});
  double* out = array.mutable_data();
  for (std::size_t i = 0; i < points.size(); ++i)
    view.write(*points[i], out + i * static_cast<std::size_t>(view.dimension));
  return array;
}

template <class Point>
py::array_t<double> points_array(const std::vector<Point>& points, const CoordinateView<Point>& view) {
  std::vector<const Point*> pointers;
  pointers.reserve(points.size());
  for (const auto& p : points) pointers.push_back(&p);
  return points_array(pointers, view);
}

py::array_t<double> vector_array(const Eigen::VectorXd& v);

/// The fields of a Result: weights, masses, target_masses, centroids*, transport_cost, status,
/// message, iterations, errors, mass_scale, source_mass, timings, history, and the cells as one
/// array of vertices (`cell_vertices*`, cell i's are rows cell_offsets[i]:cell_offsets[i+1]) with
/// the neighbour across each edge (`cell_neighbors`, negative on the domain's boundary).
template <class Point>
py::dict pack_result(const Result<Point>& result, const std::vector<CoordinateView<Point>>& views) {
  py::dict out;
  const Summary& s = result.summary;
  out["weights"] = vector_array(result.weights);
  out["masses"] = vector_array(result.masses);
  out["target_masses"] = vector_array(result.target_masses);
  out["transport_cost"] = result.transport_cost;
  out["status"] = std::string(to_string(s.status));
  out["message"] = s.message;
  out["iterations"] = s.iterations;
  out["max_relative_error"] = s.max_relative_error;
  out["rms_relative_error"] = s.rms_relative_error;
  out["mass_scale"] = s.mass_scale;
  out["source_mass"] = s.source_mass;
  py::dict timings;
  timings["diagram_s"] = s.timings.diagram_s;
  timings["assembly_s"] = s.timings.assembly_s;
  timings["linear_solve_s"] = s.timings.linear_solve_s;
  timings["total_s"] = s.timings.total_s;
  out["timings"] = timings;
  py::list history;
  for (const auto& r : s.history) {
    py::dict record;
    record["iteration"] = r.iteration;
    record["max_relative_error"] = r.max_relative_error;
    record["rms_relative_error"] = r.rms_relative_error;
    record["step"] = r.step;
    record["elapsed_s"] = r.elapsed_s;
    history.append(record);
  }
  out["history"] = history;
  const auto& cells = result.diagram.cells;
  py::array_t<std::int64_t> offsets(static_cast<py::ssize_t>(cells.size() + 1));
  std::int64_t* offset = offsets.mutable_data();
  offset[0] = 0;
  for (std::size_t i = 0; i < cells.size(); ++i)
    offset[i + 1] = offset[i] + static_cast<std::int64_t>(cells[i].empty() ? 0 : cells[i].size());
  py::array_t<std::int64_t> neighbors(static_cast<py::ssize_t>(offset[cells.size()]));
  std::vector<const Point*> vertices, centroids;
  vertices.reserve(static_cast<std::size_t>(offset[cells.size()]));
  for (std::size_t i = 0; i < cells.size(); ++i) {
    if (cells[i].empty()) continue;
    for (std::size_t k = 0; k < cells[i].size(); ++k) {
      neighbors.mutable_data()[vertices.size()] = cells[i].neighbors[k];
      vertices.push_back(&cells[i].vertices[k]);
    }
  }
  for (const auto& c : result.centroids) centroids.push_back(&c);
  for (const auto& view : views) {
    out[("centroids" + view.suffix).c_str()] = points_array(centroids, view);
    out[("cell_vertices" + view.suffix).c_str()] = points_array(vertices, view);
  }
  if (result.ball_radii.size() > 0) out["ball_radii"] = vector_array(result.ball_radii);
  out["cell_offsets"] = offsets;
  out["cell_neighbors"] = neighbors;
  return out;
}

/// Solves with the request's masses, weights and options, the GIL released, and packs the result.
template <class G, class D>
py::dict solve_and_pack(const G& geometry, const D& density, std::span<const typename G::Point> sites,
                        SolveRequest& request, const std::vector<CoordinateView<typename G::Point>>& views) {
  const std::size_t n = sites.size();
  Options options = request.options;
  std::optional<Eigen::VectorXd> masses = read_vector(request.masses, "masses", n);
  if (!masses) {
    masses = equal_masses(n);
    options.rescale_masses = true;  // equal masses summing to the source mass
  }
  const std::optional<Eigen::VectorXd> weights = read_vector(request.weights, "weights", n);
  std::optional<Result<typename G::Point>> result;
  {
    py::gil_scoped_release release;
    result = solve(geometry, density, sites, *masses, options, weights);
  }
  return pack_result(*result, views);
}

}  // namespace sdot::python
