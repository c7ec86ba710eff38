#pragma once
/// \file image.hpp
/// Grayscale images from files, e.g. to build a density from data: binary and ascii PGM, and
/// PNG of any colour type (read with libpng, which stays private to the library).

#include <cstddef>
#include <span>
#include <string>
#include <vector>

namespace sdot {

/// A grayscale image: `width` × `height` values in [0, 1], row-major, row 0 at the top.
struct GrayImage {
  ///@{
  /// The size in pixels: `width` columns, `height` rows.
  int width = 0, height = 0;
  ///@}
  /// `width * height` values; pixel (row, column) is `values[row * width + column]`.
  std::vector<double> values;
  /// The value of pixel (`row`, `column`); precondition: 0 ≤ row < height, 0 ≤ column < width.
  [[nodiscard]] double at(int row, int column) const {
    return values[static_cast<std::size_t>(row) * static_cast<std::size_t>(width) + static_cast<std::size_t>(column)];
  }
};

/// Reads a grayscale image, detecting the format from the file's first bytes (not its name):
/// - PGM: P2 (ascii) and P5 (binary; 2 bytes per value, most significant first, when maxval > 255),
///   maxval 1..65535, `#` comments; value v becomes v / maxval.
/// - PNG: 1..16-bit gray, gray + alpha, RGB, RGBA and palette images. Colour becomes the luminance
///   0.2126 R + 0.7152 G + 0.0722 B of the stored (gamma-encoded) samples; alpha is ignored.
///
/// Throws InputError whose field is `path` when the file is missing or unreadable, its format is
/// unknown, its data are truncated or corrupt, its size is zero, or a PGM's maxval (or a value)
/// is out of range.
[[nodiscard]] GrayImage read_image(const std::string& path);

/// Decodes the bytes of a PGM or PNG file, as read_image does with a file's content (the format
/// comes from the first bytes); `name` is the InputError's field, e.g. the file's path. The size
/// a header announces is checked (at most 2^28 pixels, and a binary PGM must hold its raster)
/// before memory is allocated for it. Throws InputError for the same reasons as read_image.
[[nodiscard]] GrayImage decode_image(const std::string& name, std::span<const unsigned char> bytes);

/// Writes `image` as a binary PGM (P5), with maxval 65535 when `sixteen_bit`, else 255. Values are
/// clamped to [0, 1] and rounded. The file is replaced atomically (write_file_atomically: a failure
/// leaves a previous file intact). Throws InputError (field `path`) when the file cannot be written,
/// and (field `image`) when the image is empty, its size does not match its values, or a value is
/// not finite.
void write_pgm(const std::string& path, const GrayImage& image, bool sixteen_bit = false);

/// Writes `image` as an 8-bit grayscale PNG; values are clamped and rounded, errors as `write_pgm`.
void write_png(const std::string& path, const GrayImage& image);

/// How an image defines a density (see image_density on the plane and equirectangular_density
/// on the sphere, which say which they accept).
enum class ImageInterpolation {
  constant,  ///< each pixel's value on the whole pixel
  bilinear,  ///< bilinear interpolation of the pixel-centre values (plane)
  linear,    ///< linear interpolation on triangles between pixel centres (sphere)
};

}  // namespace sdot
