#include "sdot/image.hpp"
#include "sdot/input_file.hpp"

#include <png.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <span>
#include <string_view>

#include "sdot/error.hpp"
#include "sdot/output_file.hpp"

namespace sdot {
namespace {

/// Images larger than this many pixels are refused (2^28 values take 2 GiB as doubles).
constexpr std::size_t max_pixels = std::size_t{1} << 28;

struct FileCloser {
  void operator()(std::FILE* file) const { std::fclose(file); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

std::vector<unsigned char> read_file(const std::string& path) {
  require_regular_file(path);
  errno = 0;
  const File file(std::fopen(path.c_str(), "rb"));
  if (!file) throw InputError(path, std::string("cannot open file: ") + std::strerror(errno));
  std::vector<unsigned char> bytes;
  unsigned char buffer[1 << 16];
  for (;;) {
    const std::size_t n = std::fread(buffer, 1, sizeof buffer, file.get());
    bytes.insert(bytes.end(), buffer, buffer + n);
    if (n < sizeof buffer) break;
  }
  if (std::ferror(file.get())) throw InputError(path, std::string("cannot read file: ") + std::strerror(errno));
  return bytes;
}

void check_size(const std::string& path, std::uint64_t width, std::uint64_t height) {
  if (width == 0 || height == 0)
    throw InputError(path, "zero image size " + std::to_string(width) + "x" + std::to_string(height));
  if (width > max_pixels || height > max_pixels || width * height > max_pixels)
    throw InputError(path, "image of " + std::to_string(width) + "x" + std::to_string(height) +
                               " pixels is too large (at most " + std::to_string(max_pixels) + " pixels)");
}

// ---------------------------------------------------------------------------------------------
// PGM

class PgmParser {
 public:
  PgmParser(const std::string& path, std::span<const unsigned char> bytes) : path_(path), bytes_(bytes) {}

  GrayImage parse() {
    const bool ascii = bytes_[1] == '2';
    pos_ = 2;
    const std::uint64_t width = header_number("width");
    const std::uint64_t height = header_number("height");
    const std::uint64_t maxval = header_number("maxval");
    if (maxval < 1 || maxval > 65535)
      throw InputError(path_, "PGM maxval " + std::to_string(maxval) + " is out of range 1..65535");
    check_size(path_, width, height);
    GrayImage image;
    image.width = static_cast<int>(width);
    image.height = static_cast<int>(height);
    const std::size_t count = width * height;
    const auto scale = static_cast<double>(maxval);
    if (ascii) {
      image.values.reserve(std::min(count, (bytes_.size() - pos_) / 2 + 1));
      for (std::size_t i = 0; i < count; ++i) {
        skip_space_and_comments();
        if (pos_ >= bytes_.size())
          throw InputError(path_, "truncated PGM data: " + std::to_string(count) + " values expected, " +
                                      std::to_string(i) + " found");
        const std::uint64_t v = number("pixel value " + std::to_string(i));
        check_value(v, maxval, i);
        image.values.push_back(static_cast<double>(v) / scale);
      }
      return image;
    }
    // Binary: exactly one whitespace character after maxval, then the raster.
    if (pos_ >= bytes_.size() || !is_space(bytes_[pos_]))
      throw InputError(path_, "truncated PGM header: expected a whitespace character after maxval");
    ++pos_;
    const std::size_t bytes_per_value = maxval > 255 ? 2 : 1;
    const std::size_t available = bytes_.size() - pos_;
    if (available < count * bytes_per_value)
      throw InputError(path_, "truncated PGM data: " + std::to_string(count * bytes_per_value) + " bytes expected, " +
                                  std::to_string(available) + " found");
    image.values.resize(count);
    const unsigned char* data = bytes_.data() + pos_;
    for (std::size_t i = 0; i < count; ++i) {
      const std::uint64_t v =
          bytes_per_value == 2 ? (std::uint64_t{data[2 * i]} << 8) | data[2 * i + 1] : std::uint64_t{data[i]};
      check_value(v, maxval, i);
      image.values[i] = static_cast<double>(v) / scale;
    }
    return image;
  }

 private:
  static bool is_space(unsigned char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
  }

  void skip_space_and_comments() {
    while (pos_ < bytes_.size()) {
      if (is_space(bytes_[pos_])) {
        ++pos_;
      } else if (bytes_[pos_] == '#') {
        while (pos_ < bytes_.size() && bytes_[pos_] != '\n' && bytes_[pos_] != '\r') ++pos_;
      } else {
        break;
      }
    }
  }

  std::uint64_t header_number(const std::string& what) {
    if (pos_ < bytes_.size() && !is_space(bytes_[pos_]) && bytes_[pos_] != '#')
      throw InputError(path_, "malformed PGM header: expected whitespace before the " + what);
    skip_space_and_comments();
    if (pos_ >= bytes_.size()) throw InputError(path_, "truncated PGM header: missing " + what);
    return number(what);
  }

  /// A decimal number at pos_, followed by whitespace, '#' or the end of the file.
  std::uint64_t number(const std::string& what) {
    const std::size_t start = pos_;
    std::uint64_t v = 0;
    while (pos_ < bytes_.size() && bytes_[pos_] >= '0' && bytes_[pos_] <= '9') {
      v = std::min<std::uint64_t>(v * 10 + (bytes_[pos_] - '0'), std::uint64_t{1} << 40);  // saturate
      ++pos_;
    }
    if (pos_ == start || (pos_ < bytes_.size() && !is_space(bytes_[pos_]) && bytes_[pos_] != '#')) {
      const std::size_t end = std::min(bytes_.size(), start + 16);
      std::string got;
      for (std::size_t k = start; k < end && !is_space(bytes_[k]); ++k)
        got += (bytes_[k] >= 32 && bytes_[k] < 127) ? static_cast<char>(bytes_[k]) : '?';
      throw InputError(path_, "malformed PGM: " + what + " is not a non-negative integer (got \"" + got + "\")");
    }
    return v;
  }

  void check_value(std::uint64_t v, std::uint64_t maxval, std::size_t i) const {
    if (v > maxval)
      throw InputError(path_, "PGM value " + std::to_string(v) + " of pixel " + std::to_string(i) + " exceeds maxval " +
                                  std::to_string(maxval));
  }

  const std::string& path_;
  std::span<const unsigned char> bytes_;
  std::size_t pos_ = 0;
};

// ---------------------------------------------------------------------------------------------
// PNG
//
// libpng reports errors through longjmp. The only frames a longjmp crosses are libpng's own C
// frames and our callbacks, which hold nothing to destroy; it lands in `decode_png` /
// `encode_png`, whose locals are all trivially destructible and not used after the jump (they
// return false at once). Every C++ object (buffers, messages) lives in the callers.

struct PngContext {
  const unsigned char* data = nullptr;  // reading: the whole file
  std::size_t size = 0;
  std::size_t position = 0;
  std::vector<unsigned char>* output = nullptr;  // writing
  char message[256] = {};
};

void on_png_error(png_structp png, png_const_charp message) {
  auto* context = static_cast<PngContext*>(png_get_error_ptr(png));
  std::snprintf(context->message, sizeof context->message, "%s", message ? message : "unknown libpng error");
  png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {}

void on_png_read(png_structp png, png_bytep out, png_size_t length) {
  auto* context = static_cast<PngContext*>(png_get_io_ptr(png));
  if (length > context->size - context->position) png_error(png, "unexpected end of file (truncated data)");
  std::memcpy(out, context->data + context->position, length);
  context->position += length;
}

void on_png_write(png_structp png, png_bytep data, png_size_t length) {
  auto* context = static_cast<PngContext*>(png_get_io_ptr(png));
  bool ok = true;
  try {
    context->output->insert(context->output->end(), data, data + length);
  } catch (...) {  // no C++ exception may unwind through libpng
    ok = false;
  }
  if (!ok) png_error(png, "out of memory");
}

void on_png_flush(png_structp) {}

/// Deflate expands its input at most 1032 times (a 258-byte match in 2 bits).
constexpr std::uint64_t max_deflate_ratio = 1032;

struct DecodedPng {
  std::uint32_t width = 0, height = 0;
  int channels = 0;   // 1 (gray) or 3 (RGB), after the transformations
  int bit_depth = 0;  // 8 or 16
  std::vector<unsigned char>* pixels = nullptr;
  std::vector<png_bytep>* rows = nullptr;
  bool too_large = false;
  std::uint64_t data_needed = 0;  // > 0: the file is too short for the header's size (bytes of image data)
};

bool decode_png(png_structp png, png_infop info, DecodedPng* out) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_info(png, info);
  const png_byte color_type = png_get_color_type(png, info);
  const png_byte depth = png_get_bit_depth(png, info);
  // The decompressed image data hold at least width·height·bits / 8 bytes, plus a filter byte per
  // row of the last interlace pass (every other row); refused before allocating the pixels when
  // the file cannot hold it.
  const std::uint64_t stored_bits = std::uint64_t{png_get_channels(png, info)} * depth;
  const std::uint64_t stored_width = png_get_image_width(png, info), stored_height = png_get_image_height(png, info);
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (color_type == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  // Alpha is ignored, also the one that png_set_palette_to_rgb makes of a palette's tRNS chunk.
  if ((color_type & PNG_COLOR_MASK_ALPHA) || png_get_valid(png, info, PNG_INFO_tRNS)) png_set_strip_alpha(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  out->width = png_get_image_width(png, info);
  out->height = png_get_image_height(png, info);
  out->channels = png_get_channels(png, info);
  out->bit_depth = png_get_bit_depth(png, info);
  if (out->width == 0 || out->height == 0 || std::uint64_t{out->width} * out->height > max_pixels) {
    out->too_large = true;
    return true;
  }
  const std::uint64_t data_bytes = stored_width * stored_height * stored_bits / 8 + stored_height / 2;
  const auto* context = static_cast<const PngContext*>(png_get_io_ptr(png));
  if (data_bytes > max_deflate_ratio * context->size) {
    out->data_needed = data_bytes;
    return true;
  }
  if ((out->channels != 1 && out->channels != 3) || (out->bit_depth != 8 && out->bit_depth != 16))
    png_error(png, "unsupported PNG sample layout");
  const std::size_t row_bytes = png_get_rowbytes(png, info);
  out->pixels->resize(row_bytes * out->height);
  out->rows->resize(out->height);
  for (std::uint32_t r = 0; r < out->height; ++r) (*out->rows)[r] = out->pixels->data() + r * row_bytes;
  png_read_image(png, out->rows->data());
  png_read_end(png, nullptr);
  return true;
}

GrayImage read_png(const std::string& path, std::span<const unsigned char> bytes) {
  PngContext context;
  context.data = bytes.data();
  context.size = bytes.size();
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &context, on_png_error, on_png_warning);
  if (!png) throw InputError(path, "cannot initialise libpng");
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    throw InputError(path, "cannot initialise libpng");
  }
  png_set_read_fn(png, &context, on_png_read);
  // Only the pixels matter: libpng skips every ancillary chunk but tRNS unread (fuzzing found
  // that libpng 1.6.39 allocates the length a zTXt chunk claims, up to 2 GiB, even after warning
  // that it exceeds its limit).
  png_set_keep_unknown_chunks(png, PNG_HANDLE_CHUNK_NEVER, nullptr, -1);
  std::vector<unsigned char> pixels;
  std::vector<png_bytep> rows;
  DecodedPng decoded;
  decoded.pixels = &pixels;
  decoded.rows = &rows;
  bool ok = false;
  try {
    ok = decode_png(png, info, &decoded);
  } catch (...) {  // std::bad_alloc from the buffers
    png_destroy_read_struct(&png, &info, nullptr);
    throw;
  }
  png_destroy_read_struct(&png, &info, nullptr);
  if (!ok) throw InputError(path, std::string("corrupt PNG: ") + context.message);
  check_size(path, decoded.width, decoded.height);
  if (decoded.data_needed > 0)
    throw InputError(path, "truncated PNG: a " + std::to_string(decoded.width) + "x" + std::to_string(decoded.height) +
                               " image needs at least " + std::to_string(decoded.data_needed) +
                               " bytes of image data, more than a file of " + std::to_string(bytes.size()) +
                               " bytes can hold");

  GrayImage image;
  image.width = static_cast<int>(decoded.width);
  image.height = static_cast<int>(decoded.height);
  const std::size_t count = std::size_t{decoded.width} * decoded.height;
  image.values.resize(count);
  const bool wide = decoded.bit_depth == 16;
  const double scale = wide ? 65535.0 : 255.0;
  auto sample = [&](const unsigned char* p, std::size_t k) -> double {
    return wide ? static_cast<double>((unsigned{p[2 * k]} << 8) | p[2 * k + 1]) : static_cast<double>(p[k]);
  };
  for (std::size_t i = 0; i < count; ++i) {
    const unsigned char* p = pixels.data() + i * static_cast<std::size_t>(decoded.channels) * (wide ? 2 : 1);
    const double v =
        decoded.channels == 1 ? sample(p, 0) : 0.2126 * sample(p, 0) + 0.7152 * sample(p, 1) + 0.0722 * sample(p, 2);
    image.values[i] = std::clamp(v / scale, 0.0, 1.0);
  }
  return image;
}

bool encode_png(png_structp png, png_infop info, const GrayImage* image, const std::vector<png_bytep>* rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_IHDR(png, info, static_cast<png_uint_32>(image->width), static_cast<png_uint_32>(image->height), 8,
               PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_write_image(png, const_cast<png_bytepp>(rows->data()));
  png_write_end(png, nullptr);
  return true;
}

// ---------------------------------------------------------------------------------------------
// Writing

void check_image(const GrayImage& image) {
  if (image.width <= 0 || image.height <= 0)
    throw InputError("image",
                     "size " + std::to_string(image.width) + "x" + std::to_string(image.height) + " is not positive");
  const std::size_t count = static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height);
  if (image.values.size() != count)
    throw InputError("image.values", std::to_string(image.values.size()) + " values for a " +
                                         std::to_string(image.width) + "x" + std::to_string(image.height) + " image");
  for (std::size_t i = 0; i < count; ++i)
    if (!std::isfinite(image.values[i])) throw InputError(indexed("image.values", i), "not a finite number");
}

unsigned quantise(double v, unsigned maxval) {
  return static_cast<unsigned>(std::lround(std::clamp(v, 0.0, 1.0) * maxval));
}

// Atomically (a temporary file renamed into place): a failure leaves any previous file intact.
void write_bytes(const std::string& path, const std::vector<unsigned char>& bytes) {
  write_file_atomically(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace

GrayImage read_image(const std::string& path) {
  const std::vector<unsigned char> bytes = read_file(path);
  return decode_image(path, bytes);
}

GrayImage decode_image(const std::string& path, std::span<const unsigned char> bytes) {
  if (bytes.empty()) throw InputError(path, "empty file (expected a PGM or PNG image)");
  if (bytes.size() >= 8 && png_sig_cmp(bytes.data(), 0, 8) == 0) return read_png(path, bytes);
  if (bytes.size() >= 2 && bytes[0] == 'P') {
    if (bytes[1] == '2' || bytes[1] == '5') return PgmParser(path, bytes).parse();
    if (bytes[1] >= '1' && bytes[1] <= '7')
      throw InputError(path, std::string("Netpbm format P") + static_cast<char>(bytes[1]) +
                                 " is not supported (only grayscale PGM: P2 or P5)");
  }
  if (bytes.size() < 8 && png_sig_cmp(bytes.data(), 0, bytes.size()) == 0)
    throw InputError(path, "truncated PNG signature");
  throw InputError(path, "unknown image format (expected PGM P2/P5 or PNG, detected from the first bytes)");
}

void write_pgm(const std::string& path, const GrayImage& image, bool sixteen_bit) {
  check_image(image);
  const unsigned maxval = sixteen_bit ? 65535 : 255;
  const std::string header =
      "P5\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n" + std::to_string(maxval) + "\n";
  std::vector<unsigned char> bytes(header.begin(), header.end());
  bytes.reserve(header.size() + image.values.size() * (sixteen_bit ? 2 : 1));
  for (const double v : image.values) {
    const unsigned q = quantise(v, maxval);
    if (sixteen_bit) bytes.push_back(static_cast<unsigned char>(q >> 8));
    bytes.push_back(static_cast<unsigned char>(q & 0xff));
  }
  write_bytes(path, bytes);
}

void write_png(const std::string& path, const GrayImage& image) {
  check_image(image);
  const auto width = static_cast<std::size_t>(image.width);
  std::vector<unsigned char> pixels(image.values.size());
  std::transform(image.values.begin(), image.values.end(), pixels.begin(),
                 [](double v) { return static_cast<unsigned char>(quantise(v, 255)); });
  std::vector<png_bytep> rows(static_cast<std::size_t>(image.height));
  for (std::size_t r = 0; r < rows.size(); ++r) rows[r] = pixels.data() + r * width;

  std::vector<unsigned char> encoded;
  PngContext context;
  context.output = &encoded;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &context, on_png_error, on_png_warning);
  if (!png) throw InputError(path, "cannot initialise libpng");
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    throw InputError(path, "cannot initialise libpng");
  }
  png_set_write_fn(png, &context, on_png_write, on_png_flush);
  const bool ok = encode_png(png, info, &image, &rows);
  png_destroy_write_struct(&png, &info);
  if (!ok) throw InputError(path, std::string("cannot encode PNG: ") + context.message);
  write_bytes(path, encoded);
}

}  // namespace sdot
