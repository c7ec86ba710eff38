#include "bindings.hpp"

namespace sdot::python {

std::string shape_string(const py::array& array) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < array.ndim(); ++d) s += (d ? ", " : "") + std::to_string(array.shape(d));
  return s + (array.ndim() == 1 ? ",)" : ")");
}

const double* checked_rows(const py::array_t<double>& array, const std::string& field, int dimension) {
  if (array.ndim() != 2 || array.shape(1) != dimension)
    throw InputError(
        field, "must be an array of shape (n, " + std::to_string(dimension) + "), got shape " + shape_string(array));
  if (!(array.flags() & py::array::c_style)) throw InputError(field, "must be C-contiguous");
  return array.data();
}

std::optional<Eigen::VectorXd> read_vector(const py::object& value, const std::string& field, std::size_t count) {
  if (value.is_none()) return std::nullopt;
  const auto array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
  if (!array || array.ndim() != 1)
    throw InputError(field, "must be a 1-D array of " + std::to_string(count) + " numbers");
  if (static_cast<std::size_t>(array.shape(0)) != count)
    throw InputError(field, "there are " + std::to_string(array.shape(0)) + " values for " + std::to_string(count) +
                                " " + (field.find("triangle") != std::string::npos ? "triangles" : "sites"));
  Eigen::VectorXd v(static_cast<Eigen::Index>(count));
  for (std::size_t i = 0; i < count; ++i) {
    v[static_cast<Eigen::Index>(i)] = array.data()[i];
    if (!std::isfinite(v[static_cast<Eigen::Index>(i)])) throw InputError(indexed(field, i), "is not finite");
  }
  return v;
}

std::vector<std::array<int, 3>> read_triangles(const py::object& value, const std::string& field) {
  const auto array = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(value);
  if (!array || array.ndim() != 2 || array.shape(1) != 3)
    throw InputError(field, "must be an integer array of shape (m, 3)");
  std::vector<std::array<int, 3>> triangles(static_cast<std::size_t>(array.shape(0)));
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      const std::int64_t index = array.data()[3 * t + static_cast<std::size_t>(k)];
      if (index < 0 || index > std::numeric_limits<int>::max())
        throw InputError(indexed(field, t), "vertex index " + std::to_string(index) + " is out of range");
      triangles[t][static_cast<std::size_t>(k)] = static_cast<int>(index);
    }
  return triangles;
}

GrayImage read_image_array(const py::object& value, const std::string& field) {
  const auto array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
  if (!array || array.ndim() != 2 || array.shape(0) < 1 || array.shape(1) < 1)
    throw InputError(field, "an image must be a non-empty 2-D array (rows, columns)");
  GrayImage image{static_cast<int>(array.shape(1)), static_cast<int>(array.shape(0)), {}};
  image.values.assign(array.data(), array.data() + array.size());
  for (std::size_t i = 0; i < image.values.size(); ++i)
    if (!(std::isfinite(image.values[i]) && image.values[i] >= 0))
      throw InputError(field + "[" + std::to_string(i / static_cast<std::size_t>(image.width)) + ", " +
                           std::to_string(i % static_cast<std::size_t>(image.width)) + "]",
                       "must be finite and >= 0, got " + std::to_string(image.values[i]));
  return image;
}

int read_quadrature_order(const py::object& value, const std::string& field) {
  const int order = value.cast<int>();
  if (order < 1 || order > 64) throw InputError(field, "must be an integer in 1..64, got " + std::to_string(order));
  return order;
}

py::array_t<double> vector_array(const Eigen::VectorXd& v) {
  py::array_t<double> array(v.size());
  std::copy(v.data(), v.data() + v.size(), array.mutable_data());
  return array;
}

}  // namespace sdot::python
