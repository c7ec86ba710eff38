#pragma once
/// \file plane.hpp
/// The Euclidean plane E²: cost c(x, y) = |x − y|²/2, weights ψ with cells argmin_i c(x, y_i) − ψ_i
/// (power cells), clipped to a convex polygon source domain (default: the unit square).

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include "sdot/chart_diagram.hpp"
#include "sdot/density.hpp"
#include "sdot/diagram.hpp"

namespace sdot {

/// The Euclidean plane with cost |x − y|²/2 and a convex polygon source domain: a model of
/// `Geometry` and `ProjectiveGeometry` (docs/plane.md). Weights ψ: cell i is
/// {x : |x − y_i|²/2 − ψ_i ≤ |x − y_j|²/2 − ψ_j ∀j}. Sites may lie outside the domain.
class Plane {
 public:
  using Point = Eigen::Vector2d;  ///< a point (x, y) of the plane

  /// The unit square [0, 1]².
  Plane();
  /// The source domain `domain` (already validated by ConvexPolygon).
  explicit Plane(ConvexPolygon domain);

  /// "plane", the geometry's name in problem files and on the command line.
  static constexpr std::string_view name() { return "plane"; }
  /// The projective chart is affine (to_projective is linear in x): polynomial densities make
  /// polynomial integrands, which fixed-order quadrature integrates exactly.
  static constexpr bool affine_chart = true;
  /// The source domain, counter-clockwise.
  [[nodiscard]] const ConvexPolygon& domain() const { return domain_; }

  /// The transport cost c(x, y) = |x − y|²/2.
  [[nodiscard]] static double cost(const Point& x, const Point& y) { return (x - y).squaredNorm() / 2; }
  /// Throws InputError for a non-finite coordinate or a duplicate site (naming both indices).
  void validate_sites(std::span<const Point> sites) const;
  /// ψ_i = (1 − t)|y_i − x₀|²/2: the Voronoi diagram of x₀ + t(y_i − x₀), with x₀ the domain's
  /// centroid and t ≤ 1 chosen so that all those points lie in the domain; every cell is
  /// non-empty, also for sites outside the domain.
  [[nodiscard]] Eigen::VectorXd default_weights(std::span<const Point> sites) const;
  /// `count` points uniform in the domain, drawn from std::mt19937_64(seed) by rejection from its
  /// bounding box (x before y): the sites of `sdot bench` and `python -m sdot.bench`.
  [[nodiscard]] std::vector<Point> uniform_samples(std::size_t count, std::uint64_t seed) const;
  /// The power diagram of the sites with weights ψ, clipped to the domain (one cell per site,
  /// possibly empty); boundary edges carry boundary_label(k) for edge k of domain().
  [[nodiscard]] Diagram<Point> build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights) const;
  /// With `stop_at_empty_cell`, the builder may stop at the first empty cell (see the solver's
  /// line search) and leave the cells it has not built empty.
  [[nodiscard]] Diagram<Point> build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                             bool stop_at_empty_cell) const;

  /// Exact area, first moment and ∫|x − y|²/2 of a polygon, or of a polygon cut by the site's ball
  /// (edges labelled ball_arc_label are arcs around `site`). The cost comes with the second moment
  /// at no extra cost, so it is computed whatever `with_cost`.
  [[nodiscard]] CellIntegrals<Point> integrate(const Cell<Point>& cell, const Point& site, bool with_cost = true) const;
  /// ∫ρ, ∫xρ and (with `with_cost`) ∫|x − y|²/2 ρ over the cell, by triangle_rule(order) on the
  /// triangles of a fan from its first vertex.
  [[nodiscard]] CellIntegrals<Point> integrate(const Cell<Point>& cell, const Point& site,
                                               const ScalarField<Point>& rho, int order, bool with_cost = true) const;
  /// |ab| / |y_i − y_j|.
  [[nodiscard]] double facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                    const Point& site_j, double weight_j) const;
  /// ∫_{[a,b]} ρ ds / |y_i − y_j|.
  [[nodiscard]] double facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                    const Point& site_j, double weight_j, const ScalarField<Point>& rho,
                                    int order) const;
  /// The centroid M / m from the first moment M and mass m.
  [[nodiscard]] Point centroid(const CellIntegrals<Point>& integrals) const {
    return integrals.first_moment / integrals.mass;
  }

  /// Partial transport (sdot/partial.hpp): the part of `cell` within the ball
  /// {x : |x − site|²/2 ≤ weight} of radius √(2·weight), its arcs labelled ball_arc_label.
  [[nodiscard]] Cell<Point> cut_by_ball(const Cell<Point>& cell, const Point& site, double weight) const;
  /// Σ over the cell's ball arcs of ∫ ds / |x − site| = the arcs' angles.
  [[nodiscard]] double arc_weight(const Cell<Point>& cell, const Point& site) const;
  /// √(2·weight) (0 for weight ≤ 0).
  [[nodiscard]] static double ball_radius(double weight) { return weight > 0 ? std::sqrt(2 * weight) : 0; }
  /// area / 2π: the weight whose ball has this area.
  [[nodiscard]] static double ball_weight(double area) { return area / (2 * std::numbers::pi); }
  /// The cell with each ball arc drawn as `pieces` chords (for pictures).
  [[nodiscard]] Cell<Point> with_sampled_arcs(const Cell<Point>& cell, const Point& site, int pieces) const;
  /// Min and max of |x − site|²/2 over a non-empty polygon cell.
  [[nodiscard]] std::pair<double, double> cost_range(const Cell<Point>& cell, const Point& site) const;

  /// The projective chart (see ProjectiveGeometry): ((x − o)/s, 1) with o the domain's centroid
  /// and s its radius, so coordinates are O(1) whatever the domain's position and size. Linear
  /// in x: a "linear" density piece is linear in the plane's coordinates.
  [[nodiscard]] Eigen::Vector3d to_projective(const Point& x) const {
    Eigen::Vector3d result;
    result << (x - chart_origin_) / chart_scale_, 1.0;
    return result;
  }
  /// The inverse of to_projective: o + s·(x₁, x₂)/x₃.
  [[nodiscard]] Point from_projective(const Eigen::Vector3d& x) const {
    return chart_origin_ + chart_scale_ * x.head<2>() / x.z();
  }

 private:
  void set_chart();

  ConvexPolygon domain_;
  Point chart_origin_ = Point::Zero();
  double chart_scale_ = 1;
  // The last diagram's regular triangulation, the start of the next (shared by copies).
  std::shared_ptr<PowerDiagramWarmStart> warm_start_ = make_power_diagram_warm_start();
};

}  // namespace sdot
