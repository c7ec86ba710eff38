#pragma once
// Shared by the harnesses of the sdot command's problem files (problem_fuzz.cpp,
// mesh_density_fuzz.cpp): the geometry registry, a scratch folder, the command's JSON reader,
// and one solve through the registry, as `sdot solve` runs it, with its checks. InputError and
// nlohmann::json::exception are the expected failures; any other exception escapes (a crash
// for libFuzzer), and a NaN or infinity in the result JSON or "nan" in the SVG is a bug.

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "common.hpp"
#include "fuzz_support.hpp"
#include "registry.hpp"
#include "sdot/error.hpp"

namespace sdot::fuzz {

using nlohmann::json;

/// Problems are cut to this many Newton iterations (each may halve its step 40 times), so that
/// an input runs in milliseconds, and in seconds at worst (big quadrature orders on the sphere),
/// under the sanitizers.
constexpr int max_iterations = 3;
/// Mesh densities' quadrature orders above this are cut to it (on the sphere, big triangles add
/// up to 29 more): order 64 on the sphere took 20 s for 3 iterations under the sanitizers.
constexpr int max_quadrature_order = 8;
/// Inputs with more sites are rejected (slow, and nothing new for the readers).
constexpr std::size_t max_sites = 30;

inline const cli::Registry& registry() {
  static const cli::Registry instance = [] {
    cli::Registry r;
    cli::register_geometries(r);
    return r;
  }();
  return instance;
}

/// This process's scratch folder, removed at exit: the input file, and problem/, the problems'
/// base directory.
inline const std::string& scratch_directory() {
  static const std::string* path = [] {
    std::string pattern = (std::filesystem::temp_directory_path() / "sdot_fuzz_XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) fail("cannot create a scratch folder");
    std::filesystem::create_directory(pattern + "/problem");
    std::atexit([] {
      std::error_code error;
      std::filesystem::remove_all(scratch_directory(), error);
    });
    return new std::string(pattern);  // never destroyed: the atexit handler above uses it
  }();
  return *path;
}

/// The problems' base directory (empty unless a harness writes a density file into it).
inline std::string problem_directory() {
  return scratch_directory() + "/problem";
}

/// The bytes read as the command reads a problem file (cli::read_json_file); nullopt when they
/// are not JSON (an InputError).
inline std::optional<json> read_json_bytes(const std::uint8_t* data, std::size_t size) {
  const std::string path = scratch_directory() + "/input.json";
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  try {
    return cli::read_json_file(path, "the problem file");
  } catch (const InputError&) {
    return std::nullopt;
  }
}

/// True when a "file" field anywhere names a file outside the scratch folder (an absolute path,
/// or one with ".."): such inputs are skipped, the harness reads no other file.
inline bool names_outside_file(const json& value) {
  if (value.is_array()) {
    for (const auto& item : value)
      if (names_outside_file(item)) return true;
  } else if (value.is_object()) {
    for (const auto& [key, item] : value.items()) {
      if (key == "file" && item.is_string()) {
        const std::string file = item.get<std::string>();
        if (file.empty() || file[0] == '/' || file.find("..") != std::string::npos) return true;
      }
      if (names_outside_file(item)) return true;
    }
  }
  return false;
}

/// Bounds the solver's work: an int `max_iterations` cut (or set when absent) to
/// sdot::fuzz::max_iterations, a mesh density's integer `quadrature_order` in
/// (max_quadrature_order, 64] cut to max_quadrature_order (other values stay, to be rejected).
inline void cap_work(json& problem) {
  const auto it = problem.find("max_iterations");
  if (it == problem.end() || (it->is_number_integer() && it->get<double>() > max_iterations &&
                              it->get<double>() <= std::numeric_limits<int>::max()))
    problem["max_iterations"] = max_iterations;
  const auto density = problem.find("density");
  if (density == problem.end() || !density->is_object()) return;
  const auto order = density->find("quadrature_order");
  if (order != density->end() && order->is_number_integer() && order->get<double>() > max_quadrature_order &&
      order->get<double>() <= 64)
    *order = max_quadrature_order;
}

inline void check_finite(const json& value, const std::string& where) {
  if (value.is_number_float() && !std::isfinite(value.get<double>())) {
    std::fprintf(stderr, "fuzz harness: %s is %g in the result\n", where.c_str(), value.get<double>());
    fail("non-finite number in the result JSON");
  }
  if (value.is_array())
    for (std::size_t i = 0; i < value.size(); ++i) check_finite(value[i], where + "[" + std::to_string(i) + "]");
  if (value.is_object())
    for (const auto& [key, item] : value.items()) check_finite(item, where + "." + key);
}

/// Solves `problem` with the registry, as `sdot solve` does (quiet, with the SVG).
inline void solve_and_check(const json& problem) {
  if (!problem.is_object() || !problem.contains("geometry") || !problem["geometry"].is_string()) return;
  const cli::GeometryCommands* commands = registry().find(problem["geometry"].get<std::string>());
  if (commands == nullptr) return;
  cli::RunContext context;
  context.quiet = true;
  context.want_svg = true;
  context.base_directory = problem_directory();
  cli::SolveOutput output;
  try {
    output = commands->solve(problem, context);
  } catch (const InputError&) {
    return;
  } catch (const json::exception&) {
    return;
  }
  check_finite(output.result, "result");
  (void)output.result.dump(1);  // as the command writes it: no invalid UTF-8
  if (output.svg.find("nan") != std::string::npos || output.svg.find("inf") != std::string::npos)
    fail("NaN or infinity in the SVG");
}

}  // namespace sdot::fuzz
