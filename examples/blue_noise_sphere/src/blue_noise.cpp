#include "blue_noise.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <sdot/error.hpp>
#include <sdot/solver.hpp>
#include <span>

namespace blue_noise {

namespace {

constexpr double pi = std::numbers::pi;

double degrees_to_radians(double degrees) {
  return degrees * pi / 180;
}

/// One smooth bump of the synthetic relief: a Gaussian in the angle from its centre.
struct Bump {
  double longitude_deg, latitude_deg, radius_deg, height;
};

// Rough stand-ins for the continents, placed like the Earth's so that the land surrounds the
// origin (the whole-sphere OT problem needs points in every hemisphere).
constexpr std::array<Bump, 21> continents{{
    {-100, 46, 16, 1.0}, {-85, 33, 10, 0.8}, {-110, 58, 11, 0.8}, {-152, 63, 7, 0.7},  // North America
    {-42, 72, 6, 0.85},                                                                // Greenland
    {-60, -8, 14, 1.0},  {-66, -33, 9, 0.9}, {-71, -47, 5, 0.8},                       // South America
    {18, 6, 16, 1.0},    {12, 22, 13, 0.9},  {28, -20, 10, 0.9},                       // Africa
    {14, 50, 9, 0.8},    {38, 56, 11, 0.8},                                            // Europe
    {90, 48, 18, 1.0},   {110, 30, 14, 0.9}, {78, 21, 7, 0.9},    {125, 60, 11, 0.8},  // Asia
    {134, -25, 11, 1.0}, {146, -34, 5, 0.7},                                           // Australia
    {0, -90, 13, 1.0},   {70, -78, 7, 0.5},                                            // Antarctica
}};

// Mountain ranges / population centres: bumps of the density inside the land.
constexpr std::array<Bump, 9> highlands{{
    {-105, 42, 6, 1.0},  // Rocky Mountains
    {-75, 40, 4, 0.9},   // US east coast
    {-68, -20, 5, 1.0},  // Andes
    {10, 47, 5, 1.0},    // Alps
    {35, 2, 5, 0.8},     // East Africa
    {85, 32, 7, 1.0},    // Tibet
    {117, 32, 5, 0.9},   // eastern China
    {78, 20, 4, 0.9},    // India
    {150, -32, 3, 0.8},  // south-east Australia
}};

double bump_sum(const Point& x, std::span<const Bump> bumps) {
  double sum = 0;
  for (const Bump& bump : bumps) {
    const Point center =
        sdot::from_longitude_latitude(degrees_to_radians(bump.longitude_deg), degrees_to_radians(bump.latitude_deg));
    const double angle = geodesic_distance(x, center), radius = degrees_to_radians(bump.radius_deg);
    sum += bump.height * std::exp(-0.5 * (angle / radius) * (angle / radius));
  }
  return sum;
}

/// The synthetic image's value at a point: 0 in the ocean, in (0, 1] on land.
double synthetic_value(const Point& x) {
  // Relief: continents plus a low-frequency ripple that makes the coastlines irregular. Every
  // term is a smooth function of the 3-D position, so the image has no seam at ±180°.
  const double ripple = 0.12 * std::sin(7 * x.x() + 3 * x.z() + 1.0) * std::cos(6 * x.y() - 2 * x.z() + 0.5) +
                        0.06 * std::sin(13 * x.y() + 5 * x.x());
  const double relief = bump_sum(x, continents) + ripple;
  constexpr double sea_level = 0.5;
  if (relief <= sea_level) return 0;
  // Land: low near the coast, rising inland, with denser highlands.
  const double inland = std::min(1.0, (relief - sea_level) / 0.35);
  const double highland = std::min(1.0, bump_sum(x, highlands));
  return std::clamp(0.15 + 0.35 * inland + 0.5 * highland * inland, 0.0, 1.0);
}

/// A uniform double in [0, 1) from 53 random bits (the same on every platform).
double uniform(std::mt19937_64& generator) {
  return static_cast<double>(generator() >> 11) * 0x1.0p-53;
}

/// The point at parameter t on the great arc from a to b (not at constant speed; a ≠ −b).
Point along_arc(const Point& a, const Point& b, double t) {
  return ((1 - t) * a + t * b).normalized();
}

/// `target` when ρ > 0 there, else the last point with ρ > 0 on the arc from `start` (ρ > 0)
/// towards it. A cell's centroid can fall where ρ = 0 when the cell straddles a concave coast
/// or two continents.
Point inside_support(const SphereDensity& density, const Point& start, const Point& target, bool& pulled_back) {
  pulled_back = !(density.value(target) > 0);
  if (!pulled_back) return target;
  double inside = 0, outside = 1;
  for (int step = 0; step < 40; ++step) {
    const double middle = 0.5 * (inside + outside);
    if (density.value(along_arc(start, target, middle)) > 0)
      inside = middle;
    else
      outside = middle;
  }
  return along_arc(start, target, inside);
}

/// Area of the part of a cell where ρ > 0 (where the density has pieces).
double support_area_in_cell(const sdot::Sphere& sphere, const SphereDensity& density, const sdot::Cell<Point>& cell,
                            const Point& site) {
  double area = 0;
  density.for_each_overlap(
      cell, [&](std::size_t, const sdot::Cell<Point>& part) { area += sphere.integrate(part, site, false).mass; });
  return area;
}

double pearson_correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const auto n = static_cast<double>(a.size());
  if (a.size() < 2) return 0;
  double mean_a = 0, mean_b = 0;
  for (std::size_t k = 0; k < a.size(); ++k) mean_a += a[k] / n, mean_b += b[k] / n;
  double covariance = 0, variance_a = 0, variance_b = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    covariance += (a[k] - mean_a) * (b[k] - mean_b);
    variance_a += (a[k] - mean_a) * (a[k] - mean_a);
    variance_b += (b[k] - mean_b) * (b[k] - mean_b);
  }
  return variance_a > 0 && variance_b > 0 ? covariance / std::sqrt(variance_a * variance_b) : 0;
}

}  // namespace

sdot::GrayImage synthetic_earth(int width, int height) {
  if (width < 3 || height < 2)
    throw sdot::InputError("--synthetic", "the image needs at least 3 columns and 2 rows, got " +
                                              std::to_string(width) + " x " + std::to_string(height));
  sdot::GrayImage image{width, height, {}};
  image.values.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
  for (int row = 0; row < height; ++row)
    for (int column = 0; column < width; ++column) {
      // The value at the pixel centre, as equirectangular_density places pixels.
      const double lon = -pi + (column + 0.5) * 2 * pi / width, lat = pi / 2 - (row + 0.5) * pi / height;
      image.values[static_cast<std::size_t>(row) * static_cast<std::size_t>(width) + static_cast<std::size_t>(column)] =
          synthetic_value(sdot::from_longitude_latitude(lon, lat));
    }
  return image;
}

double longitude(const Point& x) {
  return std::atan2(x.y(), x.x());
}
double latitude(const Point& x) {
  return std::atan2(x.z(), std::hypot(x.x(), x.y()));
}
double geodesic_distance(const Point& a, const Point& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

std::vector<Point> sample_points(const SphereDensity& density, double max_value, int count, std::uint64_t seed) {
  const double acceptance = density.total_mass() / (4 * pi * max_value);
  if (!(max_value > 0) || !(acceptance > 0))
    throw sdot::InputError("image", "the density is zero everywhere (a black image): there is nothing to sample");
  std::mt19937_64 generator(seed);
  std::vector<Point> points;
  points.reserve(static_cast<std::size_t>(count));
  // Expected trials: count / acceptance; a hundred times that means something is wrong.
  const double max_trials = 100 * count / acceptance + 1e6;
  for (double trial = 0; static_cast<int>(points.size()) < count; ++trial) {
    if (trial > max_trials) throw sdot::InputError("image", "rejection sampling accepts almost no point");
    const double z = 2 * uniform(generator) - 1, lon = 2 * pi * uniform(generator) - pi;
    const double r = std::sqrt(std::max(0.0, 1 - z * z));
    const Point x(r * std::cos(lon), r * std::sin(lon), z);
    if (uniform(generator) * max_value < density.value(x)) points.push_back(x);
  }
  return points;
}

PointSetStatistics point_set_statistics(const std::vector<Point>& points, const std::vector<sdot::Cell<Point>>& cells,
                                        const SphereDensity& density, const sdot::GrayImage& image) {
  const sdot::Sphere sphere;
  const auto n = static_cast<Eigen::Index>(points.size());
  PointSetStatistics statistics;
  // The nearest neighbour of a point is one of its Voronoi neighbours (zero heights give the
  // Voronoi diagram of the cost −ln⟨x, y⟩, which orders distances like the angle).
  const auto voronoi = sphere.build_diagram(std::span<const Point>(points), Eigen::VectorXd::Zero(n));
  const auto neighbours = sdot::adjacency(voronoi);
  std::vector<double> nearest(points.size()), support_areas(points.size());
#pragma omp parallel for schedule(dynamic, 64)
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    double distance = pi;
    for (int j : neighbours[k]) distance = std::min(distance, geodesic_distance(points[k], points[std::size_t(j)]));
    nearest[k] = distance;
    support_areas[k] = support_area_in_cell(sphere, density, cells[k], points[k]);
  }
  statistics.nearest_min = *std::min_element(nearest.begin(), nearest.end());
  statistics.normalized_min = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < points.size(); ++k) {
    statistics.nearest_mean += nearest[k] / static_cast<double>(n);
    if (support_areas[k] > 0) {
      const double normalized = nearest[k] / std::sqrt(support_areas[k]);
      statistics.normalized_min = std::min(statistics.normalized_min, normalized);
      statistics.normalized_mean += normalized;
      ++statistics.normalized_count;
    }
  }
  if (statistics.normalized_count > 0) {
    statistics.normalized_mean /= statistics.normalized_count;
  } else {
    statistics.normalized_min = 0;
  }

  // Point counts per block of pixels against the counts the image asks for. About 16 points per
  // block of the support: the blocks resolve the density without drowning in counting noise.
  const double dlon = 2 * pi / image.width, dlat = pi / image.height;
  std::vector<double> pixel_mass(image.values.size());
  double total_mass = 0, land_area = 0;
  for (int row = 0; row < image.height; ++row) {
    const double area = dlon * (std::sin(pi / 2 - row * dlat) - std::sin(pi / 2 - (row + 1) * dlat));
    for (int column = 0; column < image.width; ++column) {
      const auto pixel = static_cast<std::size_t>(row * image.width + column);
      pixel_mass[pixel] = image.values[pixel] * area;
      total_mass += pixel_mass[pixel];
      if (image.values[pixel] > 0) land_area += area;
    }
  }
  const double blocks_wanted = static_cast<double>(n) / 16 / std::max(land_area / (4 * pi), 1e-3);
  const int block_rows = std::clamp(static_cast<int>(std::lround(std::sqrt(blocks_wanted / 2))), 1, image.height);
  const int block_columns = std::clamp(2 * block_rows, 1, image.width);
  auto block_of_pixel = [&](int row, int column) {
    return (row * block_rows / image.height) * block_columns + column * block_columns / image.width;
  };
  std::vector<double> expected(static_cast<std::size_t>(block_rows * block_columns)), observed(expected.size());
  for (int row = 0; row < image.height; ++row)
    for (int column = 0; column < image.width; ++column)
      expected[std::size_t(block_of_pixel(row, column))] +=
          static_cast<double>(n) * pixel_mass[std::size_t(row * image.width + column)] / total_mass;
  for (const Point& x : points) {
    const int column = std::clamp(static_cast<int>(std::floor((longitude(x) + pi) / dlon)), 0, image.width - 1);
    const int row = std::clamp(static_cast<int>(std::floor((pi / 2 - latitude(x)) / dlat)), 0, image.height - 1);
    observed[std::size_t(block_of_pixel(row, column))] += 1;
  }
  std::vector<double> expected_counts, observed_counts;
  for (std::size_t b = 0; b < expected.size(); ++b) {
    statistics.count_l1_error += std::abs(observed[b] - expected[b]) / static_cast<double>(n);
    if (expected[b] > 0) expected_counts.push_back(expected[b]), observed_counts.push_back(observed[b]);
  }
  statistics.blocks = static_cast<int>(expected_counts.size());
  statistics.count_correlation = pearson_correlation(observed_counts, expected_counts);
  return statistics;
}

LloydResult lloyd(const sdot::Sphere& sphere, const SphereDensity& density, const sdot::GrayImage& image,
                  std::vector<Point> initial, const LloydOptions& options) {
  using Clock = std::chrono::steady_clock;
  const double maximum = *std::max_element(image.values.begin(), image.values.end());
  const FlooredDensity transport{density, options.floor * maximum};
  LloydResult result;
  std::vector<Point>& sites = result.points;
  sites = std::move(initial);
  const std::size_t n = sites.size();
  const Eigen::VectorXd masses = sdot::equal_masses(n, density.total_mass() + transport.floor * 4 * pi);
  sdot::Options solver_options;
  solver_options.tolerance = options.tolerance;
  std::optional<Eigen::VectorXd> previous_weights;

  // Solves OT at the current sites, from the previous weights when they leave no cell empty
  // (the solver requires non-empty starting cells; a warm start saves most Newton steps).
  auto solve = [&](bool& warm_start) {
    warm_start = false;
    if (previous_weights) {
      const auto diagram = sphere.build_diagram(std::span<const Point>(sites), *previous_weights);
      warm_start = std::none_of(diagram.cells.begin(), diagram.cells.end(), [](const auto& c) { return c.empty(); });
    }
    auto solution = sdot::solve(sphere, transport, std::span<const Point>(sites), masses, solver_options,
                                warm_start ? previous_weights : std::nullopt);
    const auto status = solution.summary.status;
    if (!solution.summary.usable() && status != sdot::Status::iteration_limit)
      throw SolverFailure("the OT solve failed: " + solution.summary.message);
    previous_weights = solution.weights;
    return solution;
  };
  auto support_area_of = [&](const auto& solution) {
    double area = 0;
    for (std::size_t i = 0; i < n; ++i)
      area += support_area_in_cell(sphere, density, solution.diagram.cells[i], sites[i]);
    return area;
  };

  double mean_spacing = 0;
  for (int iteration = 1; iteration <= options.iterations; ++iteration) {
    const auto start = Clock::now();
    IterationLog entry;
    entry.iteration = iteration;
    const auto solution = solve(entry.warm_start);
    entry.newton_iterations = solution.summary.iterations;
    entry.status = std::string(sdot::to_string(solution.summary.status));
    entry.max_relative_mass_error = solution.summary.max_relative_error;
    double statistics_seconds = 0;  // not part of the iteration's time
    if (iteration == 1) {
      const auto statistics_start = Clock::now();
      result.initial = point_set_statistics(sites, solution.diagram.cells, density, image);
      result.support_area = support_area_of(solution);
      mean_spacing = std::sqrt(result.support_area / static_cast<double>(n));
      statistics_seconds = std::chrono::duration<double>(Clock::now() - statistics_start).count();
    }
    for (std::size_t i = 0; i < n; ++i) {
      bool pulled_back = false;
      const Point moved = inside_support(density, sites[i], solution.centroids[i], pulled_back);
      const double displacement = geodesic_distance(sites[i], moved);
      entry.mean_displacement += displacement / static_cast<double>(n);
      entry.max_displacement = std::max(entry.max_displacement, displacement);
      entry.pulled_back += pulled_back ? 1 : 0;
      sites[i] = moved;
    }
    entry.seconds = std::chrono::duration<double>(Clock::now() - start).count() - statistics_seconds;
    result.log.push_back(entry);
    if (options.progress) options.progress(entry);
    if (entry.mean_displacement < options.stop_displacement * mean_spacing) {
      result.small_displacement = true;
      break;
    }
  }

  bool warm_start = false;
  const auto final_solution = solve(warm_start);
  result.final_status = std::string(sdot::to_string(final_solution.summary.status));
  result.final_max_relative_mass_error = final_solution.summary.max_relative_error;
  result.final = point_set_statistics(sites, final_solution.diagram.cells, density, image);
  if (result.log.empty()) {  // no iteration: the final points are the initial ones
    result.initial = result.final;
    result.support_area = support_area_of(final_solution);
  }
  return result;
}

}  // namespace blue_noise
