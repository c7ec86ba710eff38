// Grayscale image reading and writing: PGM (P2, P5 8/16-bit) and PNG round trips, colour PNGs
// written here with libpng, and every error case.
#include "sdot/image.hpp"

#include <gtest/gtest.h>
#include <png.h>

#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "sdot/error.hpp"

// Under AddressSanitizer (scripts/test-sanitized.sh) an allocation above 1 GiB fails the test: a
// reader must refuse the size a file claims before allocating it, and no test image needs more.
extern "C" const char* __asan_default_options() {
  return "max_allocation_size_mb=1024";
}

namespace sdot {
namespace {

namespace fs = std::filesystem;

class ImageTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "sdot_image_test_XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override { fs::remove_all(dir_); }

  [[nodiscard]] std::string path(const std::string& name) const { return (dir_ / name).string(); }

  void write_file(const std::string& file, const std::string& bytes) const {
    std::ofstream out(file, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }

  [[nodiscard]] static std::string read_bytes(const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }

  /// Expects read_image(file) to throw an InputError naming the file and containing `problem`.
  static void expect_error(const std::string& file, const std::string& problem) {
    try {
      (void)read_image(file);
      ADD_FAILURE() << "no InputError for " << file;
    } catch (const InputError& e) {
      EXPECT_EQ(e.field(), file);
      const std::string message = e.what();
      EXPECT_NE(message.find(file), std::string::npos) << message;
      EXPECT_NE(message.find(problem), std::string::npos) << "expected \"" << problem << "\" in: " << message;
    }
  }

  fs::path dir_;
};

GrayImage random_image(int width, int height, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> uniform(0, 1);
  GrayImage image;
  image.width = width;
  image.height = height;
  for (int i = 0; i < width * height; ++i) image.values.push_back(uniform(random));
  image.values[0] = 0;  // the extremes survive exactly
  image.values[1] = 1;
  return image;
}

void expect_close(const GrayImage& read, const GrayImage& original, double tolerance) {
  ASSERT_EQ(read.width, original.width);
  ASSERT_EQ(read.height, original.height);
  ASSERT_EQ(read.values.size(), original.values.size());
  for (std::size_t i = 0; i < read.values.size(); ++i) ASSERT_NEAR(read.values[i], original.values[i], tolerance) << i;
  EXPECT_EQ(read.values[0], 0.0);
  EXPECT_EQ(read.values[1], 1.0);
}

struct RawPng {
  int width, height, color_type, bit_depth;
  std::vector<png_bytep> rows;
  std::vector<png_color> palette;
  std::vector<png_byte> palette_alpha;  // a tRNS chunk for a palette image
};

/// The libpng calls; libpng's errors longjmp back here (only trivially destructible locals).
bool encode_raw_png(png_structp png, png_infop info, std::FILE* out, const RawPng* image) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_init_io(png, out);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image->width), static_cast<png_uint_32>(image->height),
               image->bit_depth, image->color_type, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  if (!image->palette.empty()) png_set_PLTE(png, info, image->palette.data(), static_cast<int>(image->palette.size()));
  if (!image->palette_alpha.empty())
    png_set_tRNS(png, info, image->palette_alpha.data(), static_cast<int>(image->palette_alpha.size()), nullptr);
  png_write_info(png, info);
  png_write_image(png, const_cast<png_bytepp>(image->rows.data()));
  png_write_end(png, nullptr);
  return true;
}

/// Writes a PNG with libpng: `rows` holds the raw samples (16-bit ones most significant byte first).
bool write_raw_png(const std::string& file, int width, int height, int color_type, int bit_depth,
                   const std::vector<std::vector<unsigned char>>& rows, const std::vector<png_color>& palette = {},
                   const std::vector<png_byte>& palette_alpha = {}) {
  std::FILE* out = std::fopen(file.c_str(), "wb");
  if (!out) return false;
  RawPng image{width, height, color_type, bit_depth, {}, palette, palette_alpha};
  for (const auto& row : rows) image.rows.push_back(const_cast<png_bytep>(row.data()));
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  const bool ok = encode_raw_png(png, info, out, &image);
  png_destroy_write_struct(&png, &info);
  std::fclose(out);
  return ok;
}

/// The PNG chunk CRC (CRC-32, polynomial 0xedb88320).
std::uint32_t crc32(const std::string& bytes) {
  std::uint32_t crc = 0xffffffffu;
  for (const char c : bytes) {
    crc ^= static_cast<unsigned char>(c);
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

double luminance(double r, double g, double b) {
  return 0.2126 * r + 0.7152 * g + 0.0722 * b;
}

// ---------------------------------------------------------------------------------------------
// Round trips

TEST_F(ImageTest, Pgm8RoundTrip) {
  const GrayImage image = random_image(37, 23, 1);
  write_pgm(path("a.pgm"), image);
  EXPECT_EQ(read_bytes(path("a.pgm")).substr(0, 3), "P5\n");
  const GrayImage read = read_image(path("a.pgm"));
  expect_close(read, image, 0.5 / 255 + 1e-12);
  EXPECT_EQ(read.at(2, 5), read.values[2 * 37 + 5]);
}

TEST_F(ImageTest, Pgm16RoundTrip) {
  const GrayImage image = random_image(19, 41, 2);
  write_pgm(path("a.pgm"), image, true);
  EXPECT_EQ(read_bytes(path("a.pgm")).size(), std::string("P5\n19 41\n65535\n").size() + 2 * 19 * 41);
  expect_close(read_image(path("a.pgm")), image, 0.5 / 65535 + 1e-12);
}

TEST_F(ImageTest, PngRoundTrip) {
  const GrayImage image = random_image(64, 3, 3);
  write_png(path("a.png"), image);
  expect_close(read_image(path("a.png")), image, 0.5 / 255 + 1e-12);
}

TEST_F(ImageTest, FormatComesFromTheBytesNotTheExtension) {
  const GrayImage image = random_image(5, 4, 4);
  write_png(path("really_a_png.pgm"), image);
  write_pgm(path("really_a_pgm.png"), image);
  expect_close(read_image(path("really_a_png.pgm")), image, 0.5 / 255 + 1e-12);
  expect_close(read_image(path("really_a_pgm.png")), image, 0.5 / 255 + 1e-12);
}

TEST_F(ImageTest, AsciiPgmWithComments) {
  write_file(path("a.pgm"),
             "P2\n# a comment line\n3 # width\n2\n# maxval next\n10\n"
             "0 5 10\n# a comment in the raster\n1\t2  3\n");
  const GrayImage image = read_image(path("a.pgm"));
  ASSERT_EQ(image.width, 3);
  ASSERT_EQ(image.height, 2);
  const std::vector<double> expected = {0, 0.5, 1, 0.1, 0.2, 0.3};
  for (std::size_t i = 0; i < expected.size(); ++i) EXPECT_DOUBLE_EQ(image.values[i], expected[i]);
  EXPECT_DOUBLE_EQ(image.at(1, 2), 0.3);
}

TEST_F(ImageTest, BinaryPgmWithCommentAndSmallMaxval) {
  write_file(path("a.pgm"), std::string("P5 # comment\n2 2 3\n") + std::string("\x00\x01\x02\x03", 4));
  const GrayImage image = read_image(path("a.pgm"));
  ASSERT_EQ(image.values.size(), 4u);
  for (int i = 0; i < 4; ++i) EXPECT_DOUBLE_EQ(image.values[static_cast<std::size_t>(i)], i / 3.0);
}

TEST_F(ImageTest, RgbPngBecomesLuminance) {
  // Row 0: red, green, blue; row 1: white, black, (10, 200, 30).
  const std::vector<std::vector<unsigned char>> rows = {{255, 0, 0, 0, 255, 0, 0, 0, 255},
                                                        {255, 255, 255, 0, 0, 0, 10, 200, 30}};
  ASSERT_TRUE(write_raw_png(path("rgb.png"), 3, 2, PNG_COLOR_TYPE_RGB, 8, rows));
  const GrayImage image = read_image(path("rgb.png"));
  ASSERT_EQ(image.width, 3);
  ASSERT_EQ(image.height, 2);
  EXPECT_NEAR(image.at(0, 0), 0.2126, 1e-12);
  EXPECT_NEAR(image.at(0, 1), 0.7152, 1e-12);
  EXPECT_NEAR(image.at(0, 2), 0.0722, 1e-12);
  EXPECT_NEAR(image.at(1, 0), 1, 1e-12);
  EXPECT_NEAR(image.at(1, 1), 0, 1e-12);
  EXPECT_NEAR(image.at(1, 2), luminance(10, 200, 30) / 255, 1e-12);
}

TEST_F(ImageTest, RgbaSixteenBitPngIgnoresAlpha) {
  // One pixel (r, g, b, a) = (0x1234, 0x8000, 0xffff, 0x0000).
  const std::vector<std::vector<unsigned char>> rows = {{0x12, 0x34, 0x80, 0x00, 0xff, 0xff, 0x00, 0x00}};
  ASSERT_TRUE(write_raw_png(path("rgba16.png"), 1, 1, PNG_COLOR_TYPE_RGB_ALPHA, 16, rows));
  const GrayImage image = read_image(path("rgba16.png"));
  ASSERT_EQ(image.values.size(), 1u);
  EXPECT_NEAR(image.values[0], luminance(0x1234, 0x8000, 0xffff) / 65535, 1e-12);
}

TEST_F(ImageTest, GrayAlphaAndSixteenBitGrayPngs) {
  ASSERT_TRUE(write_raw_png(path("ga.png"), 2, 1, PNG_COLOR_TYPE_GRAY_ALPHA, 8, {{51, 0, 204, 255}}));
  const GrayImage ga = read_image(path("ga.png"));
  ASSERT_EQ(ga.values.size(), 2u);
  EXPECT_NEAR(ga.values[0], 0.2, 1e-12);
  EXPECT_NEAR(ga.values[1], 0.8, 1e-12);
  ASSERT_TRUE(write_raw_png(path("g16.png"), 1, 2, PNG_COLOR_TYPE_GRAY, 16, {{0x01, 0x02}, {0xff, 0xfe}}));
  const GrayImage g16 = read_image(path("g16.png"));
  ASSERT_EQ(g16.values.size(), 2u);
  EXPECT_NEAR(g16.at(0, 0), 0x0102 / 65535.0, 1e-12);
  EXPECT_NEAR(g16.at(1, 0), 0xfffe / 65535.0, 1e-12);
  // 1-bit gray: 0b10100000 → 1, 0, 1.
  ASSERT_TRUE(write_raw_png(path("g1.png"), 3, 1, PNG_COLOR_TYPE_GRAY, 1, {{0xa0}}));
  const GrayImage g1 = read_image(path("g1.png"));
  ASSERT_EQ(g1.values.size(), 3u);
  EXPECT_EQ(g1.values[0], 1.0);
  EXPECT_EQ(g1.values[1], 0.0);
  EXPECT_EQ(g1.values[2], 1.0);
}

TEST_F(ImageTest, PalettePngBecomesLuminance) {
  const std::vector<png_color> palette = {{255, 0, 0}, {0, 0, 255}, {100, 150, 200}};
  ASSERT_TRUE(write_raw_png(path("palette.png"), 3, 1, PNG_COLOR_TYPE_PALETTE, 8, {{2, 0, 1}}, palette));
  const GrayImage image = read_image(path("palette.png"));
  ASSERT_EQ(image.values.size(), 3u);
  EXPECT_NEAR(image.values[0], luminance(100, 150, 200) / 255, 1e-12);
  EXPECT_NEAR(image.values[1], 0.2126, 1e-12);
  EXPECT_NEAR(image.values[2], 0.0722, 1e-12);
  // With transparency (a tRNS chunk): ignored.
  ASSERT_TRUE(
      write_raw_png(path("palette_alpha.png"), 3, 1, PNG_COLOR_TYPE_PALETTE, 8, {{2, 0, 1}}, palette, {0, 128, 255}));
  const GrayImage transparent = read_image(path("palette_alpha.png"));
  ASSERT_EQ(transparent.values.size(), 3u);
  EXPECT_NEAR(transparent.values[0], luminance(100, 150, 200) / 255, 1e-12);
  EXPECT_NEAR(transparent.values[1], 0.2126, 1e-12);
}

TEST_F(ImageTest, WritersClampAndValidate) {
  GrayImage image{2, 1, {-0.5, 1.5}};
  write_pgm(path("clamped.pgm"), image);
  const GrayImage read = read_image(path("clamped.pgm"));
  EXPECT_EQ(read.values[0], 0.0);
  EXPECT_EQ(read.values[1], 1.0);
  EXPECT_THROW(write_pgm(path("bad.pgm"), GrayImage{2, 2, {0, 0, 0}}), InputError);
  EXPECT_THROW(write_png(path("bad.png"), GrayImage{0, 0, {}}), InputError);
  EXPECT_THROW(write_png(path("bad.png"), GrayImage{1, 1, {std::nan("")}}), InputError);
  try {
    write_png(path("no_such_dir/a.png"), image);
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), path("no_such_dir/a.png"));
  }
}

// ---------------------------------------------------------------------------------------------
// Errors: each names the file and the problem.

TEST_F(ImageTest, MissingFile) {
  expect_error(path("missing.pgm"), "cannot open file");
}

TEST_F(ImageTest, DirectoryIsNotAnImage) {
  expect_error(dir_.string(), "is a folder, not a file");
}

TEST_F(ImageTest, EmptyFile) {
  write_file(path("empty.png"), "");
  expect_error(path("empty.png"), "empty file");
}

TEST_F(ImageTest, RandomBytesAreAnUnknownFormat) {
  std::mt19937 random(5);
  std::string bytes;
  for (int i = 0; i < 1000; ++i) bytes += static_cast<char>(random() % 256);
  bytes[0] = 'x';
  write_file(path("random.png"), bytes);
  expect_error(path("random.png"), "unknown image format");
}

TEST_F(ImageTest, UnsupportedNetpbmFormat) {
  write_file(path("colour.ppm"), "P6\n1 1\n255\nabc");
  expect_error(path("colour.ppm"), "P6 is not supported");
}

TEST_F(ImageTest, TruncatedBinaryPgm) {
  write_file(path("short.pgm"), "P5\n4 4\n255\n0123456789");
  expect_error(path("short.pgm"), "truncated PGM data: 16 bytes expected, 10 found");
  write_file(path("short16.pgm"), "P5\n2 2\n1000\n0123456");
  expect_error(path("short16.pgm"), "truncated PGM data: 8 bytes expected, 7 found");
}

TEST_F(ImageTest, TruncatedAsciiPgm) {
  write_file(path("short.pgm"), "P2\n3 3\n255\n1 2 3 4\n");
  expect_error(path("short.pgm"), "truncated PGM data: 9 values expected, 4 found");
}

TEST_F(ImageTest, TruncatedPgmHeader) {
  write_file(path("header.pgm"), "P5\n4 # no height\n");
  expect_error(path("header.pgm"), "truncated PGM header: missing height");
  write_file(path("nomaxval.pgm"), "P2 4 4");
  expect_error(path("nomaxval.pgm"), "missing maxval");
}

TEST_F(ImageTest, MalformedPgmHeader) {
  write_file(path("bad.pgm"), "P5\n4 x4\n255\n");
  expect_error(path("bad.pgm"), "height is not a non-negative integer");
  write_file(path("neg.pgm"), "P2\n2 1\n255\n1 -2\n");
  expect_error(path("neg.pgm"), "pixel value 1 is not a non-negative integer");
}

TEST_F(ImageTest, BadMaxval) {
  write_file(path("zero.pgm"), "P5\n1 1\n0\n\x00");
  expect_error(path("zero.pgm"), "maxval 0 is out of range 1..65535");
  write_file(path("big.pgm"), "P2\n1 1\n65536\n0\n");
  expect_error(path("big.pgm"), "maxval 65536 is out of range 1..65535");
}

TEST_F(ImageTest, ValueAboveMaxval) {
  write_file(path("over.pgm"), "P2\n2 1\n10\n3 11\n");
  expect_error(path("over.pgm"), "PGM value 11 of pixel 1 exceeds maxval 10");
  write_file(path("over16.pgm"), std::string("P5\n1 1\n1000\n\x03\xe9", 14));
  expect_error(path("over16.pgm"), "PGM value 1001 of pixel 0 exceeds maxval 1000");
}

TEST_F(ImageTest, ZeroSize) {
  write_file(path("zero.pgm"), "P5\n0 4\n255\n");
  expect_error(path("zero.pgm"), "zero image size 0x4");
  write_file(path("zero2.pgm"), "P2\n3 0\n255\n");
  expect_error(path("zero2.pgm"), "zero image size 3x0");
}

TEST_F(ImageTest, HugeSizeIsRefused) {
  write_file(path("huge.pgm"), "P5\n100000 100000\n255\n");
  expect_error(path("huge.pgm"), "too large");
}

TEST_F(ImageTest, CorruptPng) {
  write_png(path("good.png"), random_image(40, 40, 6));
  std::string bytes = read_bytes(path("good.png"));
  const auto idat = bytes.find("IDAT");
  ASSERT_NE(idat, std::string::npos);
  // Corrupted image data (the chunk's CRC no longer matches).
  std::string corrupted = bytes;
  for (std::size_t k = idat + 8; k < idat + 40; ++k) corrupted[k] = static_cast<char>(corrupted[k] ^ 0x5a);
  write_file(path("corrupt.png"), corrupted);
  expect_error(path("corrupt.png"), "corrupt PNG");
  // Corrupted header (IHDR CRC).
  corrupted = bytes;
  corrupted[18] = static_cast<char>(corrupted[18] ^ 0x01);
  write_file(path("header.png"), corrupted);
  expect_error(path("header.png"), "corrupt PNG");
  // Truncated in the image data, and right after the signature.
  write_file(path("truncated.png"), bytes.substr(0, idat + 20));
  expect_error(path("truncated.png"), "corrupt PNG");
  write_file(path("signature.png"), bytes.substr(0, 8));
  expect_error(path("signature.png"), "truncated data");
  write_file(path("half_signature.png"), bytes.substr(0, 4));
  expect_error(path("half_signature.png"), "truncated PNG signature");
}

TEST_F(ImageTest, PngWithZeroWidthIsCorrupt) {
  write_png(path("good.png"), random_image(2, 2, 7));
  std::string bytes = read_bytes(path("good.png"));
  // IHDR data start at byte 16: width (4 bytes), height (4 bytes). Zero the width and fix the CRC.
  for (int k = 16; k < 20; ++k) bytes[static_cast<std::size_t>(k)] = 0;
  const std::uint32_t crc = crc32(bytes.substr(12, 17));
  for (int k = 0; k < 4; ++k) bytes[static_cast<std::size_t>(29 + k)] = static_cast<char>((crc >> (24 - 8 * k)) & 0xff);
  write_file(path("zero.png"), bytes);
  expect_error(path("zero.png"), "zero");
}

// ---------------------------------------------------------------------------------------------
// decode_image, and the inputs that fuzzing found (tests/fuzz, docs/reliability.md)

/// A PNG chunk: length, type, data, CRC.
std::string make_png_chunk(const std::string& type, const std::string& data) {
  std::string chunk;
  for (int k = 0; k < 4; ++k) chunk += static_cast<char>((data.size() >> (24 - 8 * k)) & 0xff);
  chunk += type + data;
  const std::uint32_t crc = crc32(type + data);
  for (int k = 0; k < 4; ++k) chunk += static_cast<char>((crc >> (24 - 8 * k)) & 0xff);
  return chunk;
}

/// decode_image on a string's bytes.
GrayImage decode(const std::string& name, const std::string& bytes) {
  return decode_image(name, std::span(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size()));
}

/// Expects decode_image to throw an InputError naming `name` and containing `problem`.
void expect_decode_error(const std::string& name, const std::string& bytes, const std::string& problem) {
  try {
    (void)decode(name, bytes);
    ADD_FAILURE() << "no InputError for " << name;
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), name);
    const std::string message = e.what();
    EXPECT_NE(message.find(problem), std::string::npos) << "expected \"" << problem << "\" in: " << message;
  }
}

TEST_F(ImageTest, DecodeImageReadsBytesAsReadImageReadsTheFile) {
  const GrayImage original = random_image(7, 5, 8);
  write_png(path("a.png"), original);
  write_pgm(path("a.pgm"), original, true);
  for (const char* file : {"a.png", "a.pgm"}) {
    const GrayImage from_file = read_image(path(file));
    const GrayImage from_bytes = decode(file, read_bytes(path(file)));
    EXPECT_EQ(from_bytes.width, from_file.width);
    EXPECT_EQ(from_bytes.height, from_file.height);
    EXPECT_EQ(from_bytes.values, from_file.values);
  }
  expect_decode_error("empty", "", "empty file");
}

// fuzz_png found it: after its IHDR (16384 x 16384, 16-bit RGB) a zTXt chunk claims 0x75000000
// bytes; libpng warned "chunk data is too large" and still allocated 1.96 GB before finding
// the file's end. Ancillary chunks are now skipped unread.
TEST_F(ImageTest, FuzzPngChunkClaimingTwoGigabytesIsNotAllocated) {
  const unsigned char input[] = {0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d,
                                 0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x40, 0x00, 0x00, 0x00, 0x40, 0x00,
                                 0x10, 0x02, 0x00, 0x00, 0x00, 0x76, 0x3a, 0x5b, 0x90, 0x75, 0x00, 0x00,
                                 0x00, 0x7a, 0x54, 0x58, 0x74, 0x49, 0x44, 0x41, 0x54, 0x8a, 0x00, 0x40};
  expect_decode_error("fuzz.png", std::string(reinterpret_cast<const char*>(input), sizeof input), "corrupt PNG");
}

TEST_F(ImageTest, PngAncillaryChunksAreSkipped) {
  const GrayImage original = random_image(6, 4, 9);
  write_png(path("plain.png"), original);
  const std::string bytes = read_bytes(path("plain.png"));
  // Text, a compressed text whose CRC is wrong, and an unknown chunk, between IHDR and IDAT.
  std::string bad_crc = make_png_chunk("zTXt", std::string("Comment\0\0x", 10));
  bad_crc[bad_crc.size() - 1] = static_cast<char>(bad_crc.back() ^ 0x5a);
  const std::string chunks = make_png_chunk("tEXt", std::string("Comment\0made by a test", 23)) + bad_crc +
                             make_png_chunk("abCd", std::string(100, 'x'));
  const std::size_t after_ihdr = 8 + 25;
  expect_close(decode("chunks.png", bytes.substr(0, after_ihdr) + chunks + bytes.substr(after_ihdr)), original,
               0.5 / 255);
}

// A 16384 x 16384 16-bit RGB image (1.6 GB of samples) whose file holds a few bytes of image
// data: refused before the pixel buffer is allocated (deflate expands at most 1032:1).
TEST_F(ImageTest, PngTooShortForItsSizeIsRefusedBeforeDecoding) {
  std::string header;
  for (const std::uint32_t v : {16384u, 16384u})
    for (int k = 0; k < 4; ++k) header += static_cast<char>((v >> (24 - 8 * k)) & 0xff);
  header += std::string("\x10\x02\0\0\0", 5);  // 16-bit, RGB, deflate, adaptive filters, not interlaced
  const std::string empty_deflate("\x78\x9c\x03\x00\x00\x00\x00\x01", 8);
  const std::string png = std::string("\x89PNG\r\n\x1a\n", 8) + make_png_chunk("IHDR", header) +
                          make_png_chunk("IDAT", empty_deflate) + make_png_chunk("IEND", "");
  expect_decode_error("large.png", png, "truncated PNG: a 16384x16384 image needs at least 1610620928 bytes");
}

}  // namespace
}  // namespace sdot
