#pragma once
/// \file diagram.hpp
/// Laguerre (power) cells as convex polygons, shared by every geometry.

#include <Eigen/Core>
#include <vector>

namespace sdot {

/// Label of an edge that lies on the boundary of the source domain (any negative label).
/// `boundary_label(k)` marks domain edge k; `is_boundary(label)` tests it.
constexpr int boundary_label(int domain_edge) {
  return -1 - domain_edge;
}
constexpr bool is_boundary(int label) {
  return label < 0;
}

/// One Laguerre cell W_i restricted to the source domain: a convex polygon with vertices in
/// counter-clockwise order. Edge k runs from `vertices[k]` to `vertices[(k+1) % size]`;
/// `neighbors[k]` is the index of the site on the other side, or a negative boundary label.
/// An empty cell has no vertices.
template <class Point>
struct Cell {
  std::vector<Point> vertices;
  std::vector<int> neighbors;

  [[nodiscard]] bool empty() const { return vertices.size() < 3; }
  [[nodiscard]] std::size_t size() const { return vertices.size(); }
};

/// The Laguerre diagram of a set of sites with weights, restricted to the source domain:
/// one cell per site (possibly empty), in site order.
template <class Point>
struct Diagram {
  std::vector<Cell<Point>> cells;
};

/// Integrals of the source density over one cell: mass ∫ρ, first moment ∫x ρ (in the
/// geometry's ambient coordinates) and transport cost ∫ c(x, y_i) ρ.
template <class Point>
struct CellIntegrals {
  double mass = 0;
  Point first_moment = Point::Zero();
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
