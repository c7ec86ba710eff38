#pragma once
// The 2-D regular triangulation behind build_power_diagram: CGAL's, with exact predicates, kept
// out of the public headers. Only built when CGAL is found (SDOT_HAVE_CGAL).

#include <array>
#include <cstdint>
#include <mutex>
#include <optional>
#include <span>
#include <vector>

#include "sdot/chart_diagram.hpp"

namespace sdot::detail {

/// The Laguerre neighbours of every site of the power diagram {v : |v − c_i|² − w_i ≤ |v − c_j|² − w_j}
/// in the whole plane (the edges of the regular triangulation), in CSR form, and which sites are
/// vertices of the triangulation (the others, hidden, have empty cells). Every predicate is exact
/// on the given doubles, so cocircular and collinear sites and equal centres are handled exactly.
struct RegularTriangulation {
  Adjacency neighbors;
  std::vector<char> is_vertex;
  std::vector<int> order;          ///< the vertices in storage order, close to their insertion order (a Hilbert curve)
  bool stopped_at_hidden = false;  ///< stopped early at a hidden site (only with `stop_at_hidden`): nothing else is set
  /// The triangles, counter-clockwise, each from its smallest vertex, sorted: set when asked for
  /// and every site is a vertex (the start of regular_triangulation_by_flips).
  std::vector<std::array<int, 3>> triangles;
};
/// With `stop_at_hidden`, stops as soon as some site is hidden (its cell is empty). With
/// `with_triangles`, also lists the triangles (for a warm start; not worth their time otherwise).
RegularTriangulation regular_triangulation(std::span<const Vec2> centers, std::span<const double> power_weights,
                                           bool stop_at_hidden = false, bool with_triangles = false);

/// A triangulation of all the sites: its triangles, counter-clockwise, and the twin of each
/// half-edge (half-edge 3k + e runs from vertex e + 1 to e + 2 of triangle k; its twin is the same
/// edge in the other triangle, −1 on the convex hull; empty until regular_triangulation_by_flips
/// needs them).
struct SiteTriangulation {
  std::vector<std::array<int, 3>> triangles;
  std::vector<int> twins;
};

/// The regular triangulation by edge flips from `surface`, a triangulation of the same centres in
/// which every site is a vertex (the regular triangulation at other weights): each edge that is
/// not locally regular is flipped, with exact predicates, until none is, which makes it the
/// regular triangulation (a locally convex lifted surface over a convex domain is the lower hull).
/// `surface` becomes that triangulation. Empty when some edge cannot be flipped (its
/// quadrilateral is not convex: a site becomes hidden, or the flips would have to pass through
/// such a state) or after more than `max_flips` flips; `surface` is then still a triangulation of
/// the sites, part of the way, and the caller builds from scratch.
std::optional<RegularTriangulation> regular_triangulation_by_flips(std::span<const Vec2> centers,
                                                                   std::span<const double> power_weights,
                                                                   SiteTriangulation& surface, std::size_t max_flips);

/// A 64-bit fingerprint of the centres' bits: a warm start applies to the same centres only.
std::uint64_t centers_fingerprint(std::span<const Vec2> centers);

}  // namespace sdot::detail

namespace sdot {
/// The last regular triangulation of a geometry's diagrams (see chart_diagram.hpp).
struct PowerDiagramWarmStart {
  std::mutex mutex;
  std::size_t count = 0;
  std::uint64_t fingerprint = 0;
  detail::SiteTriangulation surface;
};
}  // namespace sdot
