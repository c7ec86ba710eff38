// The sdot command: solve a problem file, run the benchmark, or run the demo.
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "common.hpp"
#include "registry.hpp"
#include "sdot/detail/runtime_settings.hpp"
#include "sdot/output_file.hpp"

namespace {

using sdot::cli::json;

constexpr const char* usage_text =
    "usage:\n"
    "  sdot solve PROBLEM.json [-o RESULT.json] [--svg DIAGRAM.svg] [--quiet]\n"
    "  sdot bench --geometry NAME --n N [--seed S] [--tolerance T] [--linear-solver auto|ldlt|cg|cholmod|multigrid]\n"
    "             [--density-triangles T] [--quiet]\n"
    "  sdot demo [--out DIR] [--quiet]\n"
    "  sdot --help | --version\n"
    "exit codes: 0 success, 1 internal error, 2 bad input or usage, 3 the solver did not converge\n";

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Atomically (sdot::write_file_atomically): a failed or killed run leaves the previous file intact.
void write_file(const std::filesystem::path& path, const std::string& content) {
  std::error_code error;
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), error);
  if (error) throw sdot::InputError(path.string(), "cannot write: " + error.message());
  sdot::write_file_atomically(path.string(), content);
}

const sdot::cli::GeometryCommands& find_geometry(const sdot::cli::Registry& registry, const json& name_value) {
  if (!name_value.is_string()) throw sdot::InputError("geometry", "must be a string");
  const std::string name = name_value.get<std::string>();
  if (const auto* commands = registry.find(name)) return *commands;
  std::string known;
  for (const auto& n : registry.names()) known += (known.empty() ? "" : ", ") + n;
  throw sdot::InputError("geometry", "unknown geometry '" + name + "' (known: " + known + ")");
}

std::string next_argument(int& i, int argc, char** argv) {
  if (i + 1 >= argc) throw UsageError(std::string(argv[i]) + " needs a value");
  return argv[++i];
}

int run_solve(const sdot::cli::Registry& registry, int argc, char** argv) {
  std::string problem_path, result_path, svg_path;
  sdot::cli::RunContext context;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "-o" || arg == "--output")
      result_path = next_argument(i, argc, argv);
    else if (arg == "--svg")
      svg_path = next_argument(i, argc, argv);
    else if (arg == "--quiet" || arg == "-q")
      context.quiet = true;
    else if (!arg.empty() && arg[0] == '-')
      throw UsageError("unknown option " + arg);
    else if (problem_path.empty())
      problem_path = arg;
    else
      throw UsageError("more than one problem file");
  }
  if (problem_path.empty()) throw UsageError("solve needs a PROBLEM.json");
  const json problem = sdot::cli::read_json_file(problem_path, "the problem file");
  context.base_directory = std::filesystem::path(problem_path).parent_path().string();
  if (!problem.is_object()) throw sdot::InputError(problem_path, "the problem must be a JSON object");
  if (!problem.contains("geometry")) throw sdot::InputError("geometry", "missing (e.g. \"plane\")");
  const auto& commands = find_geometry(registry, problem["geometry"]);
  if (problem.contains("sites") && problem["sites"].is_array())
    sdot::cli::use_malloc_policy_for(problem["sites"].size());
  context.want_svg = !svg_path.empty();
  const auto output = commands.solve(problem, context);
  const std::string text = output.result.dump(1) + "\n";
  if (result_path.empty())
    std::cout << text;
  else
    write_file(result_path, text);
  if (!svg_path.empty()) write_file(svg_path, output.svg);
  if (!context.quiet) std::fprintf(stderr, "%s\n", output.result["message"].get<std::string>().c_str());
  return output.converged ? 0 : 3;
}

int run_bench(const sdot::cli::Registry& registry, int argc, char** argv) {
  sdot::cli::BenchRequest request;
  std::string geometry;
  bool have_n = false;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    auto number = [&](const std::string& value) {
      std::size_t used = 0;
      double x = 0;
      try {
        x = std::stod(value, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != value.size() || !std::isfinite(x)) throw UsageError(arg + " needs a number, got '" + value + "'");
      return x;
    };
    if (arg == "--geometry")
      geometry = next_argument(i, argc, argv);
    else if (arg == "--n") {
      const double n = number(next_argument(i, argc, argv));
      if (n < 1 || n != std::floor(n)) throw UsageError("--n must be a positive integer");
      request.n = static_cast<std::size_t>(n);
      have_n = true;
    } else if (arg == "--seed")
      request.seed = static_cast<unsigned>(number(next_argument(i, argc, argv)));
    else if (arg == "--tolerance") {
      request.tolerance = number(next_argument(i, argc, argv));
      if (!(request.tolerance > 0)) throw UsageError("--tolerance must be positive");
    } else if (arg == "--density-triangles") {
      const double t = number(next_argument(i, argc, argv));
      if (t < 1 || t != std::floor(t)) throw UsageError("--density-triangles must be a positive integer");
      request.density_triangles = static_cast<std::size_t>(t);
    } else if (arg == "--linear-solver")
      request.linear_solver = next_argument(i, argc, argv);
    else if (arg == "--quiet" || arg == "-q")
      request.quiet = true;
    else
      throw UsageError("unknown option " + arg);
  }
  if (geometry.empty() || !have_n) throw UsageError("bench needs --geometry NAME and --n N");
  const auto& commands = find_geometry(registry, json(geometry));
  sdot::cli::use_malloc_policy_for(request.n);
  const json line = commands.bench(request);
  std::cout << line.dump() << std::endl;
  return line["status"] == "converged" || line["status"] == "precision_floor" ? 0 : 3;
}

int run_demo(const sdot::cli::Registry& registry, int argc, char** argv) {
  std::filesystem::path out_dir = "out";
  sdot::cli::RunContext context;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--out")
      out_dir = next_argument(i, argc, argv);
    else if (arg == "--quiet" || arg == "-q")
      context.quiet = true;
    else
      throw UsageError("unknown option " + arg);
  }
  context.want_svg = true;
  int status = 0;
  for (const auto& name : registry.names()) {
    const auto* commands = registry.find(name);
    if (!commands->demo_problem) continue;
    const json problem = commands->demo_problem();
    write_file(out_dir / (name + "_problem.json"), problem.dump(1) + "\n");
    if (!context.quiet) std::fprintf(stderr, "demo: %s, %zu sites\n", name.c_str(), problem["sites"].size());
    const auto output = commands->solve(problem, context);
    write_file(out_dir / (name + "_result.json"), output.result.dump(1) + "\n");
    write_file(out_dir / (name + "_diagram.svg"), output.svg);
    std::fprintf(stderr, "demo: %s: %s -> %s\n", name.c_str(), output.result["message"].get<std::string>().c_str(),
                 (out_dir / (name + "_diagram.svg")).string().c_str());
    if (!output.converged) status = 3;
  }
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  // Huge pages on the heap: sdot bench, sphere, 10⁶ sites, 23.4 and 25.0 s -> 13.4 and 13.0 s,
  // peak RSS 953 -> 955 MB (runtime_settings.hpp).
  sdot::detail::rerun_with_runtime_settings(argv, "SDOT_COMMAND_REEXEC", {.heap_huge_pages = true});
  sdot::cli::Registry registry;
  sdot::cli::register_geometries(registry);
  try {
    if (argc < 2) throw UsageError("no command given");
    const std::string command = argv[1];
    if (command == "--help" || command == "-h" || command == "help") {
      std::cout << usage_text;
      return 0;
    }
    if (command == "--version") {
      std::cout << "sdot " SDOT_VERSION "\n";
      return 0;
    }
    if (command == "solve") return run_solve(registry, argc, argv);
    if (command == "bench") return run_bench(registry, argc, argv);
    if (command == "demo") return run_demo(registry, argc, argv);
    throw UsageError("unknown command '" + command + "'");
  } catch (const UsageError& e) {
    std::fprintf(stderr, "sdot: %s\n%s", e.what(), usage_text);
    return 2;
  } catch (const sdot::InputError& e) {
    std::fprintf(stderr, "sdot: error: %s\n", e.what());
    return 2;
  } catch (const json::exception& e) {
    std::fprintf(stderr, "sdot: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sdot: internal error: %s\n", e.what());
    return 1;
  }
}
