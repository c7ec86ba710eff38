#include "sdot/geometries/sphere_densities.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "sdot/error.hpp"

namespace sdot {

Sphere::Point from_longitude_latitude(double longitude, double latitude) {
  return {std::cos(latitude) * std::cos(longitude), std::cos(latitude) * std::sin(longitude), std::sin(latitude)};
}

PiecewiseDensity<Sphere> equirectangular_density(const Sphere& sphere, const GrayImage& image,
                                                 ImageInterpolation interpolation, double scale,
                                                 const std::string& field) {
  using Point = Sphere::Point;
  constexpr double pi = std::numbers::pi;
  if (image.width < 1 || image.height < 1 ||
      image.values.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height))
    throw InputError(field, "the image is empty or its size does not match its values");
  if (image.width < 3)
    throw InputError(field,
                     "an equirectangular image needs at least 3 columns (a pixel must span less than 180°), got " +
                         std::to_string(image.width));
  if (!(std::isfinite(scale) && scale > 0)) throw InputError(field + ".scale", "must be a positive number");
  const double dlon = 2 * pi / image.width, dlat = pi / image.height;
  std::vector<DensityPiece<Point>> pieces;
  auto quad = [](double lon0, double lat0, double lon1, double lat1) {
    return std::vector<Point>{from_longitude_latitude(lon0, lat0), from_longitude_latitude(lon1, lat0),
                              from_longitude_latitude(lon1, lat1), from_longitude_latitude(lon0, lat1)};
  };
  if (interpolation == ImageInterpolation::constant) {
    for (int row = 0; row < image.height; ++row)
      for (int column = 0; column < image.width; ++column) {
        const double value = image.at(row, column) * scale;
        if (value <= 0) continue;
        const double lon0 = -pi + column * dlon, lat0 = pi / 2 - row * dlat;
        pieces.push_back({quad(lon0, lat0, lon0 + dlon, lat0 - dlat), PieceKind::constant, {value, 0, 0}});
      }
    return PiecewiseDensity<Sphere>(sphere, pieces, {}, 3, field + ".pixels");
  }
  if (interpolation != ImageInterpolation::linear)
    throw InputError(field + ".interpolation", "the sphere accepts \"constant\" or \"linear\" image interpolation");
  // Linear: vertices at the pixel centres and the poles; triangles between them.
  std::vector<Point> vertices;
  std::vector<double> values;
  for (int r = 0; r < image.height; ++r)
    for (int c = 0; c < image.width; ++c) {
      vertices.push_back(from_longitude_latitude(-pi + (c + 0.5) * dlon, pi / 2 - (r + 0.5) * dlat));
      values.push_back(image.at(r, c) * scale);
    }
  auto node = [&](int r, int c) { return r * image.width + (c % image.width); };
  const int north = static_cast<int>(vertices.size()), south = north + 1;
  double north_value = 0, south_value = 0;
  for (int c = 0; c < image.width; ++c)
    north_value += image.at(0, c) * scale, south_value += image.at(image.height - 1, c) * scale;
  vertices.push_back(Point::UnitZ());
  values.push_back(north_value / image.width);
  vertices.push_back(-Point::UnitZ());
  values.push_back(south_value / image.width);
  std::vector<std::array<int, 3>> triangles;
  auto add = [&](int a, int b, int c) {
    const auto at = [&](int v) { return values[static_cast<std::size_t>(v)]; };
    if (at(a) > 0 || at(b) > 0 || at(c) > 0) triangles.push_back({a, b, c});  // ρ = 0 on the others
  };
  for (int c = 0; c < image.width; ++c) {
    add(north, node(0, c), node(0, c + 1));
    add(south, node(image.height - 1, c + 1), node(image.height - 1, c));
    for (int r = 0; r + 1 < image.height; ++r) {
      add(node(r, c), node(r + 1, c), node(r + 1, c + 1));
      add(node(r, c), node(r + 1, c + 1), node(r, c + 1));
    }
  }
  return mesh_density(sphere, std::span<const Point>(vertices), std::span<const std::array<int, 3>>(triangles),
                      std::span<const double>(values), 3, field + ".pixels");
}

}  // namespace sdot
