// Tests of the blue-noise example: the library pieces, a small synthetic run of the command
// checked from its JSON output, and bad input.
#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>

#include "blue_noise.hpp"
#include "support/scratch_directory.hpp"

namespace fs = std::filesystem;
using blue_noise::Point;
using json = nlohmann::json;

namespace {

using sdot::testing::read_text;

fs::path scratch() {
  return sdot::testing::scratch_directory("blue_noise_test");
}

/// Runs the command with `arguments`, standard error to `stderr_path`; returns its exit code.
int run(const std::string& arguments, const fs::path& stderr_path) {
  const std::string command = std::string(BLUE_NOISE_COMMAND) + " " + arguments + " 2> " + stderr_path.string();
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// Smallest great-circle distance between two of the points (brute force, independent of the
/// library's Voronoi-based statistics).
double minimal_distance(const std::vector<Point>& points) {
  double minimum = std::numbers::pi;
  for (std::size_t i = 0; i < points.size(); ++i)
    for (std::size_t j = i + 1; j < points.size(); ++j)
      minimum = std::min(minimum, blue_noise::geodesic_distance(points[i], points[j]));
  return minimum;
}

sdot::GrayImage keep_at_least(sdot::GrayImage image, double threshold) {
  for (double& value : image.values)
    if (value < threshold) value = 0;
  return image;
}

double median_of_positive(const sdot::GrayImage& image) {
  std::vector<double> positive;
  for (double value : image.values)
    if (value > 0) positive.push_back(value);
  std::nth_element(positive.begin(), positive.begin() + std::ptrdiff_t(positive.size() / 2), positive.end());
  return positive[positive.size() / 2];
}

}  // namespace

TEST(BlueNoise, SyntheticImageIsEarthLike) {
  const auto image = blue_noise::synthetic_earth(64, 32);
  ASSERT_EQ(image.values.size(), 64u * 32u);
  const auto [low, high] = std::minmax_element(image.values.begin(), image.values.end());
  EXPECT_EQ(*low, 0.0);  // ocean
  EXPECT_LE(*high, 1.0);
  EXPECT_GT(*high, 0.8);
  const auto land = std::count_if(image.values.begin(), image.values.end(), [](double v) { return v > 0; });
  EXPECT_GT(land, 64 * 32 / 5);  // land and ocean both cover a good part of the globe
  EXPECT_LT(land, 64 * 32 * 4 / 5);
  EXPECT_EQ(image.values, blue_noise::synthetic_earth(64, 32).values);  // deterministic
}

TEST(BlueNoise, SamplingIsDeterministicPerSeedAndInsideTheSupport) {
  const sdot::Sphere sphere;
  const auto image = blue_noise::synthetic_earth(64, 32);
  const auto density = sdot::equirectangular_density(sphere, image, sdot::ImageInterpolation::constant);
  const auto first = blue_noise::sample_points(density, 1.0, 200, 7);
  const auto again = blue_noise::sample_points(density, 1.0, 200, 7);
  const auto other = blue_noise::sample_points(density, 1.0, 200, 8);
  ASSERT_EQ(first.size(), 200u);
  EXPECT_EQ(first, again);
  EXPECT_NE(first, other);
  for (const Point& x : first) {
    EXPECT_NEAR(x.norm(), 1, 1e-14);
    EXPECT_GT(density.value(x), 0);
  }
}

TEST(BlueNoise, SyntheticRunSpreadsPointsAndFollowsTheDensity) {
  const fs::path output = scratch() / "points.json", png = scratch() / "points.png", svg = scratch() / "points.svg",
                 log = scratch() / "run.log";
  constexpr int count = 500;
  constexpr std::uint64_t seed = 3;
  const int code = run("--synthetic 64 32 --points 500 --iterations 8 --seed 3 -o " + output.string() + " --png " +
                           png.string() + " --svg " + svg.string() + " --quiet",
                       log);
  ASSERT_EQ(code, 0) << read_text(log);
  const json result = json::parse(read_text(output));

  std::vector<Point> points;
  for (const auto& p : result.at("points"))
    points.emplace_back(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
  ASSERT_EQ(points.size(), std::size_t(count));
  ASSERT_EQ(result.at("lon_lat_degrees").size(), std::size_t(count));

  const sdot::Sphere sphere;
  const auto image = blue_noise::synthetic_earth(64, 32);
  const auto density = sdot::equirectangular_density(sphere, image, sdot::ImageInterpolation::constant);
  for (const Point& x : points) {
    EXPECT_NEAR(x.norm(), 1, 1e-12);
    EXPECT_GT(density.value(x), 0) << "a point where the density is zero: " << x.transpose();
  }

  // Each Lloyd iteration solved OT accurately, and the log has at most the requested length.
  const auto& iterations = result.at("iterations");
  ASSERT_GE(iterations.size(), 1u);
  ASSERT_LE(iterations.size(), 8u);
  for (const auto& entry : iterations) EXPECT_LE(entry.at("max_relative_mass_error").get<double>(), 1e-6);
  EXPECT_LE(result.at("final_solve").at("max_relative_mass_error").get<double>(), 1e-6);

  // Blue noise: the closest pair is much farther apart than in the initial (independent) sample,
  // which the same seed reproduces.
  const auto initial = blue_noise::sample_points(density, 1.0, count, seed);
  const double initial_minimum = minimal_distance(initial), final_minimum = minimal_distance(points);
  EXPECT_GT(final_minimum, 2 * initial_minimum);
  const auto& statistics = result.at("statistics");
  EXPECT_NEAR(statistics.at("initial").at("nearest_neighbor_min").get<double>(), initial_minimum, 1e-12);
  EXPECT_NEAR(statistics.at("final").at("nearest_neighbor_min").get<double>(), final_minimum, 1e-12);
  EXPECT_GT(statistics.at("final").at("normalized_nearest_neighbor_mean").get<double>(),
            statistics.at("initial").at("normalized_nearest_neighbor_mean").get<double>());

  // The high-density half of the sphere (the northern hemisphere holds 71% of the mass) gets its
  // share of the points: the capacity-constrained points match it to within 1.5 points (measured
  // for seeds 1 to 6), where the independent initial sample (seed 3) is off by 29 points.
  sdot::GrayImage north = image;
  std::fill(north.values.begin() + std::ptrdiff_t(north.values.size() / 2), north.values.end(), 0.0);
  const double north_mass_fraction =
      sdot::equirectangular_density(sphere, north, sdot::ImageInterpolation::constant).total_mass() /
      density.total_mass();
  ASSERT_GT(north_mass_fraction, 0.6);
  const double north_point_fraction =
      double(std::count_if(points.begin(), points.end(), [](const Point& x) { return x.z() > 0; })) / count;
  EXPECT_NEAR(north_point_fraction, north_mass_fraction, 0.005);

  // Inside the land too: the denser half of the land's pixels (values at or above the median
  // positive value) gets the share of the points its mass asks for. The tolerance is wider: at
  // 64 x 32 pixels the region's staircase boundary is crossed by ~100 cells (measured
  // deviations 0.006 to 0.029 over seeds 1 to 6; 0.003 at 128 x 64 pixels).
  const double threshold = median_of_positive(image);
  const auto dense_half =
      sdot::equirectangular_density(sphere, keep_at_least(image, threshold), sdot::ImageInterpolation::constant);
  const double dense_mass_fraction = dense_half.total_mass() / density.total_mass();
  const double dense_point_fraction =
      double(
          std::count_if(points.begin(), points.end(), [&](const Point& x) { return density.value(x) >= threshold; })) /
      count;
  EXPECT_NEAR(dense_point_fraction, dense_mass_fraction, 0.04);

  // The pictures exist; the PNG has dark dots over a light background.
  const auto picture = sdot::read_image(png.string());
  EXPECT_EQ(picture.width, 1024);
  EXPECT_EQ(picture.height, 512);
  const auto dark = std::count_if(picture.values.begin(), picture.values.end(), [](double v) { return v < 0.2; });
  EXPECT_GT(dark, count);
  EXPECT_NE(read_text(svg).find("<circle"), std::string::npos);
}

TEST(BlueNoise, BadInputIsExitCodeTwoWithAReason) {
  const fs::path log = scratch() / "bad.log";
  const fs::path missing = scratch() / "no_such_image.pgm";
  EXPECT_EQ(run(missing.string() + " --points 100 --quiet", log), 2);
  EXPECT_NE(read_text(log).find("no_such_image.pgm"), std::string::npos) << read_text(log);

  const fs::path narrow = scratch() / "narrow.pgm";  // 2 columns: a pixel would span 180°
  std::ofstream(narrow) << "P2\n2 4\n255\n10 20\n30 40\n50 60\n70 80\n";
  EXPECT_EQ(run(narrow.string() + " --points 100 --quiet", log), 2);
  EXPECT_NE(read_text(log).find("at least 3 columns"), std::string::npos) << read_text(log);

  EXPECT_EQ(run("--synthetic 64 32 --points 0 --quiet", log), 2);
  EXPECT_NE(read_text(log).find("--points"), std::string::npos) << read_text(log);

  EXPECT_EQ(run("--synthetic 64 32 --quiet", log), 2);  // no --points
  EXPECT_NE(read_text(log).find("--points"), std::string::npos) << read_text(log);

  EXPECT_EQ(run("--synthetic 64 32 --points 100 --interpolation bilinear --quiet", log), 2);
  EXPECT_NE(read_text(log).find("--interpolation"), std::string::npos) << read_text(log);

  const fs::path black = scratch() / "black.pgm";
  std::ofstream(black) << "P2\n4 2\n255\n0 0 0 0\n0 0 0 0\n";
  EXPECT_EQ(run(black.string() + " --points 100 --quiet", log), 2);
  EXPECT_NE(read_text(log).find("zero everywhere"), std::string::npos) << read_text(log);
}
