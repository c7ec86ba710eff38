#pragma once
/// \file piecewise_density.hpp
/// Densities given as data: ρ defined piece by piece on convex geodesic polygons (the triangles
/// of a mesh, the pixels of an image, the convex parts of a non-convex domain) and zero outside
/// the pieces. One implementation serves every geometry whose geodesics are straight in a
/// projective chart (`ProjectiveGeometry`): the plane, the sphere (central projection) and H²
/// (the Klein model). Cells are intersected with the pieces they overlap, found through a
/// bounding-cap tree (never a scan of all pieces), and each intersection is handed to the
/// geometry's own integration: exact for constant pieces, quadrature for the others.
///
///     auto rho = sdot::mesh_density(sphere, vertices, triangles, values);  // ρ per vertex
///     auto result = sdot::solve(sphere, rho, sites, masses);
///
/// Where ρ vanishes the solver still works as long as the support is connected (see solve()).

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "sdot/cap_tree.hpp"
#include "sdot/density.hpp"
#include "sdot/geometry.hpp"

namespace sdot {

/// A geometry whose cell edges and geodesics are straight in a projective chart: points map to
/// homogeneous 3-vectors (`to_projective`, defined up to a positive factor) and back
/// (`from_projective`), and a geodesic through two points is the plane through the origin
/// spanned by their images. The scale of `to_projective` fixes what "linear" means for a
/// density piece: ρ(x) = Σ λ_k v_k with Σ λ_k R_k ∝ to_projective(x), Σ λ_k = 1, R_k the corners'
/// images (plane: linear in x; sphere: linear on the flat triangle, centrally projected;
/// H²: linear in Klein coordinates).
template <class G>
concept ProjectiveGeometry = Geometry<G> &&
    requires(const G& geometry, const typename G::Point& point, const Eigen::Vector3d& homogeneous) {
  { geometry.to_projective(point) } -> std::convertible_to<Eigen::Vector3d>;
  { geometry.from_projective(homogeneous) } -> std::convertible_to<typename G::Point>;
};

/// How ρ varies over one piece.
enum class PieceKind : std::uint8_t {
  constant,  ///< ρ = values[0] on the piece; integrated exactly
  linear,    ///< a triangle with ρ = values[k] at corner k, linear in the chart; quadrature
  field,     ///< ρ = the density's field function on the piece; quadrature (the piece bounds a
             ///< region where the field is smooth, e.g. one pixel of a bilinear image)
};

/// One piece: a convex geodesic polygon (either orientation, at least 3 vertices, inside an
/// open hemisphere of the chart) and the local form of ρ.
template <class Point>
struct DensityPiece {
  std::vector<Point> polygon;            ///< the vertices, in the geometry's coordinates
  PieceKind kind = PieceKind::constant;  ///< how ρ varies on the piece
  std::array<double, 3> values{};        ///< ρ ≥ 0: values[0] (constant), at corner k (linear)
};

/// ρ defined on interior-disjoint convex pieces, zero elsewhere. A model of `Density<G>`.
/// Thread-safe for concurrent integration.
template <ProjectiveGeometry G>
class PiecewiseDensity {
 public:
  using Point = typename G::Point;  ///< the geometry's point type

  /// Validates the pieces (throws InputError naming `<name>[p]` for a non-finite vertex,
  /// a negative or non-finite value, fewer than 3 vertices, a non-convex polygon, a linear piece
  /// that is not a triangle, a field piece without a field). Degenerate pieces (zero area) are
  /// dropped. `field` is used by pieces of kind `field`; `quadrature_order` (1…64) by linear
  /// and field pieces, raised for large pieces (see piece_order). The pieces' coordinates are interpreted in
  /// `geometry`'s chart.
  PiecewiseDensity(const G& geometry, const std::vector<DensityPiece<Point>>& pieces, ScalarField<Point> field = {},
                   int quadrature_order = 3, std::string name = "density.pieces");

  /// The number of pieces kept (degenerate ones dropped).
  [[nodiscard]] std::size_t piece_count() const { return kinds_.size(); }
  /// ∫ρ over all pieces.
  [[nodiscard]] double total_mass() const;
  /// The base quadrature order of linear and field pieces (see the constructor).
  [[nodiscard]] int quadrature_order() const { return quadrature_order_; }

  /// Mass, first moment and cost of ρ over a cell (the `Density` concept).
  [[nodiscard]] CellIntegrals<Point> integrate_cell(const G& geometry, const Cell<Point>& cell, const Point& site,
                                                    bool with_cost = true) const;
  /// ∫_{[a,b]} ρ / |∇(c_i − c_j)| ds over the pieces the edge crosses. An edge lying along the
  /// common edge of two pieces takes the mean of both sides.
  [[nodiscard]] double facet_weight(const G& geometry, const Point& a, const Point& b, const Point& site_i,
                                    double weight_i, const Point& site_j, double weight_j) const;

  /// Calls visit(piece index, clipped polygon as a cell) for each non-empty intersection of a
  /// cell with a piece (also useful to inspect or draw the density).
  template <class Visit>
  void for_each_overlap(const Cell<Point>& cell, Visit&& visit) const;

  /// The same density times the indicator of a region given as interior-disjoint convex
  /// polygons (e.g. PlaneRegion::convex_pieces() of a domain with holes). Throws InputError
  /// naming `<field>[r]` for an invalid region piece.
  [[nodiscard]] PiecewiseDensity restricted_to(const std::vector<std::vector<Point>>& region,
                                               const std::string& field = "domain.pieces") const;

  /// ρ at a point (0 outside the pieces). Walks the cap tree: for probing, not for integration.
  [[nodiscard]] double value(const Point& x) const;

 private:
  [[nodiscard]] std::span<const Eigen::Vector3d> corners(std::size_t piece) const {
    return {corners_.data() + offsets_[piece], corners_.data() + offsets_[piece + 1]};
  }
  [[nodiscard]] Eigen::Vector3d unit(const Point& x) const { return geometry_.to_projective(x).normalized(); }
  /// Appends a validated piece (unit corners, counter-clockwise); build_index() afterwards.
  void add_unit_piece(const std::vector<Eigen::Vector3d>& polygon, PieceKind kind, double constant,
                      const Eigen::Vector3d& numerator, const Eigen::Vector3d& denominator);
  void build_index();
  /// The quadrature order for a piece. In an affine chart (the plane: `G::affine_chart`) linear
  /// and bilinear ρ make polynomial integrands, and `quadrature_order` (default 3: exact up to
  /// degree 4) is exact. Elsewhere the chart's Jacobian varies across a piece, so large pieces
  /// need more: `quadrature_order` + ⌈18 × the piece's radius in radians⌉ (measured: a Klein
  /// triangle of radius 0.5 needs order 12 for 1e-15; pieces of a 10⁶-triangle sphere mesh,
  /// radius ~2e-3, get order 4, exact to round-off).
  [[nodiscard]] int piece_order(std::size_t piece) const {
    if constexpr (requires { requires G::affine_chart; }) return quadrature_order_;
    return std::min(64, quadrature_order_ + static_cast<int>(std::ceil(18 * cap_radii_[piece])));
  }
  /// The local ρ of a piece at a point.
  [[nodiscard]] double local_value(std::size_t piece, const Point& x) const;
  [[nodiscard]] CellIntegrals<Point> integrate_piece(const G& geometry, std::size_t piece, const Cell<Point>& polygon,
                                                     const Point& site, bool with_cost) const;

  G geometry_;
  std::string name_;
  ScalarField<Point> field_;
  int quadrature_order_ = 5;
  std::vector<Eigen::Vector3d> corners_;  // unit projective corners, counter-clockwise
  std::vector<Eigen::Vector3d> normals_;  // edge k of a piece: n·X ≥ 0 inside
  std::vector<std::uint32_t> offsets_{0};
  std::vector<PieceKind> kinds_;
  std::vector<double> constants_;
  std::vector<Eigen::Vector3d> numerators_, denominators_;  // linear: ρ = a·X / b·X
  std::vector<Eigen::Vector3d> cap_centers_;
  std::vector<double> cap_radii_;
  CapTree tree_;  // over the pieces' bounding caps
};

/// A triangle mesh: vertices and triangles as vertex-index triples.
template <class Point>
struct TriangleMesh {
  std::vector<Point> vertices;                ///< the vertices, in the geometry's coordinates
  std::vector<std::array<int, 3>> triangles;  ///< vertex indices of each triangle
};

/// Splits every triangle into 4 by its geodesic edge midpoints, `levels` times (shared edges get
/// one midpoint): builds meshes over a domain from a few coarse triangles.
template <ProjectiveGeometry G>
TriangleMesh<typename G::Point> subdivide(const G& geometry, const TriangleMesh<typename G::Point>& mesh, int levels);

/// ρ piecewise linear on a triangle mesh, from its values at the vertices (linear in the
/// geometry's chart, see ProjectiveGeometry). Throws InputError naming `<name>.vertices[i]`,
/// `<name>.triangles[t]` (index out of range, larger than a hemisphere) or `<name>.values[i]`
/// (negative, not finite, wrong count). Triangles of zero area (also repeated vertices) are
/// dropped. Triangles must not overlap.
template <ProjectiveGeometry G>
PiecewiseDensity<G> mesh_density(const G& geometry, std::span<const typename G::Point> vertices,
                                 std::span<const std::array<int, 3>> triangles, std::span<const double> vertex_values,
                                 int quadrature_order = 5, const std::string& name = "density");

/// ρ constant on each triangle of a mesh (one value per triangle), integrated exactly.
template <ProjectiveGeometry G>
PiecewiseDensity<G> mesh_density_per_triangle(const G& geometry, std::span<const typename G::Point> vertices,
                                              std::span<const std::array<int, 3>> triangles,
                                              std::span<const double> triangle_values,
                                              const std::string& name = "density");

}  // namespace sdot

#include "sdot/detail/piecewise_density_impl.hpp"
