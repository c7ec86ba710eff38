#include "pictures.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <sdot/error.hpp>
#include <sdot/output_file.hpp>
#include <sstream>

namespace blue_noise {

namespace {

constexpr double pi = std::numbers::pi;

double image_maximum(const sdot::GrayImage& image) {
  const double maximum = *std::max_element(image.values.begin(), image.values.end());
  return maximum > 0 ? maximum : 1;
}

/// Dot radius in picture units: small enough that dots stay apart where points are densest.
double dot_radius(double spacing, double units_per_radian) {
  return std::clamp(0.22 * spacing * units_per_radian, 0.8, 5.0);
}

/// Mollweide projection of (longitude, latitude) to x ∈ [−2√2, 2√2], y ∈ [−√2, √2] (y up).
std::pair<double, double> mollweide(double lon, double lat) {
  // Solve 2θ + sin 2θ = π sin φ by Newton's method (the derivative vanishes at the poles).
  double theta = lat;
  if (std::abs(lat) < pi / 2 - 1e-9) {
    for (int k = 0; k < 60; ++k) {
      const double f = 2 * theta + std::sin(2 * theta) - pi * std::sin(lat);
      const double derivative = 2 + 2 * std::cos(2 * theta);
      if (derivative < 1e-12) break;
      const double step = f / derivative;
      theta -= step;
      if (std::abs(step) < 1e-12) break;
    }
  }
  return {2 * std::numbers::sqrt2 / pi * lon * std::cos(theta), std::numbers::sqrt2 * std::sin(theta)};
}

}  // namespace

void write_png_picture(const std::string& path, const sdot::GrayImage& image, const std::vector<Point>& points,
                       double spacing, int width) {
  const int height = width / 2;
  sdot::GrayImage picture{width, height, std::vector<double>(std::size_t(width) * std::size_t(height))};
  const double maximum = image_maximum(image);
  // Background: the nearest image pixel, dimmed so that the dots stand out.
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const int row = std::min(image.height - 1, (y * image.height) / height);
      const int column = std::min(image.width - 1, (x * image.width) / width);
      picture.values[std::size_t(y) * std::size_t(width) + std::size_t(x)] = 1 - 0.45 * image.at(row, column) / maximum;
    }
  // Dots, antialiased by their coverage of each pixel; drawn again one width to the left and
  // right so that dots on the ±180° seam appear on both sides.
  const double pixels_per_radian = width / (2 * pi), radius = dot_radius(spacing, pixels_per_radian);
  for (const Point& point : points) {
    const double center_x = (longitude(point) + pi) * pixels_per_radian;
    const double center_y = (pi / 2 - latitude(point)) * pixels_per_radian;
    for (double shift : {-double(width), 0.0, double(width)}) {
      const double cx = center_x + shift;
      for (int y = int(std::floor(center_y - radius - 1)); y <= int(std::ceil(center_y + radius + 1)); ++y)
        for (int x = int(std::floor(cx - radius - 1)); x <= int(std::ceil(cx + radius + 1)); ++x) {
          if (x < 0 || x >= width || y < 0 || y >= height) continue;
          const double distance = std::hypot(x + 0.5 - cx, y + 0.5 - center_y);
          const double coverage = std::clamp(radius + 0.5 - distance, 0.0, 1.0);
          double& value = picture.values[std::size_t(y) * std::size_t(width) + std::size_t(x)];
          value *= 1 - coverage;
        }
    }
  }
  sdot::write_png(path, picture);
}

void write_svg_picture(const std::string& path, const sdot::GrayImage& image, const std::vector<Point>& points,
                       double spacing) {
  constexpr double scale = 500 / (2 * std::numbers::sqrt2);  // the map is 1000 × 500 units
  constexpr double margin = 10;
  auto to_svg = [&](double lon, double lat) {
    const auto [x, y] = mollweide(lon, lat);
    return std::pair{margin + 500 + scale * x, margin + 250 - scale * y};
  };
  std::ostringstream svg;
  svg.precision(6);
  svg << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << 1000 + 2 * margin << "\" height=\"" << 500 + 2 * margin
      << "\" viewBox=\"0 0 " << 1000 + 2 * margin << ' ' << 500 + 2 * margin << "\">\n";
  svg << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";

  // The density: the image averaged down to at most 360 × 180 cells and quantised to 16 levels;
  // each run of equal level in a row is one quadrilateral (parallels are horizontal lines and
  // x is linear in longitude along them).
  const int columns = std::min(image.width, 360), rows = std::min(image.height, 180);
  std::vector<double> cells(std::size_t(rows) * std::size_t(columns)), counts(cells.size());
  for (int row = 0; row < image.height; ++row)
    for (int column = 0; column < image.width; ++column) {
      const std::size_t cell =
          std::size_t(row * rows / image.height) * std::size_t(columns) + std::size_t(column * columns / image.width);
      cells[cell] += image.at(row, column), counts[cell] += 1;
    }
  const double maximum = image_maximum(image);
  auto level_of = [&](std::size_t cell) {
    const double value = cells[cell] / counts[cell] / maximum;
    return value > 0 ? std::max(1, int(std::lround(15 * value))) : 0;
  };
  svg << "<g stroke-width=\"0.6\">\n";
  for (int row = 0; row < rows; ++row) {
    const double top = pi / 2 - row * pi / rows, bottom = pi / 2 - (row + 1) * pi / rows;
    for (int begin = 0; begin < columns;) {
      const int level = level_of(std::size_t(row) * std::size_t(columns) + std::size_t(begin));
      int end = begin + 1;
      while (end < columns && level_of(std::size_t(row) * std::size_t(columns) + std::size_t(end)) == level) ++end;
      if (level > 0) {
        const double west = -pi + begin * 2 * pi / columns, east = -pi + end * 2 * pi / columns;
        char color[8];
        std::snprintf(color, sizeof color, "#%02x%02x%02x", 238 - 5 * level, 236 - 6 * level, 228 - 8 * level);
        svg << "<polygon fill=\"" << color << "\" stroke=\"" << color << "\" points=\"";
        for (const auto& [lon, lat] : {std::pair{west, top}, {east, top}, {east, bottom}, {west, bottom}}) {
          const auto [x, y] = to_svg(lon, lat);
          svg << x << ',' << y << ' ';
        }
        svg << "\"/>\n";
      }
      begin = end;
    }
  }
  svg << "</g>\n";

  // Graticule every 30° and the outline of the map.
  svg << "<g fill=\"none\" stroke=\"#9aa4b0\" stroke-width=\"0.5\">\n";
  for (int lat_deg = -60; lat_deg <= 60; lat_deg += 30) {
    const auto [x0, y0] = to_svg(-pi, lat_deg * pi / 180);
    const auto [x1, y1] = to_svg(pi, lat_deg * pi / 180);
    svg << "<line x1=\"" << x0 << "\" y1=\"" << y0 << "\" x2=\"" << x1 << "\" y2=\"" << y1 << "\"/>\n";
  }
  for (int lon_deg = -180; lon_deg <= 180; lon_deg += 30) {
    svg << "<polyline points=\"";
    for (int k = 0; k <= 90; ++k) {
      const auto [x, y] = to_svg(lon_deg * pi / 180, pi / 2 - k * pi / 90);
      svg << x << ',' << y << ' ';
    }
    svg << "\"/>\n";
  }
  svg << "</g>\n";

  svg << "<g fill=\"#1a1a1a\">\n";
  const double radius = dot_radius(spacing, scale * 2 * std::numbers::sqrt2 / pi);
  for (const Point& point : points) {
    const auto [x, y] = to_svg(longitude(point), latitude(point));
    svg << "<circle cx=\"" << x << "\" cy=\"" << y << "\" r=\"" << radius << "\"/>\n";
  }
  svg << "</g>\n</svg>\n";

  sdot::write_file_atomically(path, svg.str());  // throws InputError(path, "cannot write: ...")
}

}  // namespace blue_noise
