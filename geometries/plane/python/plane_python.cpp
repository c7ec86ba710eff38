// The Python package's adapter for the plane: sites (n, 2), a convex or general polygon domain
// (with holes), image densities over a rectangle, the benchmark problem.
#include <Eigen/Geometry>

#include "bindings.hpp"
#include "sdot/geometries/plane.hpp"
#include "sdot/geometries/plane_densities.hpp"
#include "sdot/geometries/plane_region.hpp"

namespace sdot::python {
namespace {

using Point = Plane::Point;

std::vector<Point> ring(const py::handle& value, const std::string& field) {
  return read_points<Point>(value.cast<py::array_t<double>>(), field, 2,
                            [](const double* row, std::size_t) { return Point(row[0], row[1]); });
}

CoordinateView<Point> coordinates() {
  return {"", 2, [](const Point& p, double* out) { out[0] = p.x(), out[1] = p.y(); }};
}

/// The domain: None (unit square), ("polygon", vertices) or ("region", [(outer, [holes]), ...]).
/// A polygon that is convex becomes the plane's domain; any other polygon or region is handled
/// as the bounding box with the density restricted to the region (as the sdot command does).
struct PlaneDomain {
  Plane plane;
  std::optional<PlaneRegion> region;
};

PlaneDomain read_domain(const py::object& domain) {
  if (domain.is_none()) return {};
  const auto spec = domain.cast<py::tuple>();
  std::vector<PolygonWithHoles> polygons;
  if (spec[0].cast<std::string>() == "polygon") {
    auto vertices = ring(spec[1], "domain");
    try {
      return {Plane(ConvexPolygon(vertices, "domain")), std::nullopt};
    } catch (const InputError&) {  // not convex (or degenerate): the region's validation says which
      polygons.push_back({std::move(vertices), {}});
    }
  } else {
    const auto list = spec[1].cast<py::list>();
    for (std::size_t i = 0; i < list.size(); ++i) {
      const auto polygon = list[i].cast<py::tuple>();
      const std::string field = list.size() == 1 ? "domain" : indexed("domain", i);
      PolygonWithHoles p;
      p.outer = ring(polygon[0], field + ".outer");
      const auto holes = polygon[1].cast<py::list>();
      for (std::size_t h = 0; h < holes.size(); ++h) p.holes.push_back(ring(holes[h], indexed(field + ".holes", h)));
      polygons.push_back(std::move(p));
    }
  }
  PlaneRegion region(std::move(polygons), "domain");
  const Plane plane(
      ConvexPolygon::rectangle(region.lower().x(), region.lower().y(), region.upper().x(), region.upper().y()));
  return {plane, std::move(region)};
}

py::dict solve_plane(SolveRequest& request) {
  std::vector<Point> storage;
  const auto sites = view_points<Point>(request.sites, "sites", storage);
  const PlaneDomain domain = read_domain(request.domain);
  const Plane& plane = domain.plane;
  static const std::vector<std::vector<Point>> none;
  const auto& pieces = domain.region ? domain.region->convex_pieces() : none;
  const std::vector<CoordinateView<Point>> views = {coordinates()};
  return with_density(
      plane, request, [](const py::array_t<double>& array, const std::string& field) { return ring(array, field); },
      [&](const GrayImage& image, const py::handle& extent, const std::string& interpolation, double scale) {
        Eigen::AlignedBox2d rectangle;
        for (const auto& v : plane.domain().vertices()) rectangle.extend(v);
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
      pieces, 2, views[0].write,
      [&](const auto& density) { return solve_and_pack(plane, density, sites, request, views); });
}

py::dict bench_plane(std::size_t n, unsigned seed) {
  const auto sites = Plane().uniform_samples(n, seed);
  py::dict problem;
  problem["sites"] = points_array(sites, coordinates());
  problem["geometry"] = "plane";
  return problem;
}

}  // namespace

void register_plane(Registry& registry) {
  registry.add("plane", {solve_plane, bench_plane});
}

}  // namespace sdot::python
