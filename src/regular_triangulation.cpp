// CGAL's 2-D regular triangulation (exact predicates, inexact constructions; the constructions are
// never used: cells are clipped from the neighbour lists in double precision).
#include "regular_triangulation.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Regular_triangulation_2.h>
#include <CGAL/Regular_triangulation_face_base_2.h>
#include <CGAL/Regular_triangulation_vertex_base_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <algorithm>
#include <utility>

namespace sdot::detail {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using VertexBase =
    CGAL::Triangulation_vertex_base_with_info_2<int, Kernel, CGAL::Regular_triangulation_vertex_base_2<Kernel>>;
using FaceBase = CGAL::Regular_triangulation_face_base_2<Kernel>;
using Triangulation = CGAL::Regular_triangulation_2<Kernel, CGAL::Triangulation_data_structure_2<VertexBase, FaceBase>>;

}  // namespace

RegularTriangulation regular_triangulation(std::span<const Vec2> centers, std::span<const double> power_weights) {
  const std::size_t n = centers.size();
  // CGAL's weighted point (p, w) has power |v − p|² − w: the same convention as ours.
  std::vector<std::pair<Triangulation::Weighted_point, int>> points;
  points.reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    points.emplace_back(
        Triangulation::Weighted_point(Kernel::Point_2(centers[i].x(), centers[i].y()), power_weights[i]),
        static_cast<int>(i));
  // The range constructor sorts the points along a Hilbert curve (spatial_sort) before inserting.
  const Triangulation triangulation(points.begin(), points.end());

  RegularTriangulation result;
  result.is_vertex.assign(n, 0);
  result.order.reserve(triangulation.number_of_vertices());
  for (auto v = triangulation.finite_vertices_begin(); v != triangulation.finite_vertices_end(); ++v) {
    result.is_vertex[static_cast<std::size_t>(v->info())] = 1;
    result.order.push_back(v->info());
  }
  Adjacency& adjacency = result.neighbors;
  adjacency.offsets.assign(n + 1, 0);
  for (auto e = triangulation.finite_edges_begin(); e != triangulation.finite_edges_end(); ++e) {
    const auto& face = e->first;
    ++adjacency.offsets[static_cast<std::size_t>(face->vertex(face->cw(e->second))->info()) + 1];
    ++adjacency.offsets[static_cast<std::size_t>(face->vertex(face->ccw(e->second))->info()) + 1];
  }
  for (std::size_t i = 0; i < n; ++i) adjacency.offsets[i + 1] += adjacency.offsets[i];
  adjacency.neighbors.resize(static_cast<std::size_t>(adjacency.offsets[n]));
  std::vector<int> fill(adjacency.offsets.begin(), adjacency.offsets.end() - 1);
  for (auto e = triangulation.finite_edges_begin(); e != triangulation.finite_edges_end(); ++e) {
    const auto& face = e->first;
    const int a = face->vertex(face->cw(e->second))->info(), b = face->vertex(face->ccw(e->second))->info();
    adjacency.neighbors[static_cast<std::size_t>(fill[static_cast<std::size_t>(a)]++)] = b;
    adjacency.neighbors[static_cast<std::size_t>(fill[static_cast<std::size_t>(b)]++)] = a;
  }
  // CGAL stores the faces in an order that depends on memory addresses (its internal sets are
  // keyed by handles), so the edges come in a different order from run to run. Sorted lists make
  // the clipping order, and so the cells to the last bit, the same at every run.
  for (std::size_t i = 0; i < n; ++i)
    std::sort(adjacency.neighbors.begin() + adjacency.offsets[i],
              adjacency.neighbors.begin() + adjacency.offsets[i + 1]);
  return result;
}

}  // namespace sdot::detail
