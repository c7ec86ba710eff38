#pragma once
// The sdot command's geometry registry: each geometry folder's cli/ adapter registers how to
// solve a JSON problem, run the benchmark and run its part of the demo.

#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace sdot::cli {

struct RunContext {
  bool quiet = false;
  bool want_svg = false;
  std::string base_directory;  ///< relative file names in a problem are relative to it
};

struct SolveOutput {
  nlohmann::json result;
  std::string svg;  // empty unless RunContext::want_svg
  bool converged = false;
};

struct BenchRequest {
  std::size_t n = 1000;
  unsigned seed = 1;
  double tolerance = 1e-6;
  bool quiet = false;
  std::string linear_solver = "auto";  // "auto", "ldlt", "cg" or "cholmod"
  /// > 0: a smooth piecewise-linear mesh density with about this many triangles instead of the
  /// uniform density (measures the density machinery).
  std::size_t density_triangles = 0;
};

struct GeometryCommands {
  /// Solves a problem file's JSON (already parsed); throws sdot::InputError on bad input.
  std::function<SolveOutput(const nlohmann::json& problem, const RunContext& context)> solve;
  /// Runs the benchmark problem and returns its JSON line.
  std::function<nlohmann::json(const BenchRequest& request)> bench;
  /// A built-in example problem for `sdot demo`.
  std::function<nlohmann::json()> demo_problem;
};

class Registry {
 public:
  void add(const std::string& name, GeometryCommands commands) { commands_[name] = std::move(commands); }
  [[nodiscard]] const GeometryCommands* find(const std::string& name) const {
    auto it = commands_.find(name);
    return it == commands_.end() ? nullptr : &it->second;
  }
  [[nodiscard]] std::vector<std::string> names() const {
    std::vector<std::string> result;
    for (const auto& [name, commands] : commands_) result.push_back(name);
    return result;
  }

 private:
  std::map<std::string, GeometryCommands> commands_;
};

/// Defined in the generated registered_geometries.cpp: calls every geometry's register_NAME.
void register_geometries(Registry& registry);

}  // namespace sdot::cli
