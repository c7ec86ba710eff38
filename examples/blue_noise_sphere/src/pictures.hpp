#pragma once
/// \file pictures.hpp
/// Pictures of a point set over its density image: a grayscale PNG in the equirectangular
/// projection and an SVG in the Mollweide (equal-area) projection.

#include <sdot/image.hpp>
#include <string>
#include <vector>

#include "blue_noise.hpp"

namespace blue_noise {

/// Writes a `width` × `width`/2 grayscale PNG: the image as a light background (0 white, the
/// image's maximum mid-gray) and the points as black dots whose radius is a fraction of
/// `spacing` (a typical distance between points, radians). Throws sdot::InputError naming the
/// path when it cannot be written.
void write_png_picture(const std::string& path, const sdot::GrayImage& image, const std::vector<Point>& points,
                       double spacing, int width = 1024);

/// Writes an SVG in the Mollweide projection: the image (averaged down to at most 360 × 180
/// cells, 16 gray levels) as a light raster, a 30° graticule and the points as dark dots.
/// Throws sdot::InputError naming the path when it cannot be written.
void write_svg_picture(const std::string& path, const sdot::GrayImage& image, const std::vector<Point>& points,
                       double spacing);

}  // namespace blue_noise
