// The Python package's adapter for the sphere: sites (n, 3), whole-sphere, cap and polygon
// domains, longitude–latitude image densities, the benchmark problem.
#include <numbers>

#include "bindings.hpp"
#include "sdot/geometries/sphere.hpp"
#include "sdot/geometries/sphere_densities.hpp"

namespace sdot::python {
namespace {

using Point = Sphere::Point;

std::vector<Point> directions(const py::handle& value, const std::string& field) {
  return read_points<Point>(value.cast<py::array_t<double>>(), field, 3, [&](const double* row, std::size_t i) {
    const Point p(row[0], row[1], row[2]);
    if (!(p.norm() > 0)) throw InputError(indexed(field, i), "is the zero vector");
    return Point(p.normalized());
  });
}

/// Unit vectors as they are.
CoordinateView<Point> coordinates() {
  return {"", 3, [](const Point& p, double* out) { out[0] = p.x(), out[1] = p.y(), out[2] = p.z(); }};
}

/// None (the whole sphere), ("cap", center, angle) or ("polygon", vertices).
Sphere read_domain(const py::object& domain) {
  if (domain.is_none()) return Sphere();
  const auto spec = domain.cast<py::tuple>();
  const auto type = spec[0].cast<std::string>();
  if (type == "cap") {
    const auto center = spec[1].cast<std::vector<double>>();
    if (center.size() != 3) throw InputError("domain.center", "must be 3 numbers");
    return Sphere::cap(Point(center[0], center[1], center[2]), spec[2].cast<double>());
  }
  return Sphere::polygon(directions(spec[1], "domain"));
}

py::dict solve_sphere(SolveRequest& request) {
  std::vector<Point> storage;
  const auto sites = view_points<Point>(request.sites, "sites", storage);
  Sphere sphere = read_domain(request.domain);
  if (request.extra.contains("builder"))
    sphere.set_builder(Sphere::builder_from_name(request.extra["builder"].cast<std::string>()));
  const std::vector<CoordinateView<Point>> views = {coordinates()};
  return with_density(
      sphere, request,
      [](const py::array_t<double>& array, const std::string& field) { return directions(array, field); },
      [&](const GrayImage& image, const py::handle& extent, const std::string& interpolation, double scale) {
        if (!extent.is_none())
          throw InputError("extent", "the sphere's image is a longitude-latitude map of the whole sphere");
        if (!interpolation.empty() && interpolation != "linear" && interpolation != "constant")
          throw InputError("interpolation",
                           "must be \"linear\" or \"constant\" on the sphere, got \"" + interpolation + "\"");
        return equirectangular_density(
            sphere, image, interpolation == "constant" ? ImageInterpolation::constant : ImageInterpolation::linear,
            scale);
      },
      {}, 3, views[0].write,
      [&](const auto& density) { return solve_and_pack(sphere, density, sites, request, views); });
}

py::dict bench_sphere(std::size_t n, unsigned seed) {
  const auto sites = Sphere::uniform_samples(n, seed);
  py::dict problem;
  problem["sites"] = points_array(sites, coordinates());
  problem["geometry"] = "sphere";
  return problem;
}

}  // namespace

void register_sphere(Registry& registry) {
  registry.add("sphere", {solve_sphere, bench_sphere});
}

}  // namespace sdot::python
