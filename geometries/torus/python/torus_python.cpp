// The Python package's adapter for the periodic plane: sites (n, 2), a box domain with periodic
// axes (sdot.solve(..., geometry="plane", periodic=...) arrives here), densities given on the box
// (images, meshes, functions), the benchmark problem.
#include <type_traits>
#include <utility>

#include "bindings.hpp"
#include "sdot/geometries/plane_densities.hpp"
#include "sdot/geometries/torus.hpp"
#include "sdot/geometries/torus_densities.hpp"

namespace sdot::python {
namespace {

using Point = Torus::Point;

CoordinateView<Point> coordinates() {
  return {"", 2, [](const Point& p, double* out) { out[0] = p.x(), out[1] = p.y(); }};
}

/// The domain: None (the unit square) or ("box", x0, y0, x1, y1); the periodic axes:
/// extra["periodic"] = (x, y), both by default. The pure-Python layer has checked the types.
Torus read_torus(const SolveRequest& request) {
  Eigen::AlignedBox2d box(Point(0, 0), Point(1, 1));
  if (!request.domain.is_none()) {
    const auto spec = request.domain.cast<py::tuple>();
    box = Eigen::AlignedBox2d(Point(spec[1].cast<double>(), spec[2].cast<double>()),
                              Point(spec[3].cast<double>(), spec[4].cast<double>()));
  }
  std::array<bool, 2> periodic{true, true};
  if (request.extra.contains("periodic")) {
    const auto axes = request.extra["periodic"].cast<py::tuple>();
    periodic = {axes[0].cast<bool>(), axes[1].cast<bool>()};
  }
  return Torus(box, periodic);
}

py::dict solve_torus(SolveRequest& request) {
  std::vector<Point> storage;
  const auto sites = view_points<Point>(request.sites, "sites", storage);
  const Torus torus = read_torus(request);
  const std::vector<CoordinateView<Point>> views = {coordinates()};
  const Plane& plane = torus.plane();
  static const std::vector<std::vector<Point>> no_region;
  py::dict result = with_density(
      plane, request,
      [](const py::array_t<double>& array, const std::string& field) {
        return read_points<Point>(array, field, 2,
                                  [](const double* row, std::size_t) { return Point(row[0], row[1]); });
      },
      [&](const GrayImage& image, const py::handle& extent, const std::string& interpolation, double scale) {
        Eigen::AlignedBox2d rectangle = torus.box();
        if (!extent.is_none()) {
          const auto e = extent.cast<std::vector<double>>();
          if (e.size() != 4) throw InputError("extent", "must be (x0, y0, x1, y1)");
          rectangle = Eigen::AlignedBox2d(Point(e[0], e[1]), Point(e[2], e[3]));
        }
        if (!interpolation.empty() && interpolation != "bilinear" && interpolation != "constant")
          throw InputError("interpolation",
                           "must be \"bilinear\" or \"constant\" on the plane, got \"" + interpolation + "\"");
        return image_density(plane, image, rectangle,
                             interpolation == "constant" ? ImageInterpolation::constant : ImageInterpolation::bilinear,
                             scale);
      },
      no_region, 2, views[0].write,
      [&](auto&& density) {
        using D = std::decay_t<decltype(density)>;
        // A density of the box (image, mesh, function) is repeated with the periods.
        if constexpr (std::is_same_v<D, UniformDensity>)
          return solve_and_pack(torus, density, sites, request, views);
        else
          return solve_and_pack(torus, PeriodicDensity<D>(std::forward<decltype(density)>(density)), sites, request,
                                views);
      });
  const Eigen::AlignedBox2d& box = torus.box();
  result["box"] = py::make_tuple(box.min().x(), box.min().y(), box.max().x(), box.max().y());
  result["periodic"] = py::make_tuple(torus.periodic()[0], torus.periodic()[1]);
  return result;
}

py::dict bench_torus(std::size_t n, unsigned seed) {
  // The plane's benchmark sites, on the unit square periodic in x and y.
  const auto sites = Torus().uniform_samples(n, seed);
  py::dict problem;
  problem["sites"] = points_array(sites, coordinates());
  problem["geometry"] = "torus";
  return problem;
}

}  // namespace

void register_torus(Registry& registry) {
  registry.add("torus", {solve_torus, bench_torus});
}

}  // namespace sdot::python
