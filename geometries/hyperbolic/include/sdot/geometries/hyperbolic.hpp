#pragma once
/// \file hyperbolic.hpp
/// The hyperbolic plane H² (math.md §1–§5), in the hyperboloid model
///   H² = {x ∈ R³ : ⟨x, x⟩_M = −1, x₃ > 0},  ⟨x, y⟩_M = x₁y₁ + x₂y₂ − x₃y₃.
/// Cost c(x, y) = ln(−⟨x, y⟩_M) = ln cosh d(x, y); weights h with cells argmin_i c(x, y_i) − h_i.
/// Cells are bounded by geodesics; in any Klein chart they are straight convex polygons.
///
/// The source is supported on a compact convex geodesic polygon (the domain); sites may lie
/// anywhere in H². The diagram is built in a Klein chart re-centred by a Lorentz boost that
/// maps the domain's centre to the chart origin, so accuracy does not depend on where the
/// domain lies.
///
/// Coordinates (all conversions are exact formulas, see docs/hyperbolic.md):
///   Klein      k ∈ open unit disc:  x = (k, 1) / √(1 − |k|²),        k = (x₁, x₂) / x₃
///   Poincaré   p ∈ open unit disc:  x = (2p, 1 + |p|²) / (1 − |p|²),  p = (x₁, x₂) / (1 + x₃)
///   hyperboloid x itself (checked to satisfy ⟨x, x⟩_M = −1 to 1e−9 relative, then re-projected).

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numbers>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "sdot/chart_diagram.hpp"
#include "sdot/density.hpp"
#include "sdot/diagram.hpp"
#include "sdot/partial.hpp"

namespace sdot {

/// The hyperbolic plane in the hyperboloid model, cost ln cosh d(x, y), a compact convex geodesic
/// polygon as source domain (see the file's description and docs/hyperbolic.md): a model of
/// `Geometry` and `ProjectiveGeometry`. Built from the domain's vertices in any of the three
/// models; there is no default domain (H² has infinite area).
class Hyperbolic {
 public:
  /// A point of the hyperboloid (x₁, x₂, x₃), x₃ > 0, ⟨x, x⟩_M = −1.
  using Point = Eigen::Vector3d;

  /// The coordinate model of input points.
  enum class Model {
    klein,       ///< Klein (Beltrami–Klein) disc, 2 coordinates
    poincare,    ///< Poincaré disc, 2 coordinates
    hyperboloid  ///< the hyperboloid itself, 3 coordinates
  };

  /// The domain, from hyperboloid vertices (either orientation). Throws InputError naming
  /// `domain[k]` for a vertex that is not finite or not on the hyperboloid, and `domain` /
  /// `domain[k]` for fewer than 3 vertices, coincident vertices, a non-convex or a degenerate
  /// polygon.
  explicit Hyperbolic(std::span<const Point> domain);
  /// The domain from vertices in the given model (2 coordinates for Klein and Poincaré,
  /// 3 for the hyperboloid). Throws InputError as above, and for a Klein or Poincaré vertex
  /// on or outside the ideal boundary |k| ≥ 1.
  static Hyperbolic from_model(Model model, std::span<const Eigen::VectorXd> vertices);
  /// The domain from Klein disc vertices; errors as from_model().
  static Hyperbolic from_klein(std::span<const Eigen::Vector2d> vertices);
  /// The domain from Poincaré disc vertices; errors as from_model().
  static Hyperbolic from_poincare(std::span<const Eigen::Vector2d> vertices);
  /// The regular polygon with `sides` vertices at hyperbolic distance `radius` from `center`
  /// (the first vertex in the direction of the chart's x axis at the centre). Throws InputError
  /// naming `sides` (< 3), `radius` (not positive and finite) or `center` (not on the hyperboloid).
  static Hyperbolic regular_polygon(int sides, double radius, const Point& center = Point(0, 0, 1));

  /// "hyperbolic", the geometry's name in problem files and on the command line.
  static constexpr std::string_view name() { return "hyperbolic"; }

  // ---- coordinates -------------------------------------------------------------------
  /// Minkowski form ⟨a, b⟩_M = a₁b₁ + a₂b₂ − a₃b₃.
  static double minkowski(const Point& a, const Point& b) { return a.x() * b.x() + a.y() * b.y() - a.z() * b.z(); }
  /// Hyperbolic distance arccosh(−⟨a, b⟩_M), computed stably for nearby points.
  static double distance(const Point& a, const Point& b);
  /// Klein disc point → hyperboloid. Throws InputError(field) when |k| ≥ 1 or not finite.
  static Point from_klein(const Eigen::Vector2d& k, const std::string& field = "point");
  /// Poincaré disc point → hyperboloid. Throws InputError(field) when |p| ≥ 1 or not finite.
  static Point from_poincare(const Eigen::Vector2d& p, const std::string& field = "point");
  /// Checks a hyperboloid point (finite, x₃ > 0, ⟨x, x⟩_M = −1 to 1e−9 relative) and re-projects it.
  static Point from_hyperboloid(const Point& x, const std::string& field = "point");
  /// A point in any model (2 or 3 coordinates as the model requires); InputError(field) for a
  /// wrong number of coordinates and as the model's own conversion.
  static Point from_model(Model model, const Eigen::VectorXd& coordinates, const std::string& field = "point");
  /// Hyperboloid → Klein disc: (x₁, x₂) / x₃.
  static Eigen::Vector2d to_klein(const Point& x) { return x.head<2>() / x.z(); }
  /// Hyperboloid → Poincaré disc: (x₁, x₂) / (1 + x₃).
  static Eigen::Vector2d to_poincare(const Point& x) { return x.head<2>() / (1 + x.z()); }
  /// The point at distance `r` from the origin (0, 0, 1) in direction angle `theta`.
  static Point polar(double r, double theta);
  /// The Lorentz boost (a hyperbolic translation) taking (0, 0, 1) to `center`.
  static Eigen::Matrix3d boost_to(const Point& center);
  /// The inverse of a Lorentz transformation L: J Lᵀ J.
  static Eigen::Matrix3d lorentz_inverse(const Eigen::Matrix3d& l);

  // ---- the Geometry concept ---------------------------------------------------------------
  /// The domain's vertices (counter-clockwise) on the hyperboloid.
  [[nodiscard]] const std::vector<Point>& domain() const { return domain_; }
  /// The chart centre: the domain's vertex sum, normalised onto the hyperboloid.
  [[nodiscard]] const Point& center() const { return center_; }
  /// The Lorentz boost B taking (0, 0, 1) to center() (boost_to(center())).
  [[nodiscard]] const Eigen::Matrix3d& boost() const { return boost_; }
  /// The domain polygon in the re-centred Klein chart (Klein coordinates of B⁻¹x).
  [[nodiscard]] const ConvexPolygon& chart_domain() const { return chart_domain_; }
  /// The hyperbolic area of the domain (exact).
  [[nodiscard]] double domain_area() const;
  /// `count` points uniform in hyperbolic area over the domain (rejection sampling in the
  /// re-centred Klein chart, whose area element is dk / (1 − |k|²)^{3/2}); deterministic per seed.
  [[nodiscard]] std::vector<Point> uniform_samples(std::size_t count, std::uint64_t seed) const;

  /// ln(−⟨x, y⟩_M) = ln cosh d(x, y), computed as ln(1 + ½⟨x − y, x − y⟩_M): accurate for nearby
  /// points too.
  [[nodiscard]] static double cost(const Point& x, const Point& y);
  /// Throws InputError naming `sites[i]` for a non-finite coordinate, a point off the
  /// hyperboloid's upper sheet, or a duplicate site.
  void validate_sites(std::span<const Point> sites) const;
  /// math.md §3 with κ = −1: z_i = Klein coordinates of y_i in the re-centred chart,
  /// h_i = −½ ln(1 − |z_i|²) + ln(1 − τ|z_i|²); then u_i = 2τ z_i / (1 + τ|z_i|²) ∈ W_i, and τ ≤ 1 is
  /// chosen so that every u_i lies inside the domain: every cell is non-empty.
  [[nodiscard]] Eigen::VectorXd default_weights(std::span<const Point> sites) const;
  /// The Laguerre diagram of the sites with weights h over the domain (one cell per site, possibly
  /// empty), built in the re-centred Klein chart; boundary edges carry boundary_label(k) for edge
  /// k of domain().
  [[nodiscard]] Diagram<Point> build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights) const;
  /// With `stop_at_empty_cell`, the builder may stop at the first empty cell (see the solver's
  /// line search) and leave the cells it has not built empty.
  [[nodiscard]] Diagram<Point> build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                             bool stop_at_empty_cell) const;

  /// ρ ≡ 1 (hyperbolic area). Area: hyperbolic Van Oosterom–Strackee over a fan (exact);
  /// first moment ½ Σ_e L_e m_e (exact); cost ∫ ln(−⟨x, y⟩_M) dA by a collapsed Gauss rule on the
  /// centrally projected fan triangles, with an order chosen from the triangle's size
  /// (relative error ≲ 1e−13, see docs/hyperbolic.md).
  [[nodiscard]] CellIntegrals<Point> integrate(const Cell<Point>& cell, const Point& site, bool with_cost = true) const;
  /// ρ a function: order² points per centrally projected fan triangle,
  /// dA = |det(a, b, c)| / (−⟨X, X⟩_M)^{3/2} ds dt.
  [[nodiscard]] CellIntegrals<Point> integrate(const Cell<Point>& cell, const Point& site,
                                               const ScalarField<Point>& rho, int order, bool with_cost = true) const;
  /// ∫_{[a,b]} ds / |∇(c_i − c_j)| = tanh(L/2) (−⟨q_i, a + b⟩_M) / ‖q_i − q_j‖_M, q = e^{−h} y.
  [[nodiscard]] double facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                    const Point& site_j, double weight_j) const;
  /// (1/‖q_i − q_j‖_M) ∫ ρ(x) (−⟨x, q_i⟩_M) ds, Gauss–Legendre in arc length.
  [[nodiscard]] double facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                    const Point& site_j, double weight_j, const ScalarField<Point>& rho,
                                    int order) const;
  /// M / √(−⟨M, M⟩_M).
  [[nodiscard]] Point centroid(const CellIntegrals<Point>& integrals) const;

  /// Partial transport (sdot/partial.hpp): the part of `cell` within the ball
  /// {x : ln(−⟨x, site⟩_M) ≤ weight}, the disc of radius arccosh e^{weight} around the site; its arcs
  /// are labelled ball_arc_label. integrate(cell, site) handles them exactly.
  [[nodiscard]] Cell<Point> cut_by_ball(const Cell<Point>& cell, const Point& site, double weight) const;
  /// Σ over the cell's ball arcs of ∫ ds / |∇c| = cosh r · (the arc's angle), r the ball's radius.
  [[nodiscard]] double arc_weight(const Cell<Point>& cell, const Point& site) const;
  /// arccosh e^{weight} (0 for weight ≤ 0).
  [[nodiscard]] static double ball_radius(double weight) { return weight > 0 ? std::acosh(std::exp(weight)) : 0; }
  /// ln(1 + area/2π): the weight whose ball (a disc of area 2π(cosh r − 1)) has this area.
  [[nodiscard]] static double ball_weight(double area) { return std::log1p(area / (2 * std::numbers::pi)); }
  /// The cell with each ball arc drawn as `pieces` geodesic edges (for pictures).
  [[nodiscard]] Cell<Point> with_sampled_arcs(const Cell<Point>& cell, const Point& site, int pieces) const;
  /// Min and max of ln(−⟨x, site⟩_M) over a non-empty cell.
  [[nodiscard]] std::pair<double, double> cost_range(const Cell<Point>& cell, const Point& site) const;

  /// The projective chart (see ProjectiveGeometry): the re-centred Klein chart in homogeneous
  /// coordinates, B⁻¹x / x₃ (B the boost). Geodesics are planes through the origin; a "linear"
  /// density piece is linear in the (input) Klein coordinates x₁/x₃, x₂/x₃.
  [[nodiscard]] Eigen::Vector3d to_projective(const Point& x) const { return inverse_boost_ * (x / x.z()); }
  /// Any representative (either sign) of a point inside the light cone.
  [[nodiscard]] Point from_projective(const Eigen::Vector3d& x) const {
    const double norm2 = x.z() * x.z() - x.head<2>().squaredNorm();
    return boost_ * (x / std::sqrt(std::max(norm2, 1e-300)) * (x.z() < 0 ? -1.0 : 1.0));
  }

 private:
  Hyperbolic() = default;
  void set_domain(std::vector<Point> vertices);

  std::vector<Point> domain_;
  Point center_ = Point(0, 0, 1);
  Eigen::Matrix3d boost_ = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d inverse_boost_ = Eigen::Matrix3d::Identity();
  ConvexPolygon chart_domain_;
  // The last diagram's triangulation (of the sites' Klein points, which the weights do not move),
  // shared by copies; the next build reaches its own from it by flips.
  std::shared_ptr<PowerDiagramWarmStart> warm_start_ = make_power_diagram_warm_start();
};

}  // namespace sdot
