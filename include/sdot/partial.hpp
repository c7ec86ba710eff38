#pragma once
/// \file partial.hpp
/// Partial transport: Laguerre cells cut by the sites' balls (docs/partial.md).
///
/// With `Options::partial`, the cell of site i is C_i(w) = W_i(w) ∩ B_i(w), with the ball
/// B_i(w) = {x : c(x, y_i) ≤ w_i} of radius r_i = c⁻¹(w_i): the source mass farther (in cost)
/// from every site than its weight stays where it is. This is the partial transport of Caffarelli–
/// McCann and Figalli with a quadratic-type cost, the projection of crowd motion (Leclerc, Mérigot,
/// Santambrogio, Stra) and pysdot's ball cut. The concave dual
/// Φ(w) = ∫ min(0, min_i c(x, y_i) − w_i) dμ + Σ ν_i w_i has gradient ν_i − μ(C_i) and Hessian
/// ∂μ(C_i)/∂w_j = −∫_{Γ_ij ∩ B_i} ρ / |∇_x(c_i − c_j)| ds (i ≠ j; on Γ_ij, B_i and B_j coincide, so
/// it is symmetric) and ∂μ(C_i)/∂w_i = Σ_{j≠i} ∫_{Γ_ij ∩ B_i} ρ / |∇(c_i − c_j)| + ∫_{∂B_i ∩ W_i} ρ / |∇c_i|:
/// the arcs make the diagonal dominant, so there is no constant to fix (weights are unique).
///
/// A fixed radius per site is not offered: with fixed balls the weights only move facets, so two
/// sites whose balls are disjoint keep the masses of their balls whatever the weights, and
/// prescribed masses generally have no solution.

#include <algorithm>
#include <cmath>
#include <concepts>
#include <limits>
#include <utility>

#include "sdot/diagram.hpp"
#include "sdot/geometry.hpp"

namespace sdot {

/// The Cell::neighbors label of an edge that is an arc of the site's own ball boundary (partial
/// transport), counter-clockwise around the site. Negative, so is_boundary() is true for it, and
/// distinct from every boundary_label(k).
constexpr int ball_arc_label = std::numeric_limits<int>::min();
/// True for an edge on the boundary of the site's ball.
constexpr bool is_ball_arc(int label) {
  return label == ball_arc_label;
}
/// True for an edge on the source domain's boundary (a negative label that is not a ball arc).
constexpr bool is_domain_boundary(int label) {
  return label < 0 && label != ball_arc_label;
}

/// A geometry that supports partial transport supplies, besides `Geometry`:
/// - `cut_by_ball(cell, site, weight)`: cell ∩ {x : c(x, site) ≤ weight}, with the ball's arcs as
///   edges labelled ball_arc_label, each spanning at most 90° (a full disc has 4 of them);
/// - `integrate(cell, site, with_cost)`: exact also for cells with ball arcs;
/// - `arc_weight(cell, site)`: ∫ ds / |∇_x c(x, site)| over the cell's ball arcs (the Hessian's
///   diagonal term of the arcs, for ρ ≡ 1);
/// - `ball_radius(weight)`: the (geodesic) radius c⁻¹(weight) of a ball, 0 for weight ≤ 0;
/// - `ball_weight(area)`: the weight whose ball has this area (for the start);
/// - `cost_range(cell, site)`: min and max of c(x, site) over a non-empty cell (for the start);
/// - `with_sampled_arcs(cell, site, pieces)`: the cell with each ball arc replaced by `pieces`
///   straight (geodesic) edges through points of the arc, still labelled ball_arc_label (pictures).
template <class G>
concept PartialGeometry = Geometry<G> &&
    requires(const G& geometry, const Cell<typename G::Point>& cell, const typename G::Point& point, double weight) {
  { geometry.cut_by_ball(cell, point, weight) } -> std::same_as<Cell<typename G::Point>>;
  { geometry.arc_weight(cell, point) } -> std::convertible_to<double>;
  { geometry.ball_radius(weight) } -> std::convertible_to<double>;
  { geometry.ball_weight(weight) } -> std::convertible_to<double>;
  { geometry.cost_range(cell, point) } -> std::same_as<std::pair<double, double>>;
};

namespace detail {

/// What one edge [a, b] of a cell keeps inside a ball: nothing, or the piece from `entry` to `exit`;
/// `starts_at_a` / `ends_at_b` when the piece begins at a / ends at b (then entry = a / exit = b).
template <class Point>
struct EdgeInBall {
  bool any = false;
  bool starts_at_a = false, ends_at_b = false;
  Point entry, exit;
};

/// The cut of a convex cell by a ball, shared by the geometries. `ball` supplies
/// - `clip(a, b, label)` → EdgeInBall<Point> for the edge from a to b with that neighbour label,
/// - `angle(p, q)`: the angle in [0, 2π) swept counter-clockwise around the site from p to q,
///   both on the ball's boundary,
/// - `rotate(p, angle)`: p turned counter-clockwise around the site by `angle`,
/// - `boundary_point()`: a point of the ball's boundary,
/// - `contains_site(cell)`: whether the site lies in the cell.
/// Arcs are split into pieces of at most 90° and, for a cell of fewer than 3 vertices, halved.
template <class Point, class Ball>
Cell<Point> cut_cell_by_ball(const Cell<Point>& cell, const Ball& ball) {
  constexpr double quarter_turn = 1.5707963267948966;
  Cell<Point> cut;
  const std::size_t n = cell.size();
  bool all_inside = true;
  for (std::size_t k = 0; k < n; ++k) {
    const EdgeInBall<Point> piece = ball.clip(cell.vertices[k], cell.vertices[(k + 1) % n], cell.neighbors[k]);
    all_inside = all_inside && piece.any && piece.starts_at_a && piece.ends_at_b;
    if (!piece.any) continue;
    cut.vertices.push_back(piece.starts_at_a ? cell.vertices[k] : piece.entry);
    cut.neighbors.push_back(cell.neighbors[k]);
    if (!piece.ends_at_b) {
      cut.vertices.push_back(piece.exit);
      cut.neighbors.push_back(ball_arc_label);
    }
  }
  if (all_inside) return cell;
  if (cut.vertices.empty()) {
    if (!ball.contains_site(cell)) return {};
    const Point start = ball.boundary_point();  // the whole disc: four quarter arcs
    for (int k = 0; k < 4; ++k) {
      cut.vertices.push_back(ball.rotate(start, k * quarter_turn));
      cut.neighbors.push_back(ball_arc_label);
    }
    return cut;
  }
  Cell<Point> split;
  const std::size_t m = cut.size();
  double longest_arc = 0;
  std::size_t longest_at = 0;
  for (std::size_t k = 0; k < m; ++k) {
    split.vertices.push_back(cut.vertices[k]);
    split.neighbors.push_back(cut.neighbors[k]);
    if (!is_ball_arc(cut.neighbors[k])) continue;
    const double angle = ball.angle(cut.vertices[k], cut.vertices[(k + 1) % m]);
    const int pieces = std::max(1, static_cast<int>(std::ceil(angle / quarter_turn - 1e-9)));
    if (angle / pieces > longest_arc) longest_arc = angle / pieces, longest_at = split.size() - 1;
    for (int piece = 1; piece < pieces; ++piece) {
      split.vertices.push_back(ball.rotate(cut.vertices[k], angle * piece / pieces));
      split.neighbors.push_back(ball_arc_label);
    }
  }
  if (split.size() < 3 && longest_arc > 0) {  // a chord and its arc: halve the arc
    split.vertices.insert(split.vertices.begin() + static_cast<std::ptrdiff_t>(longest_at) + 1,
                          ball.rotate(split.vertices[longest_at], longest_arc / 2));
    split.neighbors.insert(split.neighbors.begin() + static_cast<std::ptrdiff_t>(longest_at) + 1, ball_arc_label);
  }
  if (split.size() < 3) return {};
  return split;
}

/// `cell` with each ball arc from p to q replaced by `pieces` edges through rotate(p, angle(p, q)·m/pieces).
template <class Point, class Angle, class Rotate>
Cell<Point> sample_ball_arcs(const Cell<Point>& cell, int pieces, const Angle& angle, const Rotate& rotate) {
  Cell<Point> sampled;
  for (std::size_t k = 0; k < cell.size(); ++k) {
    sampled.vertices.push_back(cell.vertices[k]);
    sampled.neighbors.push_back(cell.neighbors[k]);
    if (!is_ball_arc(cell.neighbors[k])) continue;
    const double sweep = angle(cell.vertices[k], cell.vertices[(k + 1) % cell.size()]);
    for (int m = 1; m < pieces; ++m) {
      sampled.vertices.push_back(rotate(cell.vertices[k], sweep * m / pieces));
      sampled.neighbors.push_back(ball_arc_label);
    }
  }
  return sampled;
}

/// The piece of [0, length] within distance `half_width` of `center` (in the edge's parameter),
/// as an EdgeInBall with `at(s)` the point at parameter s; ends snap to a and b within 1e-13·length.
template <class Point, class At>
EdgeInBall<Point> edge_interval(double center, double half_width, double length, const Point& a, const Point& b,
                                const At& at) {
  EdgeInBall<Point> piece;
  if (!(half_width > 0) || !(length > 0)) return piece;
  double low = center - half_width, high = center + half_width;
  const double snap = 1e-13 * length;
  if (low <= snap) low = 0;
  if (high >= length - snap) high = length;
  if (!(low < high)) return piece;
  piece.any = true;
  piece.starts_at_a = low == 0;
  piece.ends_at_b = high == length;
  piece.entry = piece.starts_at_a ? a : at(low);
  piece.exit = piece.ends_at_b ? b : at(high);
  return piece;
}

}  // namespace detail
}  // namespace sdot
