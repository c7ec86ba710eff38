#pragma once
/// \file diagram.hpp
/// Laguerre (power) cells as convex polygons, shared by every geometry.

#include <Eigen/Core>
#include <vector>

namespace sdot {

/// The label −1 − `domain_edge` that Cell::neighbors gives an edge lying on edge `domain_edge`
/// (0-based) of the source domain's boundary. Site indices are ≥ 0, so every negative label is
/// a boundary label.
constexpr int boundary_label(int domain_edge) {
  return -1 - domain_edge;
}
/// True when a Cell::neighbors `label` marks an edge on the source domain's boundary (any
/// negative label), false for a neighbour site's index.
constexpr bool is_boundary(int label) {
  return label < 0;
}

/// One Laguerre cell W_i restricted to the source domain: a convex polygon with vertices in
/// counter-clockwise order. Edge k runs from `vertices[k]` to `vertices[(k+1) % size]`;
/// `neighbors[k]` is the index of the site on the other side, or a negative boundary label.
/// An empty cell has no vertices.
template <class Point>
struct Cell {
  /// The vertices, counter-clockwise (on the sphere seen from outside, on H² in a Klein chart).
  std::vector<Point> vertices;
  /// One label per edge: the neighbour site's index, or boundary_label(k) for domain edge k.
  std::vector<int> neighbors;

  /// True when the cell has fewer than 3 vertices: no area.
  [[nodiscard]] bool empty() const { return vertices.size() < 3; }
  /// The number of vertices (and of edges).
  [[nodiscard]] std::size_t size() const { return vertices.size(); }
};

/// The Laguerre diagram of a set of sites with weights, restricted to the source domain:
/// one cell per site (possibly empty), in site order.
template <class Point>
struct Diagram {
  /// `cells[i]` is the cell of site i.
  std::vector<Cell<Point>> cells;
};

/// Integrals of the source density over one cell: mass ∫ρ, first moment ∫x ρ (in the
/// geometry's ambient coordinates) and transport cost ∫ c(x, y_i) ρ.
template <class Point>
struct CellIntegrals {
  /// ∫_W ρ dA, with dA the geometry's area measure (intrinsic area on S² and H²).
  double mass = 0;
  /// ∫_W x ρ dA, x in the geometry's ambient coordinates (R² or R³).
  Point first_moment = Point::Zero();
  /// ∫_W c(x, y_i) ρ dA, y_i the cell's site; may be left at 0 by an integration called with
  /// `with_cost` false.
  double cost = 0;
};

/// Sorted, de-duplicated neighbour lists of every cell (the adjacency of the diagram).
template <class Point>
std::vector<std::vector<int>> adjacency(const Diagram<Point>& diagram);

}  // namespace sdot

#include <algorithm>

template <class Point>
std::vector<std::vector<int>> sdot::adjacency(const Diagram<Point>& diagram) {
  std::vector<std::vector<int>> result(diagram.cells.size());
  for (std::size_t i = 0; i < diagram.cells.size(); ++i) {
    for (int label : diagram.cells[i].neighbors)
      if (!is_boundary(label)) result[i].push_back(label);
    std::sort(result[i].begin(), result[i].end());
    result[i].erase(std::unique(result[i].begin(), result[i].end()), result[i].end());
  }
  return result;
}
