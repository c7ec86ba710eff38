// libFuzzer harness of the sdot command's problem files: the bytes read as the command reads a
// problem file (inputs that are not a JSON object are rejected), solved through the geometry
// registry like `sdot solve` does, with an empty folder as the problem's directory. Inputs with more than max_sites
// sites or naming a file outside the folder are rejected, and the solver's work is bounded (cap_work: max_iterations,
// quadrature order) so that each input runs in milliseconds.
#include <cstddef>
#include <cstdint>

#include "cli_fuzz_support.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  (void)sdot::fuzz::scratch_directory();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto read = sdot::fuzz::read_json_bytes(data, size);
  if (!read || !read->is_object()) return -1;
  sdot::fuzz::json& problem = *read;
  const auto sites = problem.find("sites");
  if (sites != problem.end() && sites->is_array() && sites->size() > sdot::fuzz::max_sites) return -1;
  if (sdot::fuzz::names_outside_file(problem)) return -1;
  sdot::fuzz::cap_work(problem);
  sdot::fuzz::solve_and_check(problem);
  return 0;
}
