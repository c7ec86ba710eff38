// libFuzzer harness of one image reader, sdot::decode_image (what read_image does with a file's
// bytes), built once per format (SDOT_FUZZ_FORMAT: pgm or png). Inputs that do not start like
// that format (P2/P5, or the PNG signature) are rejected, so that each harness stays on its
// reader. InputError is the expected failure; a decoded image must have a positive size that
// matches its values, all in [0, 1].
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string_view>

#include "fuzz_support.hpp"
#include "sdot/error.hpp"
#include "sdot/image.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (std::string_view(SDOT_FUZZ_FORMAT) == "png") {
    constexpr unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    if (size < 8 || std::memcmp(data, signature, 8) != 0) return -1;
  } else if (size < 2 || data[0] != 'P' || (data[1] != '2' && data[1] != '5')) {
    return -1;
  }
  try {
    const sdot::GrayImage image = sdot::decode_image("fuzz." SDOT_FUZZ_FORMAT, std::span(data, size));
    if (image.width <= 0 || image.height <= 0) sdot::fuzz::fail("decode_image returned an empty image");
    if (image.values.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height))
      sdot::fuzz::fail("decode_image returned a size that does not match its values");
    for (const double v : image.values)
      if (!(v >= 0 && v <= 1)) sdot::fuzz::fail("decode_image returned a value outside [0, 1] or NaN");
  } catch (const sdot::InputError&) {
  }
  return 0;
}
