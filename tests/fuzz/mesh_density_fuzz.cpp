// libFuzzer harness of mesh densities in problem files. The first byte picks the geometry
// (byte % 3: plane, sphere, H²) and where the mesh is (byte / 3 % 2: in the problem, or in a
// density file); the rest is a JSON object with the mesh's fields (vertices, triangles,
// values or triangle_values, quadrature_order), put into a fixed problem with four to six
// sites and solved through the geometry registry, as `sdot solve` does.
#include <cstddef>
#include <cstdint>
#include <fstream>

#include "cli_fuzz_support.hpp"

namespace {

using sdot::fuzz::json;

json base_problem(int geometry) {
  switch (geometry) {
    case 0:
      return {{"geometry", "plane"}, {"sites", {{0.2, 0.3}, {0.7, 0.2}, {0.5, 0.8}, {0.3, 0.6}}}};
    case 1:
      return {{"geometry", "sphere"},
              {"sites", {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}, {0, -1, 0}, {0, 0.6, -0.8}}}};
    default:
      return {{"geometry", "hyperbolic"},
              {"domain", {{"model", "klein"}, {"vertices", {{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}}}}},
              {"sites", {{-0.2, -0.2}, {0.2, -0.1}, {0.1, 0.25}, {-0.15, 0.2}}}};
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  (void)sdot::fuzz::scratch_directory();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return -1;
  const int geometry = data[0] % 3;
  const bool in_file = data[0] / 3 % 2 == 1;
  auto read = sdot::fuzz::read_json_bytes(data + 1, size - 1);
  if (!read || !read->is_object()) return -1;
  json& fields = *read;
  json problem = base_problem(geometry);
  if (in_file) {
    json density = {{"type", "mesh"}, {"file", "rho.json"}};
    if (const auto order = fields.find("quadrature_order"); order != fields.end()) {
      density["quadrature_order"] = *order;
      fields.erase(order);
    }
    std::ofstream(sdot::fuzz::problem_directory() + "/rho.json") << fields.dump();
    problem["density"] = std::move(density);
  } else {
    fields["type"] = "mesh";
    problem["density"] = std::move(fields);
  }
  sdot::fuzz::cap_work(problem);
  sdot::fuzz::solve_and_check(problem);
  return 0;
}
