// sdot-blue-noise: capacity-constrained blue noise on the sphere from an equirectangular image.
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sdot/error.hpp>
#include <sdot/output_file.hpp>
#include <string>

#include "blue_noise.hpp"
#include "pictures.hpp"

using json = nlohmann::json;

namespace {

const char* usage_text =
    "usage: sdot-blue-noise IMAGE --points N [--iterations K] [--seed S] [--interpolation constant|linear]\n"
    "                       [-o POINTS.json] [--png PICTURE.png] [--svg PICTURE.svg] [--quiet]\n"
    "       sdot-blue-noise --synthetic W H --points N [same options]\n"
    "\n"
    "Places N points on the unit sphere with the density of an equirectangular grayscale image\n"
    "(PGM or PNG; column 0 at longitude -180, row 0 at latitude +90): rejection sampling, then\n"
    "Lloyd iterations that alternate equal-mass optimal transport and a move to the cell centroids\n"
    "(capacity-constrained blue noise, de Goes et al. 2012).\n"
    "  --synthetic W H     use a built-in Earth-like W x H image instead of IMAGE\n"
    "  --points N          number of points (at least 4)\n"
    "  --iterations K      Lloyd iterations at most (default 20); fewer when the points stop moving\n"
    "  --seed S            seed of the initial sampling (default 1)\n"
    "  --interpolation     constant (default: each pixel's value on the pixel) or linear\n"
    "  -o FILE             JSON: points, per-iteration log, statistics (default: standard output)\n"
    "  --png FILE          equirectangular picture (grayscale PNG, 1024 x 512)\n"
    "  --svg FILE          Mollweide picture (SVG)\n"
    "  --quiet             no progress output\n"
    "Exit status: 0 success, 2 bad input (the message names it), 3 an OT solve failed, 1 internal error.\n";

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Arguments {
  std::string image_path, output_path, png_path, svg_path;
  int synthetic_width = 0, synthetic_height = 0;
  long long points = -1;
  int iterations = 20;
  std::uint64_t seed = 1;
  sdot::ImageInterpolation interpolation = sdot::ImageInterpolation::constant;
  bool quiet = false;
};

long long parse_integer(const std::string& option, const std::string& text) {
  long long value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size())
    throw UsageError(option + ": needs an integer, got '" + text + "'");
  return value;
}

Arguments parse_arguments(int argc, char** argv) {
  Arguments arguments;
  for (int i = 1; i < argc; ++i) {
    const std::string argument = argv[i];
    auto next = [&](const char* what) -> std::string {
      if (i + 1 >= argc) throw UsageError(argument + ": needs " + what);
      return argv[++i];
    };
    if (argument == "-h" || argument == "--help") {
      std::fputs(usage_text, stdout);
      std::exit(0);
    } else if (argument == "--points") {
      arguments.points = parse_integer(argument, next("a number of points"));
    } else if (argument == "--iterations") {
      const long long iterations = parse_integer(argument, next("a number of iterations"));
      if (iterations < 0 || iterations > 100000)
        throw UsageError("--iterations: must be between 0 and 100000, got " + std::to_string(iterations));
      arguments.iterations = static_cast<int>(iterations);
    } else if (argument == "--seed") {
      const long long seed = parse_integer(argument, next("a seed"));
      if (seed < 0) throw UsageError("--seed: must be a non-negative integer, got " + std::to_string(seed));
      arguments.seed = static_cast<std::uint64_t>(seed);
    } else if (argument == "--interpolation") {
      const std::string kind = next("constant or linear");
      if (kind == "constant")
        arguments.interpolation = sdot::ImageInterpolation::constant;
      else if (kind == "linear")
        arguments.interpolation = sdot::ImageInterpolation::linear;
      else
        throw UsageError("--interpolation: must be constant or linear, got '" + kind + "'");
    } else if (argument == "--synthetic") {
      const long long width = parse_integer(argument, next("a width and a height"));
      const long long height = parse_integer(argument, next("a width and a height"));
      if (width < 3 || height < 2 || width > 20000 || height > 10000)
        throw UsageError("--synthetic: the image needs 3 to 20000 columns and 2 to 10000 rows, got " +
                         std::to_string(width) + " x " + std::to_string(height));
      arguments.synthetic_width = static_cast<int>(width), arguments.synthetic_height = static_cast<int>(height);
    } else if (argument == "-o" || argument == "--output") {
      arguments.output_path = next("a file");
    } else if (argument == "--png") {
      arguments.png_path = next("a file");
    } else if (argument == "--svg") {
      arguments.svg_path = next("a file");
    } else if (argument == "--quiet") {
      arguments.quiet = true;
    } else if (argument.size() > 1 && argument[0] == '-') {
      throw UsageError("unknown option " + argument);
    } else if (arguments.image_path.empty()) {
      arguments.image_path = argument;
    } else {
      throw UsageError("unexpected argument " + argument + " (one IMAGE only)");
    }
  }
  const bool synthetic = arguments.synthetic_width > 0;
  if (arguments.image_path.empty() && !synthetic) throw UsageError("give an IMAGE or --synthetic W H");
  if (!arguments.image_path.empty() && synthetic) throw UsageError("give an IMAGE or --synthetic W H, not both");
  if (arguments.points == -1) throw UsageError("--points N is required");
  // On the whole sphere the points must not lie in one closed hemisphere: 4 at least.
  if (arguments.points < 4 || arguments.points > 10'000'000)
    throw UsageError("--points: must be between 4 and 10000000 (the points must surround the origin), got " +
                     std::to_string(arguments.points));
  return arguments;
}

json statistics_json(const blue_noise::PointSetStatistics& statistics) {
  return {{"nearest_neighbor_min", statistics.nearest_min},
          {"nearest_neighbor_mean", statistics.nearest_mean},
          {"normalized_nearest_neighbor_min", statistics.normalized_min},
          {"normalized_nearest_neighbor_mean", statistics.normalized_mean},
          {"normalized_point_count", statistics.normalized_count},
          {"blocks", statistics.blocks},
          {"block_count_correlation", statistics.count_correlation},
          {"block_count_l1_error", statistics.count_l1_error}};
}

std::string format(const char* pattern, auto... values) {
  char buffer[256];
  std::snprintf(buffer, sizeof buffer, pattern, values...);
  return buffer;
}

std::string describe(const blue_noise::PointSetStatistics& s) {
  return format(
      "nearest neighbour min %.4g mean %.4g rad; / sqrt(cell area): min %.3f mean %.3f; "
      "block counts vs image: correlation %.4f, L1 error %.4f (%d blocks)",
      s.nearest_min, s.nearest_mean, s.normalized_min, s.normalized_mean, s.count_correlation, s.count_l1_error,
      s.blocks);
}

json points_json(const std::vector<blue_noise::Point>& points) {
  json array = json::array();
  for (const auto& p : points) array.push_back({p.x(), p.y(), p.z()});
  return array;
}

json lon_lat_json(const std::vector<blue_noise::Point>& points) {
  json array = json::array();
  for (const auto& p : points)
    array.push_back(
        {blue_noise::longitude(p) * 180 / std::numbers::pi, blue_noise::latitude(p) * 180 / std::numbers::pi});
  return array;
}

}  // namespace

int main(int argc, char** argv) {
  const auto start = std::chrono::steady_clock::now();
  Arguments arguments;
  try {
    arguments = parse_arguments(argc, argv);
  } catch (const UsageError& error) {
    std::fprintf(stderr, "sdot-blue-noise: error: %s\n%s", error.what(), usage_text);
    return 2;
  }
  auto progress = [&](const std::string& line) {
    if (arguments.quiet) return;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::fprintf(stderr, "[%7.2f s] %s\n", elapsed, line.c_str());
  };
  try {
    const bool synthetic = arguments.synthetic_width > 0;
    const std::string image_name = synthetic ? "synthetic image" : arguments.image_path;
    const sdot::GrayImage image =
        synthetic ? blue_noise::synthetic_earth(arguments.synthetic_width, arguments.synthetic_height)
                  : sdot::read_image(arguments.image_path);
    const sdot::Sphere sphere;
    const auto density = sdot::equirectangular_density(sphere, image, arguments.interpolation, 1, image_name);
    const double max_value = *std::max_element(image.values.begin(), image.values.end());
    const int count = static_cast<int>(arguments.points);
    progress(format("%s: %d x %d pixels, mass %.6g, %zu density pieces", image_name.c_str(), image.width, image.height,
                    density.total_mass(), density.piece_count()));

    const auto initial = blue_noise::sample_points(density, max_value, count, arguments.seed);
    progress(format("sampled %d points (seed %llu)", count, static_cast<unsigned long long>(arguments.seed)));

    blue_noise::LloydOptions options;
    options.iterations = arguments.iterations;
    options.progress = [&](const blue_noise::IterationLog& entry) {
      const std::string pulled_back =
          entry.pulled_back > 0 ? format(", %d centroids pulled back into the support", entry.pulled_back) : "";
      progress(
          format("iteration %3d: %s start, %d Newton steps (%s), max relative mass error %.2e, "
                 "mean displacement %.3e rad (max %.3e)%s, %.3f s",
                 entry.iteration, entry.warm_start ? "warm" : "cold", entry.newton_iterations, entry.status.c_str(),
                 entry.max_relative_mass_error, entry.mean_displacement, entry.max_displacement, pulled_back.c_str(),
                 entry.seconds));
    };
    const auto result = blue_noise::lloyd(sphere, density, image, initial, options);
    progress(format("final OT solve: %s, max relative mass error %.2e", result.final_status.c_str(),
                    result.final_max_relative_mass_error));
    progress("initial: " + describe(result.initial));
    progress("final:   " + describe(result.final));

    // Dots are sized from the typical spacing of the final points.
    const double spacing = result.final.nearest_mean;
    if (!arguments.png_path.empty()) {
      blue_noise::write_png_picture(arguments.png_path, image, result.points, spacing);
      progress("wrote " + arguments.png_path);
    }
    if (!arguments.svg_path.empty()) {
      blue_noise::write_svg_picture(arguments.svg_path, image, result.points, spacing);
      progress("wrote " + arguments.svg_path);
    }

    json log = json::array();
    for (const auto& entry : result.log)
      log.push_back({{"iteration", entry.iteration},
                     {"warm_start", entry.warm_start},
                     {"newton_iterations", entry.newton_iterations},
                     {"status", entry.status},
                     {"max_relative_mass_error", entry.max_relative_mass_error},
                     {"mean_displacement", entry.mean_displacement},
                     {"max_displacement", entry.max_displacement},
                     {"pulled_back", entry.pulled_back},
                     {"seconds", entry.seconds}});
    json output = {
        {"image",
         {{"source", synthetic ? "synthetic" : arguments.image_path},
          {"width", image.width},
          {"height", image.height}}},
        {"interpolation", arguments.interpolation == sdot::ImageInterpolation::linear ? "linear" : "constant"},
        {"seed", arguments.seed},
        {"point_count", count},
        {"iterations_requested", arguments.iterations},
        {"density_mass", density.total_mass()},
        {"floor", options.floor},
        {"support_area", result.support_area},
        {"iterations", log},
        {"stopped", result.small_displacement ? "small_displacement" : "iteration_limit"},
        {"final_solve",
         {{"status", result.final_status}, {"max_relative_mass_error", result.final_max_relative_mass_error}}},
        {"statistics", {{"initial", statistics_json(result.initial)}, {"final", statistics_json(result.final)}}},
        {"points", points_json(result.points)},
        {"lon_lat_degrees", lon_lat_json(result.points)},
    };
    if (arguments.output_path.empty()) {
      std::cout << output.dump(1) << "\n";
    } else {
      sdot::write_file_atomically(arguments.output_path, output.dump(1) + "\n");
      progress("wrote " + arguments.output_path);
    }
    return 0;
  } catch (const sdot::InputError& error) {
    // The points follow the image, so sites in one hemisphere mean an image confined to one.
    const char* hint = error.field() == "sites" ? " (the image's density must not lie in one hemisphere)" : "";
    std::fprintf(stderr, "sdot-blue-noise: error: %s%s\n", error.what(), hint);
    return 2;
  } catch (const blue_noise::SolverFailure& error) {
    std::fprintf(stderr, "sdot-blue-noise: error: %s\n", error.what());
    return 3;
  } catch (const std::exception& error) {
    std::fprintf(stderr, "sdot-blue-noise: internal error: %s\n", error.what());
    return 1;
  }
}
