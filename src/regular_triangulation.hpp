#pragma once
// The 2-D regular triangulation behind build_power_diagram: CGAL's, with exact predicates, kept
// out of the public headers. Only built when CGAL is found (SDOT_HAVE_CGAL).

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
};
/// With `stop_at_hidden`, stops as soon as some site is hidden (its cell is empty).
RegularTriangulation regular_triangulation(std::span<const Vec2> centers, std::span<const double> power_weights,
                                           bool stop_at_hidden = false);

}  // namespace sdot::detail
