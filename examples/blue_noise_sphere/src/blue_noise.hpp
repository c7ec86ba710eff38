#pragma once
/// \file blue_noise.hpp
/// Capacity-constrained blue noise on the sphere ("Blue noise through optimal transport",
/// de Goes et al. 2012): points that each carry the same share of an image density and sit at
/// the centroids of their optimal-transport cells. Lloyd iterations alternate an OT solve with
/// equal masses (sdot::solve on the sphere) and a move of every point to its cell's centroid.

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <optional>
#include <sdot/geometries/sphere.hpp>
#include <sdot/geometries/sphere_densities.hpp>
#include <sdot/image.hpp>
#include <sdot/options.hpp>
#include <stdexcept>
#include <string>
#include <vector>

namespace blue_noise {

using Point = Eigen::Vector3d;
using SphereDensity = sdot::PiecewiseDensity<sdot::Sphere>;

/// A deterministic "Earth-like" equirectangular image (`width` ≥ 3, `height` ≥ 2): smooth
/// continents whose values vary in (0, 1] over an ocean of exactly 0. The land is spread over
/// the whole globe (from the Arctic to an Antarctic cap), so the points never lie in one
/// hemisphere. The same size always gives the same image.
[[nodiscard]] sdot::GrayImage synthetic_earth(int width, int height);

/// Longitude and latitude of a unit vector, in radians (longitude in [−π, π]).
[[nodiscard]] double longitude(const Point& x);
[[nodiscard]] double latitude(const Point& x);
/// Great-circle distance between two unit vectors (accurate for close points too).
[[nodiscard]] double geodesic_distance(const Point& a, const Point& b);

/// `count` independent points with probability proportional to the density: uniform points on
/// the sphere accepted with probability ρ(x) / `max_value` (rejection sampling). The same seed
/// gives the same points on every platform (the generator's raw bits are converted by hand, not
/// through std:: distributions). Throws sdot::InputError when the density is zero everywhere.
[[nodiscard]] std::vector<Point> sample_points(const SphereDensity& density, double max_value, int count,
                                               std::uint64_t seed);

/// Quality of a point set relative to its density.
struct PointSetStatistics {
  /// Great-circle distance from each point to its nearest neighbour (radians): min and mean.
  double nearest_min = 0, nearest_mean = 0;
  /// The same distances divided by sqrt(area of the point's OT cell where ρ > 0), the spacing
  /// the point is expected to have (hexagonal packing gives 1.07, independent uniform points
  /// about 0.5 on average and close to 0 at the minimum). Over the `normalized_count` points
  /// whose cell meets the support (a cell may lie where only the OT floor has mass).
  double normalized_min = 0, normalized_mean = 0;
  int normalized_count = 0;
  /// The sphere cut into `blocks` latitude–longitude blocks of pixels; Pearson correlation over
  /// the blocks with positive mass between the number of points in a block and the number it
  /// should receive (N × its share of the image mass), and Σ|observed − expected| / N.
  int blocks = 0;
  double count_correlation = 0;
  double count_l1_error = 0;
};

/// The density of the OT solves: ρ plus a small uniform floor (a model of sdot::Density).
/// Between the continents of an image such as the Earth's, ρ = 0 on whole oceans: no small
/// weight change moves mass across them, the Newton system is singular and the solver fails.
/// A uniform floor connects the support; being uniform it costs one exact integral per cell
/// (a floor on the image's zero pixels would add thousands of pieces to the huge coastal cells).
struct FlooredDensity {
  const SphereDensity& image;
  double floor;

  [[nodiscard]] sdot::CellIntegrals<Point> integrate_cell(const sdot::Sphere& sphere, const sdot::Cell<Point>& cell,
                                                          const Point& site, bool with_cost = true) const {
    auto integrals = image.integrate_cell(sphere, cell, site, with_cost);
    const auto uniform = sphere.integrate(cell, site, with_cost);
    integrals.mass += floor * uniform.mass;
    integrals.first_moment += floor * uniform.first_moment;
    integrals.cost += floor * uniform.cost;
    return integrals;
  }
  [[nodiscard]] double facet_weight(const sdot::Sphere& sphere, const Point& a, const Point& b, const Point& site_i,
                                    double weight_i, const Point& site_j, double weight_j) const {
    return image.facet_weight(sphere, a, b, site_i, weight_i, site_j, weight_j) +
           floor * sphere.facet_weight(a, b, site_i, weight_i, site_j, weight_j);
  }
};

/// Statistics of `points`, whose OT cells (for equal masses) are `cells`. `image` provides the
/// block masses (pixel value × pixel area; the pixels of equirectangular_density).
[[nodiscard]] PointSetStatistics point_set_statistics(const std::vector<Point>& points,
                                                      const std::vector<sdot::Cell<Point>>& cells,
                                                      const SphereDensity& density, const sdot::GrayImage& image);

/// One Lloyd iteration as reported.
struct IterationLog {
  int iteration = 0;
  bool warm_start = false;  ///< the previous weights were the solver's starting point
  int newton_iterations = 0;
  std::string status;  ///< the OT solver's status
  double max_relative_mass_error = 0;
  double mean_displacement = 0;  ///< great-circle distance the points moved (radians), mean
  double max_displacement = 0;
  int pulled_back = 0;  ///< centroids where ρ = 0, replaced by a point of the support
  double seconds = 0;   ///< OT solve + centroid step
};

struct LloydOptions {
  int iterations = 20;
  /// Stop early when the mean displacement falls below this fraction of the mean spacing
  /// sqrt(support area / N).
  double stop_displacement = 1e-3;
  /// Max relative mass error of each OT solve (for the floored density).
  double tolerance = 1e-9;
  /// The uniform floor added to ρ in the OT solves, as a fraction of max ρ (see FlooredDensity):
  /// large enough for a well-conditioned Newton system, small enough to carry a negligible mass.
  double floor = 1e-4;
  /// Called after each iteration (progress output); may be empty.
  std::function<void(const IterationLog&)> progress;
};

struct LloydResult {
  std::vector<Point> points;
  std::vector<IterationLog> log;
  bool small_displacement = false;  ///< stopped early because the points no longer move
  PointSetStatistics initial, final;
  /// The OT solve at the final points (it yields their cells for the statistics).
  std::string final_status;
  double final_max_relative_mass_error = 0;
  double support_area = 0;  ///< area where ρ > 0 (summed over the cells of the first solve)
};

/// An OT solve that stopped without a usable result (not an input error).
class SolverFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Runs Lloyd iterations from `initial` (points where ρ > 0): OT with equal masses for ρ plus
/// the floor, then every point moves to its cell's centroid; a centroid where ρ = 0 (a cell
/// straddling a concave coast, or two continents) is replaced by the last point with ρ > 0 on
/// the arc towards it. `density` is ρ from `image`. Throws sdot::InputError for input
/// the solver rejects (e.g. all points in one hemisphere) and SolverFailure when an OT solve fails
/// (status neither converged nor precision_floor nor iteration_limit).
[[nodiscard]] LloydResult lloyd(const sdot::Sphere& sphere, const SphereDensity& density, const sdot::GrayImage& image,
                                std::vector<Point> initial, const LloydOptions& options);

}  // namespace blue_noise
