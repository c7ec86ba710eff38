// sdot._sdot: the compiled part of the Python package. The pure-Python layer (python/sdot)
// checks and converts arguments and wraps results; everything numeric happens here.
#include <pybind11/stl.h>

#include <chrono>
#include <cmath>
#include <cstdio>

#include "bindings.hpp"
#include "mesh.hpp"
#include "run.hpp"
#include "sdot/resources.hpp"

namespace py = pybind11;
using namespace sdot::python;

namespace {

const Registry& registry() {
  static const Registry instance = [] {
    Registry r;
    register_geometries(r);
    return r;
  }();
  return instance;
}

const GeometryBindings& find_geometry(const std::string& name) {
  if (const auto* bindings = registry().find(name)) return *bindings;
  std::string list;
  for (const auto& n : registry().names()) list += (list.empty() ? "\"" : ", \"") + n + "\"";
  throw sdot::InputError("geometry", "must be one of " + list + ", got \"" + name + "\"");
}

py::dict solve(const std::string& geometry, py::array_t<double> sites, py::object masses, py::object weights,
               py::object domain, py::object density, py::dict extra, double tolerance, int max_iterations,
               const std::string& linear_solver, bool rescale_masses, bool partial, py::object callback) {
  const GeometryBindings& bindings = find_geometry(geometry);
  SolveRequest request{std::move(sites),
                       std::move(masses),
                       std::move(weights),
                       std::move(domain),
                       std::move(density),
                       std::move(extra),
                       {}};
  sdot::Options& options = request.options;
  options.tolerance = tolerance;
  options.max_iterations = max_iterations;
  options.linear_solver = sdot::linear_solver_from_name(linear_solver);
  options.rescale_masses = rescale_masses;
  options.partial = partial;
  // After each Newton iteration, with the GIL: Ctrl-C (a pending KeyboardInterrupt) stops the
  // solve, and the callback sees the iteration. A borrowed handle: `callback` outlives the solve.
  const py::handle hook = callback;
  options.callback = [hook](const sdot::IterationRecord& r) {
    py::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    if (!hook.is_none()) hook(r.iteration, r.max_relative_error, r.rms_relative_error, r.step, r.elapsed_s);
  };
  options.validate();
  return bindings.solve(request);
}

py::array_t<double> vertices_array(const std::vector<sphparam::Vec3>& vertices) {
  py::array_t<double> array({static_cast<py::ssize_t>(vertices.size()), py::ssize_t{3}});
  for (std::size_t i = 0; i < vertices.size(); ++i)
    for (int d = 0; d < 3; ++d) array.mutable_data()[3 * i + static_cast<std::size_t>(d)] = vertices[i][d];
  return array;
}

py::array_t<std::int64_t> faces_array(const std::vector<sphparam::Face>& faces) {
  py::array_t<std::int64_t> array({static_cast<py::ssize_t>(faces.size()), py::ssize_t{3}});
  for (std::size_t t = 0; t < faces.size(); ++t)
    for (std::size_t k = 0; k < 3; ++k) array.mutable_data()[3 * t + k] = faces[t][k];
  return array;
}

/// A mesh from (n, 3) float64 vertices and (m, 3) int64 faces (checked by the Python layer for
/// shape and dtype; indices and values here).
sphparam::Mesh read_mesh_arrays(const py::array_t<double>& vertices, const py::array_t<std::int64_t>& faces) {
  sphparam::Mesh mesh;
  const double* v = checked_rows(vertices, "vertices", 3);
  for (py::ssize_t i = 0; i < vertices.shape(0); ++i) {
    const sphparam::Vec3 p(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
    if (!p.allFinite()) throw sdot::InputError(sdot::indexed("vertices", static_cast<std::size_t>(i)), "is not finite");
    mesh.vertices.push_back(p);
  }
  if (faces.ndim() != 2 || faces.shape(1) != 3)
    throw sdot::InputError("faces", "must be an integer array of shape (m, 3), got shape " + shape_string(faces));
  for (py::ssize_t t = 0; t < faces.shape(0); ++t) {
    sphparam::Face f{};
    for (int k = 0; k < 3; ++k) {
      const std::int64_t index = faces.at(t, k);
      if (index < 0 || index >= vertices.shape(0))
        throw sdot::InputError(sdot::indexed("faces", static_cast<std::size_t>(t)),
                               "vertex index " + std::to_string(index) + " is out of range (there are " +
                                   std::to_string(vertices.shape(0)) + " vertices)");
      f[static_cast<std::size_t>(k)] = static_cast<int>(index);
    }
    mesh.faces.push_back(f);
  }
  return mesh;
}

py::tuple sphere_parameterization(const py::array_t<double>& vertices, const py::array_t<std::int64_t>& faces,
                                  const py::dict& options_dict, py::object vertex_factors, py::object progress) {
  const sphparam::Mesh mesh = read_mesh_arrays(vertices, faces);
  sphparam::PipelineOptions options;
  for (const auto& [key_handle, value] : options_dict) {
    const auto key = key_handle.cast<std::string>();
    if (key == "refine")
      options.refine = value.cast<int>();
    else if (key == "max_refine")
      options.max_refine = value.cast<int>();
    else if (key == "reweightings")
      options.max_reweightings = value.cast<int>();
    else if (key == "optimize")
      options.optimize = value.cast<bool>();
    else if (key == "separation_threshold")
      options.min_spacing = value.cast<double>();
    else if (key == "separation_delta")
      options.separation_delta = value.cast<double>();
    else if (key == "coarse_transport")
      options.coarse_transport_spacing = value.cast<double>();
    else if (key == "ot_tolerance")
      options.ot_tolerance = value.cast<double>();
    else if (key == "sweeps")
      options.optimizer.max_sweeps = value.cast<int>();
    else if (key == "angle_weight")
      options.optimizer.angle_weight = value.cast<double>();
    else
      throw sdot::InputError(key, "unknown option of sphere_parameterization");
  }
  if (!(options.ot_tolerance > 0)) throw sdot::InputError("ot_tolerance", "must be > 0");
  if (!(std::isfinite(options.optimizer.angle_weight) && options.optimizer.angle_weight >= 0))
    throw sdot::InputError("angle_weight", "must be a finite number >= 0");
  std::vector<double> factors;
  if (!vertex_factors.is_none()) {
    const Eigen::VectorXd values = *read_vector(vertex_factors, "target_weights", mesh.vertices.size());
    factors.assign(values.data(), values.data() + values.size());
    for (std::size_t i = 0; i < factors.size(); ++i)
      if (!(factors[i] > 0)) throw sdot::InputError(sdot::indexed("target_weights", i), "must be positive");
  }
  const py::handle hook = progress;
  if (!hook.is_none())
    options.progress = [hook](const std::string& line) {
      py::gil_scoped_acquire gil;
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      hook(line);
    };
  sphparam::ReadInfo info;
  info.format = "arrays";
  sphparam::RunResult result;
  {
    py::gil_scoped_release release;
    result = sphparam::run_parameterization(mesh, info, options, factors, true, "<arrays>");
  }
  if (result.status == "invalid_input") {
    std::string message = "not a valid closed genus-0 manifold triangle mesh:";
    for (const auto& e : result.errors) message += " " + e + ";";
    message.pop_back();
    throw sdot::InputError("mesh", message);
  }
  if (result.status == "failed") throw sdot::Error(result.errors.front());
  py::array_t<double> initial_d(static_cast<py::ssize_t>(result.initial.d.size()));
  py::array_t<double> final_d(static_cast<py::ssize_t>(result.final_map.d.size()));
  std::copy(result.initial.d.begin(), result.initial.d.end(), initial_d.mutable_data());
  std::copy(result.final_map.d.begin(), result.final_map.d.end(), final_d.mutable_data());
  // One row per input vertex: a vertex that no face uses (the report counts them) is projected
  // radially from the mesh's vertex centroid, so that the rows keep the input's numbering.
  std::vector<sphparam::Vec3> sphere(mesh.vertices.size(), sphparam::Vec3::Zero());
  std::vector<bool> mapped(mesh.vertices.size(), false);
  for (std::size_t i = 0; i < result.kept.size(); ++i) {
    sphere[static_cast<std::size_t>(result.kept[i])] = result.output.vertices[i];
    mapped[static_cast<std::size_t>(result.kept[i])] = true;
  }
  sphparam::Vec3 centroid = sphparam::Vec3::Zero();
  for (const auto& v : mesh.vertices) centroid += v / static_cast<double>(mesh.vertices.size());
  for (std::size_t i = 0; i < sphere.size(); ++i)
    if (!mapped[i]) {
      const sphparam::Vec3 d = mesh.vertices[i] - centroid;
      sphere[i] = d.norm() > 0 ? sphparam::Vec3(d.normalized()) : sphparam::Vec3::UnitZ();
    }
  return py::make_tuple(vertices_array(sphere), result.report.dump(), initial_d, final_d);
}

py::tuple read_mesh(const std::string& path, const std::string& format) {
  sphparam::ReadInfo info;
  const sphparam::Mesh mesh = sphparam::read_mesh(path, &info, format);
  py::dict details;
  details["format"] = info.format;
  details["polygons"] = info.polygons;
  details["polygon_triangles"] = info.polygon_triangles;
  details["short_faces"] = info.short_faces;
  return py::make_tuple(vertices_array(mesh.vertices), faces_array(mesh.faces), details);
}

void write_mesh(const std::string& path, const py::array_t<double>& vertices, const py::array_t<std::int64_t>& faces,
                bool ply_ascii, const std::string& format) {
  sphparam::write_mesh(path, read_mesh_arrays(vertices, faces), ply_ascii, format);
}

}  // namespace

PYBIND11_MODULE(_sdot, m) {
  m.doc() = "sdot's compiled core; use the functions of the sdot package";
  // One exception family in C++ (sdot::Error); in Python, bad input is a ValueError with the
  // library's message (which names the field and index), and a bad file too.
  py::register_exception_translator([](std::exception_ptr failure) {
    try {
      if (failure) std::rethrow_exception(failure);
    } catch (const sdot::InputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const sphparam::FileError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const sdot::Error& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
  });
  m.def("geometries", [] { return registry().names(); });
  m.def("solve", &solve, py::arg("geometry"), py::arg("sites"), py::arg("masses"), py::arg("weights"),
        py::arg("domain"), py::arg("density"), py::arg("extra"), py::arg("tolerance"), py::arg("max_iterations"),
        py::arg("linear_solver"), py::arg("rescale_masses"), py::arg("partial"), py::arg("callback"));
  m.def("bench_problem", [](const std::string& geometry, std::size_t n, unsigned seed) {
    return find_geometry(geometry).bench_problem(n, seed);
  });
  m.def("sphere_parameterization", &sphere_parameterization);
  m.def("read_mesh", &read_mesh);
  m.def("write_mesh", &write_mesh);
  m.def("mesh_format", &sphparam::mesh_format);  // the format a name says ("" when it says none)
  m.def("has_cholmod", &sdot::has_cholmod);
  m.def("peak_rss_mb", &sdot::peak_resident_memory_mb);
}
