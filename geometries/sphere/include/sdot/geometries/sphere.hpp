#pragma once
/// \file sphere.hpp
/// The unit sphere S² with the cost of Cui et al. (and of the reflector / Alexandrov problems):
/// c(x, y) = −ln⟨x, y⟩ (+∞ when ⟨x, y⟩ ≤ 0). Weights are the paper's heights h_i
/// (h_i = −ln cos r_i); the cell of site p_i is
///
///     W_i = {x : e^{h_i}⟨x, p_i⟩ ≥ e^{h_j}⟨x, p_j⟩ ∀j},
///
/// the radial projection of the face of P* = ∩{x : ⟨x, q_i⟩ ≤ 1}, q_i = e^{h_i} p_i (math.md §1).
///
/// Source domain: the whole sphere (default), a spherical cap or a convex spherical polygon.
/// Cells are convex spherical polygons: vertices are unit 3-vectors, counter-clockwise seen from
/// outside the sphere; edges are great-circle arcs, except the edges of a cap cell labelled with
/// a boundary label, which are arcs of the cap's boundary circle (each spanning at most 90°
/// around the cap's centre). Sites are 3-vectors, normalised on input.
///
/// On the whole sphere the sites must not all lie in one closed hemisphere (0 must be strictly
/// inside their convex hull), otherwise some cell is unbounded; `validate_sites` rejects that.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numbers>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include "sdot/chart_diagram.hpp"
#include "sdot/density.hpp"
#include "sdot/diagram.hpp"
#include "sdot/partial.hpp"

namespace sdot {

/// The unit sphere with the cost −ln⟨x, y⟩ and heights h as weights (see the file's description
/// and docs/sphere.md): a model of `Geometry` and `ProjectiveGeometry`. The source domain is the
/// whole sphere, a cap or a convex spherical polygon.
class Sphere {
 public:
  using Point = Eigen::Vector3d;  ///< a point of the sphere as a unit vector of R³

  /// The kind of source domain.
  enum class Domain {
    sphere,  ///< the whole sphere
    cap,     ///< a spherical cap (cap())
    polygon  ///< a convex spherical polygon (polygon())
  };
  /// How the whole-sphere diagram is built (both give the same cells up to rounding).
  enum class Builder {
    automatic,  ///< the default: currently `hull`
    clipping,   ///< per-cell clipping by the nearest sites, completed and certified with a kd-tree
                ///< query at each cell vertex (exact for any heights; no Qhull)
    hull,       ///< 3-D convex hull of q_i = e^{h_i}p_i (grown by insertion and flips, then updated
                ///< from the object's previous hull; Qhull when that fails), then per-cell clipping by
                ///< hull neighbours
  };

  /// The whole sphere.
  Sphere() = default;
  /// The cap {x : ⟨x, center⟩ ≥ cos angle}, 0 < angle < π/2 (`center` is normalised). Throws
  /// InputError naming `domain.center` (zero or not finite) or `domain.angle` (out of range).
  static Sphere cap(const Point& center, double angle);
  /// The convex spherical polygon with these vertices (either orientation, great-circle edges),
  /// lying in an open hemisphere. Throws InputError naming the vertex.
  static Sphere polygon(std::vector<Point> vertices);

  /// "sphere", the geometry's name in problem files and on the command line.
  static constexpr std::string_view name() { return "sphere"; }
  /// Which kind of source domain this is.
  [[nodiscard]] Domain domain() const { return domain_; }
  /// Cap centre, or the centre of the polygon's chart (normalised vertex sum).
  [[nodiscard]] const Point& center() const { return center_; }
  /// The cap's angular radius in radians (0 for the other domains).
  [[nodiscard]] double cap_angle() const { return angle_; }
  /// Polygon vertices, counter-clockwise seen from outside.
  [[nodiscard]] const std::vector<Point>& polygon_vertices() const { return vertices_; }
  /// Area of the source domain (4π for the whole sphere).
  [[nodiscard]] double domain_area() const;

  /// Chooses how whole-sphere diagrams are built (caps and polygons have a single builder).
  void set_builder(Builder builder) { builder_ = builder; }
  /// The builder named "automatic", "clipping" or "hull"; InputError (field `builder`) otherwise.
  static Builder builder_from_name(std::string_view name);
  /// The whole-sphere builder in use (see set_builder()).
  [[nodiscard]] Builder builder() const { return builder_; }

  /// −ln⟨x, y⟩ of the normalised x and y (+∞ when ⟨x, y⟩ ≤ 0); accurate for nearby points.
  [[nodiscard]] static double cost(const Point& x, const Point& y);
  /// Throws InputError for a zero vector, a non-finite coordinate or a duplicate (after
  /// normalisation) naming the site, and for sites that cannot cover the domain: all in a closed
  /// hemisphere (whole sphere), or some domain point at distance ≥ π/2 from every site.
  void validate_sites(std::span<const Point> sites) const;
  /// `count` points uniform on the whole sphere (normalised Gaussian triples from
  /// std::mt19937_64(seed)): the sites of `sdot bench` and `python -m sdot.bench`.
  [[nodiscard]] static std::vector<Point> uniform_samples(std::size_t count, std::uint64_t seed);
  /// h = 0 (Voronoi) on the whole sphere; on a cap or polygon, math.md §3 "S²-cap" heights
  /// whose cells are all non-empty (when every site lies in the open hemisphere around center()).
  [[nodiscard]] Eigen::VectorXd default_weights(std::span<const Point> sites) const;
  /// The Laguerre diagram of the sites with heights `weights` over the source domain (one cell
  /// per site, possibly empty), by the builder() on the whole sphere.
  [[nodiscard]] Diagram<Point> build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights) const;
  /// With `stop_at_empty_cell`, the builder may stop once it finds an empty cell and leave the
  /// cells it has not built empty: the solver's line search rejects any step that empties a
  /// cell, so a rejected trial step then costs a fraction of a diagram.
  [[nodiscard]] Diagram<Point> build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                             bool stop_at_empty_cell) const;

  /// Exact area (Van Oosterom–Strackee), exact first moment (edge formula); the cost
  /// ∫ −ln⟨x, p⟩ dA by quadrature (no closed form), accurate to about 1e-13 relative.
  [[nodiscard]] CellIntegrals<Point> integrate(const Cell<Point>& cell, const Point& site, bool with_cost = true) const;
  /// By quadrature over centrally projected fan triangles (`triangle_rule(order)`).
  [[nodiscard]] CellIntegrals<Point> integrate(const Cell<Point>& cell, const Point& site,
                                               const ScalarField<Point>& rho, int order, bool with_cost = true) const;
  /// ∫_{arc ab} 1/|∇(c_i − c_j)| ds = ⟨a_i, (b − a) × n̂⟩ / |a_i − a_j| with a = e^{h}p, exact.
  [[nodiscard]] double facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                    const Point& site_j, double weight_j) const;
  /// (e^{h_i}/|a_i − a_j|) ∫ ρ⟨x, p_i⟩ ds by Gauss–Legendre in arc length.
  [[nodiscard]] double facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                    const Point& site_j, double weight_j, const ScalarField<Point>& rho,
                                    int order) const;
  /// M / |M|.
  [[nodiscard]] Point centroid(const CellIntegrals<Point>& integrals) const {
    return integrals.first_moment.normalized();
  }
  /// The projective chart (see ProjectiveGeometry): x itself; great circles are planes through
  /// the origin. A "linear" density piece is linear on the flat triangle through its corners,
  /// centrally projected (the paper's piecewise-linear μ).
  [[nodiscard]] static Eigen::Vector3d to_projective(const Point& x) { return x; }
  /// The point x / |x| (x ≠ 0).
  [[nodiscard]] static Point from_projective(const Eigen::Vector3d& x) { return x.normalized(); }

  /// True when edge `label` of a cell is an arc of the cap's boundary circle (not a great arc).
  [[nodiscard]] bool is_circle_arc(int label) const { return domain_ == Domain::cap && is_domain_boundary(label); }

  /// Partial transport (sdot/partial.hpp): the part of `cell` within the ball
  /// {x : −ln⟨x, site⟩ ≤ weight}, the cap of angular radius arccos e^{−weight} around the site; its
  /// arcs are labelled ball_arc_label.
  [[nodiscard]] Cell<Point> cut_by_ball(const Cell<Point>& cell, const Point& site, double weight) const;
  /// Σ over the cell's ball arcs of ∫ ds / |∇c| = cos α · (the arc's angle), α the ball's radius.
  [[nodiscard]] double arc_weight(const Cell<Point>& cell, const Point& site) const;
  /// arccos e^{−weight} (0 for weight ≤ 0).
  [[nodiscard]] static double ball_radius(double weight);
  /// −ln(1 − area/2π): the weight whose ball (a cap of area 2π(1 − cos α)) has this area, +∞ from 2π.
  [[nodiscard]] static double ball_weight(double area) {
    return area < 2 * std::numbers::pi ? -std::log1p(-area / (2 * std::numbers::pi)) : INFINITY;
  }
  /// The cell with each ball arc drawn as `pieces` great arcs (for pictures).
  [[nodiscard]] Cell<Point> with_sampled_arcs(const Cell<Point>& cell, const Point& site, int pieces) const;
  /// Min and max of −ln⟨x, site⟩ over a non-empty cell (+∞ when the cell reaches ⟨x, site⟩ ≤ 0).
  [[nodiscard]] std::pair<double, double> cost_range(const Cell<Point>& cell, const Point& site) const;

  /// Points along edge k of a cell (great or small circle), `count` ≥ 2 of them, ends included.
  [[nodiscard]] std::vector<Point> edge_points(const Cell<Point>& cell, std::size_t k, int count) const;

 private:
  Diagram<Point> build_whole_sphere(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                    bool stop_at_empty_cell = false) const;
  Diagram<Point> build_in_chart(std::span<const Point> sites, const Eigen::VectorXd& weights) const;

  /// The hull builder's last triangulation, shared by copies: the next diagram (the next Newton
  /// iterate, heights a little different) starts its flips from it instead of building anew.
  struct HullCache;
  static std::shared_ptr<HullCache> make_hull_cache();
  std::shared_ptr<HullCache> hull_cache_ = make_hull_cache();

  Domain domain_ = Domain::sphere;
  Builder builder_ = Builder::automatic;
  Point center_ = Point::UnitZ();
  double angle_ = 0;
  std::vector<Point> vertices_;
  Eigen::Matrix3d frame_ = Eigen::Matrix3d::Identity();  ///< columns t1, t2, center (right-handed)
  ConvexPolygon chart_domain_;  ///< the domain in the gnomonic chart at center (cap: a bounding square)
};

}  // namespace sdot
