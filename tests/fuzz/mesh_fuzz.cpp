// libFuzzer harness of one mesh reader, sphparam::parse_mesh, built once per format
// (SDOT_FUZZ_FORMAT: off, obj, ply, freesurfer). FileError is the expected failure; any other
// exception, a crash or a sanitizer report is a bug. A parsed mesh must have finite coordinates
// and face indices in range, and then goes through validate(), as in sdot-sphere-param, which
// must not return NaN.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz_support.hpp"
#include "mesh.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  sphparam::ReadInfo info;
  sphparam::Mesh mesh;
  try {
    mesh = sphparam::parse_mesh(bytes, SDOT_FUZZ_FORMAT, "fuzz." SDOT_FUZZ_FORMAT, &info);
  } catch (const sphparam::FileError&) {
    return 0;
  }
  for (const auto& v : mesh.vertices)
    if (!v.allFinite()) sdot::fuzz::fail("parse_mesh returned a non-finite coordinate");
  for (const auto& face : mesh.faces)
    for (const int i : face)
      if (i < 0 || static_cast<std::size_t>(i) >= mesh.vertices.size())
        sdot::fuzz::fail("parse_mesh returned a face index out of range");
  // Validated as sdot-sphere-param validates it (run_parameterization, run.cpp): scaled by the
  // power of two that brings its largest coordinate into [0.5, 1), so that coordinates of 1e200
  // do not overflow the areas (validate on the raw mesh gives NaN there).
  sphparam::scale_by_power_of_two(mesh);
  const sphparam::Validation validation = sphparam::validate(mesh, info);
  if (std::isnan(validation.signed_volume)) sdot::fuzz::fail("validate returned a NaN signed_volume");
  if (std::isnan(validation.min_angle_deg)) sdot::fuzz::fail("validate returned a NaN min_angle_deg");
  if (std::isnan(validation.area_ratio)) sdot::fuzz::fail("validate returned a NaN area_ratio");
  return 0;
}
