#pragma once
/// \file chart_diagram.hpp
/// The one cell builder shared by all geometries (math.md §1).
///
/// In every geometry, the Laguerre cell of site i is, in a chart with homogeneous coordinates
/// X = (v, 1), the set {v : ⟨X, a_i − a_j⟩ ≥ 0 ∀j} for a dual vector a_i ∈ R³. That is the
/// upper envelope of the affine functions f_i(v) = a_i.x v₁ + a_i.y v₂ + a_i.z, i.e. a planar
/// power diagram. `build_chart_diagram` computes it, restricted to a convex polygon of the chart.
/// Geometries only have to supply the dual vectors and map the chart polygons to their points.

#include <Eigen/Core>
#include <array>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "sdot/diagram.hpp"

namespace sdot {

/// A point or vector of a 2-D chart.
using Vec2 = Eigen::Vector2d;
/// A homogeneous chart vector (v, 1) or a dual vector a_i.
using Vec3 = Eigen::Vector3d;

/// A convex polygon in a 2-D chart, vertices counter-clockwise, validated on construction.
class ConvexPolygon {
 public:
  /// An empty polygon (no vertices); a placeholder to assign a valid polygon to.
  ConvexPolygon() = default;
  /// Validates and stores `vertices` (either orientation; stored counter-clockwise).
  /// Throws InputError naming `field` (e.g. "domain") when a vertex is not finite, there are
  /// fewer than 3 vertices, two consecutive vertices coincide, the polygon is not convex, or
  /// its area is zero.
  explicit ConvexPolygon(std::vector<Vec2> vertices, const std::string& field = "domain");

  /// Axis-aligned rectangle [x0, x1] × [y0, y1]. Throws InputError (field `domain`) when it is
  /// degenerate or not finite.
  static ConvexPolygon rectangle(double x0, double y0, double x1, double y1);

  /// The vertices, counter-clockwise.
  [[nodiscard]] const std::vector<Vec2>& vertices() const { return vertices_; }
  /// The area (shoelace formula).
  [[nodiscard]] double area() const;
  /// The centroid of the polygon's area.
  [[nodiscard]] Vec2 centroid() const;
  /// True when `p` lies inside, on the boundary, or outside by at most the distance `slack`.
  [[nodiscard]] bool contains(const Vec2& p, double slack = 0) const;
  /// Largest distance of a vertex from the origin.
  [[nodiscard]] double radius() const;

 private:
  std::vector<Vec2> vertices_;
};

/// A cell in chart coordinates (see `Cell`).
using ChartCell = Cell<Vec2>;

/// Clips `cell` with the half-plane {v : n·v + offset ≥ 0}; the new edge gets `label`.
void clip(ChartCell& cell, const Vec2& normal, double offset, int label);

/// The convex cell bounded by `count` = normals.size() lines given in counter-clockwise order
/// around it: line k is the boundary of the half-plane {v : normals[k]·v + offsets[k] ≥ 0}, edge k
/// lies on it with label labels[k], and vertex k is where lines k − 1 and k cross. This reads a
/// Laguerre cell off a triangulation (its neighbours around a vertex) without clipping. Returns
/// false, leaving `cell` unspecified, when that is not certain at the working precision:
/// consecutive normals that do not turn counter-clockwise (parallel lines among them), an edge
/// of negative length (a line that does not bound the cell), a vertex outside |v|∞ ≤ `bound`,
/// or fewer than 3 lines. The caller then clips.
bool cell_from_ordered_lines(ChartCell& cell, std::span<const Vec2> normals, std::span<const double> offsets,
                             std::span<const int> labels, double bound);

/// Neighbour candidates for a set of affine functions f_i(v) = a_i·(v, 1), in CSR form:
/// the neighbours of site i are `neighbors[k]` for `offsets[i]` ≤ k < `offsets[i + 1]`
/// (of(i)). Always a superset of
/// the true Laguerre neighbours inside any polygon, computed from the regular triangulation
/// (Qhull, lower hull of the lifted points (a_i.xy / 2, −a_i.z)). Indices ≥ the number of
/// sites are internal helper functions that never win on the domain; builders skip them.
struct Adjacency {
  /// Where each site's list starts in `neighbors`; one entry per site, plus the end.
  std::vector<int> offsets;
  /// The lists of all sites, one after the other.
  std::vector<int> neighbors;
  /// The neighbour candidates of site i.
  [[nodiscard]] std::span<const int> of(std::size_t i) const {
    return {neighbors.data() + offsets[i], neighbors.data() + offsets[i + 1]};
  }
};

/// The last regular triangulation of `build_power_diagram` calls (opaque; thread-safe).
struct PowerDiagramWarmStart;
/// An empty warm start, for a geometry to hold (and share between its copies).
std::shared_ptr<PowerDiagramWarmStart> make_power_diagram_warm_start();

/// How `build_power_diagram` and `build_chart_diagram` find the cells.
enum class PowerDiagramMethod {
  /// `regular_triangulation` when this build has it (`has_regular_triangulation()`), else `kd_tree`.
  automatic,
  /// The neighbours from a 2-D regular triangulation with exact predicates (CGAL), then each cell
  /// clipped from the domain by its neighbours. InputError when the build has no CGAL.
  regular_triangulation,
  /// Built-in, no third-party code: each cell clipped by the sites a kd-tree with per-node weight
  /// bounds finds below the envelope at its vertices (branch and bound), until none is.
  kd_tree,
};

/// True when this build of sdot has the CGAL regular triangulation (CMake option SDOT_WITH_CGAL).
bool has_regular_triangulation();

/// Upper envelope of f_i(v) = a_i·(v, 1) over `domain`: cell i = {v ∈ domain : f_i ≥ f_j ∀j}.
/// Boundary edges are labelled `boundary_label(k)` for domain edge k. `anchors` (optional, one
/// per site) are chart points near each site's cell — e.g. the site's own chart coordinates
/// (Klein point, gnomonic point) — used to organise the kd-tree's search; the cells do not depend
/// on them, only that method's speed does. Default: the power centres a_i.xy, right for the plane.
/// `stop_at_empty_cell`: the builder may stop at the first empty cell and leave the cells it
/// has not built empty (for line searches, which reject any step that empties a cell).
std::vector<ChartCell> build_chart_diagram(std::span<const Vec3> dual, const ConvexPolygon& domain,
                                           std::span<const Vec2> anchors = {}, bool stop_at_empty_cell = false,
                                           PowerDiagramMethod method = PowerDiagramMethod::automatic);

/// The power diagram of centres c_i with power weights w_i (cell i = {v : |v − c_i|² − w_i ≤
/// |v − c_j|² − w_j ∀j}) over `domain`; the same cells as `build_chart_diagram` with
/// a_i = (c_i, (w_i − |c_i|²)/2), computed without cancellation when the caller has w directly.
/// With `stop_at_empty_cell`, only an empty cell among the first `own_cells` stops the build (or
/// a site hidden in the whole plane): the others may be images of those, such as a torus's ghosts,
/// which the domain can cut to nothing while their originals' cells are not empty.
/// `warm_start` (optional, from make_power_diagram_warm_start) keeps the regular triangulation
/// for the next build: when that has the same centres, it starts from it by edge flips (a Newton
/// step changes the weights only), and from scratch where the flips cannot finish. The cells are
/// the same either way. A centre or weight that is not finite (an overflowed trial step) has no
/// diagram: every cell is then empty, which a line search rejects.
std::vector<ChartCell> build_power_diagram(std::span<const Vec2> centers, std::span<const double> power_weights,
                                           const ConvexPolygon& domain, std::span<const Vec2> anchors = {},
                                           bool stop_at_empty_cell = false,
                                           PowerDiagramMethod method = PowerDiagramMethod::automatic,
                                           std::size_t own_cells = std::numeric_limits<std::size_t>::max(),
                                           PowerDiagramWarmStart* warm_start = nullptr);

/// A line of the chart plane with the half-plane on its inner side: {u : normal·u + offset ≥ 0}.
struct ChartLine {
  /// Points into the half-plane; any length (the line is normal·u + offset = 0).
  Vec2 normal;
  /// The value of normal·u + offset at u = 0.
  double offset = 0;
};

/// The bisector of cells i and j, with cell i on its inner side, in coordinates
/// u = v − fixed_centers[i] (see build_chart_diagram_with_fixed_centers).
using ChartBisector = std::function<ChartLine(std::size_t i, std::size_t j)>;

/// A diagram whose neighbours are those of the regular triangulation of `fixed_centers` with
/// `fixed_power_weights`, and whose cells are cut by `bisector(i, j)`, each cell i in coordinates
/// u = v − fixed_centers[i] (the cells come back in chart coordinates). For diagrams that are
/// power diagrams of centres that do not move from one build to the next, while the caller has
/// more accurate bisectors than those of the power form: for H², the Klein points of the sites
/// with power weights |κ_i|² + e^{h_i}/y_{i,3}, and bisectors computed from differences of the
/// sites and weights (docs/hyperbolic.md). `warm_start` (optional) reaches the next
/// triangulation by flips, as for build_power_diagram. InputError when the sizes differ or the
/// build has no CGAL (has_regular_triangulation()); every cell empty when a centre or weight is
/// not finite, and a cell empty when one of its bisectors is not.
std::vector<ChartCell> build_chart_diagram_with_fixed_centers(
    std::span<const Vec2> fixed_centers, std::span<const double> fixed_power_weights, const ChartBisector& bisector,
    const ConvexPolygon& domain, bool stop_at_empty_cell = false, PowerDiagramWarmStart* warm_start = nullptr);

/// Same, with the neighbour candidates already known (e.g. from a 3-D hull).
std::vector<ChartCell> build_chart_diagram(std::span<const Vec3> dual, const ConvexPolygon& domain,
                                           const Adjacency& candidates);

/// Neighbour candidates of the affine functions' upper envelope in the chart plane.
Adjacency chart_adjacency(std::span<const Vec3> dual, const ConvexPolygon& domain);

/// A closed triangulated surface around the origin: triangles counter-clockwise seen from
/// outside, and for each half-edge (triangle t, edge k from corner k to corner k+1) the index
/// 3t' + k' of the opposite half-edge.
struct HullTriangulation {
  /// The triangles, as indices of the points, counter-clockwise seen from outside.
  std::vector<std::array<int, 3>> triangles;
  /// `opposite[3t + k]`: the half-edge 3t' + k' running the other way along edge k of triangle t.
  std::vector<int> opposite;
};

/// A 3-D convex hull, as convex_hull_3d() and convex_hull_3d_by_flips() return it.
struct Hull3 {
  /// For each point, the points joined to it by a hull edge (none for a point inside the hull).
  Adjacency edges;
  /// 1 for the points that are hull vertices, 0 for the others.
  std::vector<char> is_vertex;
  /// The largest offset d of the facet planes n·x + d = 0 (n the unit outward normal): < 0 iff
  /// the origin is strictly inside the hull.
  double max_facet_offset = 0;
  /// The hull's triangulation: always from convex_hull_3d_by_flips(); from convex_hull_3d() with
  /// `with_surface` when the origin is strictly inside, else empty.
  HullTriangulation surface;
  /// convex_hull_3d_by_flips() with `stop_at_inside` stopped at the first point found inside the
  /// hull: `is_vertex` has a 0 (not all of them), `surface` is the part-grown surface (a start
  /// for the next call), the rest is unset.
  bool stopped_at_inside = false;
};
/// The 3-D convex hull of `points` (Qhull, triangulated): vertex adjacency along hull edges,
/// which points are hull vertices, and the largest facet offset (< 0 iff the origin is strictly
/// inside the hull). With `with_surface`, and when the origin is strictly inside, `surface` is
/// the triangulation (empty otherwise). Throws sdot::Error when the hull is degenerate (all
/// points coplanar).
Hull3 convex_hull_3d(std::span<const Vec3> points, bool with_surface = false);

/// The same hull, grown from `start`, the hull triangulation of nearby points (the previous
/// Newton iterate), or from a tetrahedron of the points when `start` is empty: reflex edges are
/// flipped, a vertex that has fallen inside leaves by a 3-1 flip once its degree is 3, and the
/// points missing from `start` are inserted (1-3 split, in Morton order) where they lie above the
/// surface. Every step adds volume, so a point found inside stays inside; a closed surface that is
/// star-shaped around the origin and locally convex is convex (Tietze), so the result is the hull.
/// Empty when that is not reached: a triangle of `start` faces the origin or names a point that
/// does not exist, no tetrahedron holds the origin, a reflex edge stays stuck (rare from an old
/// hull; the caller may then start from scratch), or a walk or the flips run too long. The caller
/// then runs convex_hull_3d. With `stop_at_inside`, stops at the first point found inside (an
/// empty Laguerre cell; see Hull3::stopped_at_inside). Without `with_edges`, Hull3::edges is left
/// empty (a caller that walks `surface` does not need it).
std::optional<Hull3> convex_hull_3d_by_flips(std::span<const Vec3> points, HullTriangulation start,
                                             bool stop_at_inside = false, bool with_edges = true);

}  // namespace sdot
