#include "sdot/geometries/plane_densities.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

#include "sdot/error.hpp"

namespace sdot {

namespace {
/// Bilinear interpolation of pixel-centre values at fractional pixel coordinates (u along a row,
/// v down the columns), clamped to the outer pixel centres.
double bilinear(const GrayImage& image, double u, double v) {
  u = std::clamp(u, 0.0, static_cast<double>(image.width - 1));
  v = std::clamp(v, 0.0, static_cast<double>(image.height - 1));
  const int i = std::min(static_cast<int>(u), std::max(image.width - 2, 0));
  const int j = std::min(static_cast<int>(v), std::max(image.height - 2, 0));
  const double s = u - i, t = v - j;
  const int i1 = std::min(i + 1, image.width - 1), j1 = std::min(j + 1, image.height - 1);
  return (1 - t) * ((1 - s) * image.at(j, i) + s * image.at(j, i1)) +
         t * ((1 - s) * image.at(j1, i) + s * image.at(j1, i1));
}
}  // namespace

PiecewiseDensity<Plane> image_density(const Plane& plane, const GrayImage& image, const Eigen::AlignedBox2d& rectangle,
                                      ImageInterpolation interpolation, double scale, const std::string& field) {
  if (image.width < 1 || image.height < 1 ||
      image.values.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height))
    throw InputError(field, "the image is empty or its size does not match its values");
  const Eigen::Vector2d low = rectangle.min(), high = rectangle.max();
  if (!(low.allFinite() && high.allFinite() && high.x() > low.x() && high.y() > low.y()))
    throw InputError(field + ".rectangle", "must be [x0, y0, x1, y1] with x0 < x1 and y0 < y1");
  if (!(std::isfinite(scale) && scale > 0)) throw InputError(field + ".scale", "must be a positive number");
  const double dx = (high.x() - low.x()) / image.width, dy = (high.y() - low.y()) / image.height;
  using Point = Plane::Point;
  std::vector<DensityPiece<Point>> pieces;
  auto rectangle_piece = [](double x0, double y0, double x1, double y1) {
    return std::vector<Point>{{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  };
  if (interpolation == ImageInterpolation::constant) {
    for (int row = 0; row < image.height; ++row)
      for (int column = 0; column < image.width; ++column) {
        const double value = image.at(row, column) * scale;
        if (value <= 0) continue;
        const double x0 = low.x() + column * dx, y1 = high.y() - row * dy;
        pieces.push_back({rectangle_piece(x0, y1 - dy, x0 + dx, y1), PieceKind::constant, {value, 0, 0}});
      }
    return PiecewiseDensity<Plane>(plane, pieces, {}, 3, field + ".pixels");
  }
  // Bilinear: pieces between consecutive breaks {edge, pixel centres…, edge} in x and y.
  std::vector<double> xs{low.x()}, ys{high.y()};
  for (int c = 0; c < image.width; ++c) xs.push_back(low.x() + (c + 0.5) * dx);
  xs.push_back(high.x());
  for (int r = 0; r < image.height; ++r) ys.push_back(high.y() - (r + 0.5) * dy);
  ys.push_back(low.y());
  for (std::size_t r = 0; r + 1 < ys.size(); ++r)
    for (std::size_t c = 0; c + 1 < xs.size(); ++c) {
      // The piece's corner values (pixel centres around it, clamped): all zero means ρ = 0 on it.
      const int c0 = std::max(static_cast<int>(c) - 1, 0), c1 = std::min(static_cast<int>(c), image.width - 1);
      const int r0 = std::max(static_cast<int>(r) - 1, 0), r1 = std::min(static_cast<int>(r), image.height - 1);
      if (image.at(r0, c0) <= 0 && image.at(r0, c1) <= 0 && image.at(r1, c0) <= 0 && image.at(r1, c1) <= 0) continue;
      if (xs[c + 1] <= xs[c] || ys[r] <= ys[r + 1]) continue;
      pieces.push_back({rectangle_piece(xs[c], ys[r + 1], xs[c + 1], ys[r]), PieceKind::field, {}});
    }
  auto shared = std::make_shared<GrayImage>(image);
  ScalarField<Point> rho = [shared, low, high, dx, dy, scale](const Point& x) {
    return scale * bilinear(*shared, (x.x() - low.x()) / dx - 0.5, (high.y() - x.y()) / dy - 0.5);
  };
  return PiecewiseDensity<Plane>(plane, pieces, std::move(rho), 3, field + ".pixels");
}

PiecewiseDensity<Plane> region_density(const Plane& plane, const PlaneRegion& region) {
  std::vector<DensityPiece<Plane::Point>> pieces;
  for (const auto& polygon : region.convex_pieces()) pieces.push_back({polygon, PieceKind::constant, {1, 0, 0}});
  return PiecewiseDensity<Plane>(plane, pieces, {}, 3, "domain.pieces");
}

}  // namespace sdot
