// The Python package's adapter for the hyperbolic plane: sites, domain and density meshes in
// one model (keyword `model`: "poincare", "klein" or "hyperboloid"), results in the hyperboloid
// and the Poincaré disk, the benchmark problem.
#include "bindings.hpp"
#include "sdot/geometries/hyperbolic.hpp"

namespace sdot::python {
namespace {

using Point = Hyperbolic::Point;
using Model = Hyperbolic::Model;

Model read_model(const SolveRequest& request) {
  if (!request.extra.contains("model")) return Model::poincare;
  const auto name = request.extra["model"].cast<std::string>();
  if (name == "poincare") return Model::poincare;
  if (name == "klein") return Model::klein;
  if (name == "hyperboloid") return Model::hyperboloid;
  throw InputError("model", "must be \"poincare\", \"klein\" or \"hyperboloid\", got \"" + name + "\"");
}

int dimension(Model model) {
  return model == Model::hyperboloid ? 3 : 2;
}

std::vector<Point> points_in(Model model, const py::handle& value, const std::string& field) {
  const int d = dimension(model);
  return read_points<Point>(value.cast<py::array_t<double>>(), field, d, [&](const double* row, std::size_t i) {
    return Hyperbolic::from_model(model, Eigen::Map<const Eigen::VectorXd>(row, d), indexed(field, i));
  });
}

void write_in(Model model, const Point& x, double* out) {
  if (model == Model::hyperboloid) {
    out[0] = x.x(), out[1] = x.y(), out[2] = x.z();
    return;
  }
  const Eigen::Vector2d p = model == Model::klein ? Hyperbolic::to_klein(x) : Hyperbolic::to_poincare(x);
  out[0] = p.x(), out[1] = p.y();
}

py::dict solve_hyperbolic(SolveRequest& request) {
  const Model model = read_model(request);
  if (request.domain.is_none())
    throw InputError("domain", "missing: the hyperbolic plane needs a compact source domain (a convex polygon)");
  const auto domain_spec = request.domain.cast<py::tuple>();
  if (domain_spec[0].cast<std::string>() != "polygon")
    throw InputError("domain", "must be a convex polygon: an array of vertices in the model's coordinates");
  const auto domain_array = domain_spec[1].cast<py::array_t<double>>();
  const double* rows = checked_rows(domain_array, "domain", dimension(model));
  std::vector<Eigen::VectorXd> vertices;
  for (py::ssize_t i = 0; i < domain_array.shape(0); ++i)
    vertices.push_back(Eigen::Map<const Eigen::VectorXd>(rows + i * dimension(model), dimension(model)));
  const Hyperbolic geometry = Hyperbolic::from_model(model, vertices);
  const auto sites = points_in(model, request.sites, "sites");
  const std::vector<CoordinateView<Point>> views = {
      {"", 3, [](const Point& x, double* out) { write_in(Model::hyperboloid, x, out); }},
      {"_poincare", 2, [](const Point& x, double* out) { write_in(Model::poincare, x, out); }}};
  return with_density(
      geometry, request,
      [&](const py::array_t<double>& array, const std::string& field) { return points_in(model, array, field); },
      [](const GrayImage&, const py::handle&, const std::string&, double) -> PiecewiseDensity<Hyperbolic> {
        throw InputError("density", "image densities are available on the plane and the sphere; use a mesh");
      },
      {}, dimension(model), [model](const Point& x, double* out) { write_in(model, x, out); },
      [&](const auto& density) {
        return solve_and_pack(geometry, density, std::span<const Point>(sites), request, views);
      });
}

/// The benchmark domain of `sdot bench`: the regular octagon of circumradius 1.5 centred at
/// distance 2 from the origin; sites uniform in hyperbolic area.
py::dict bench_hyperbolic(std::size_t n, unsigned seed) {
  const auto octagon = Hyperbolic::regular_polygon(8, 1.5, Hyperbolic::polar(2, 0)).domain();
  const std::vector<Eigen::VectorXd> vertices(octagon.begin(), octagon.end());
  const Hyperbolic geometry = Hyperbolic::from_model(Model::hyperboloid, vertices);
  const auto sites = geometry.uniform_samples(n, seed);
  const CoordinateView<Point> hyperboloid{"", 3,
                                          [](const Point& x, double* out) { write_in(Model::hyperboloid, x, out); }};
  py::dict problem;
  problem["sites"] = points_array(sites, hyperboloid);
  problem["domain"] = points_array(geometry.domain(), hyperboloid);
  problem["model"] = "hyperboloid";
  problem["geometry"] = "hyperbolic";
  return problem;
}

}  // namespace

void register_hyperbolic(Registry& registry) {
  registry.add("hyperbolic", {solve_hyperbolic, bench_hyperbolic});
}

}  // namespace sdot::python
