#pragma once
// The Python module's geometry registry: each geometry folder's python/ adapter registers how to
// solve a problem given as numpy arrays and how to make the benchmark problem of `sdot bench`.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "sdot/options.hpp"

namespace sdot::python {

namespace py = pybind11;

/// One call of `sdot.solve`, after the pure-Python layer has checked shapes and dtypes: every
/// array is float64 (int32 for triangles), C-contiguous and finite-checked by the library.
struct SolveRequest {
  py::array_t<double> sites;  ///< (n, d)
  py::object masses;          ///< None or (n,)
  py::object weights;         ///< None or (n,)
  py::object domain;          ///< None or the geometry's domain description
  py::object density;         ///< None, ("image", values, extent, interpolation, scale),
                              ///< ("mesh", vertices, triangles, values, per_triangle, order) or
                              ///< ("function", callable, order)
  py::dict extra;             ///< geometry-specific keywords (model, builder)
  Options options;
};

struct GeometryBindings {
  /// Solves; returns the result's fields as a dict (see pack_result in bindings.hpp).
  std::function<py::dict(SolveRequest& request)> solve;
  /// The problem that `sdot bench --geometry NAME --n N --seed S` solves, as keyword arguments
  /// of `sdot.solve` (sites, masses, domain and geometry keywords).
  std::function<py::dict(std::size_t n, unsigned seed)> bench_problem;
};

class Registry {
 public:
  void add(const std::string& name, GeometryBindings bindings) { bindings_[name] = std::move(bindings); }
  [[nodiscard]] const GeometryBindings* find(const std::string& name) const {
    auto it = bindings_.find(name);
    return it == bindings_.end() ? nullptr : &it->second;
  }
  [[nodiscard]] std::vector<std::string> names() const {
    std::vector<std::string> result;
    for (const auto& [name, bindings] : bindings_) result.push_back(name);
    return result;
  }

 private:
  std::map<std::string, GeometryBindings> bindings_;
};

/// Defined in the generated python_registered_geometries.cpp: calls every geometry's register_NAME.
void register_geometries(Registry& registry);

}  // namespace sdot::python
