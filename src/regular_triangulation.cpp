// CGAL's 2-D regular triangulation (exact predicates, inexact constructions; the constructions are
// never used: cells are clipped from the neighbour lists in double precision).
#include "regular_triangulation.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Regular_triangulation_2.h>
#include <CGAL/Regular_triangulation_face_base_2.h>
#include <CGAL/Regular_triangulation_vertex_base_2.h>
#include <CGAL/Spatial_sort_traits_adapter_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/property_map.h>
#include <CGAL/spatial_sort.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

namespace sdot::detail {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using VertexBase =
    CGAL::Triangulation_vertex_base_with_info_2<int, Kernel, CGAL::Regular_triangulation_vertex_base_2<Kernel>>;
using FaceBase = CGAL::Regular_triangulation_face_base_2<Kernel>;
using Triangulation = CGAL::Regular_triangulation_2<Kernel, CGAL::Triangulation_data_structure_2<VertexBase, FaceBase>>;

}  // namespace

namespace {

/// Whether consecutive centres are close, as along a space-filling curve (the solver orders its
/// sites so): the walk of the incremental insertion from one site to the next is then short.
/// The path length of n points in Hilbert order over a bounding box of area A is about
/// sqrt(n·A); in random order it is about n·sqrt(A)/2.
bool in_spatial_order(std::span<const Vec2> centers) {
  const std::size_t n = centers.size();
  if (n < 64) return false;
  Vec2 low = centers[0], high = centers[0];
  double path = 0;
  for (std::size_t i = 1; i < n; ++i) {
    low = low.cwiseMin(centers[i]), high = high.cwiseMax(centers[i]);
    path += (centers[i] - centers[i - 1]).norm();
  }
  const Vec2 extent = high - low;
  const double side = std::max(extent.x(), extent.y());
  const double area = std::max(extent.x() * extent.y(), side * side / static_cast<double>(n));
  return path <= 8 * std::sqrt(static_cast<double>(n) * area);
}

}  // namespace

RegularTriangulation regular_triangulation(std::span<const Vec2> centers, std::span<const double> power_weights,
                                           bool stop_at_hidden) {
  const std::size_t n = centers.size();
  // CGAL's weighted point (p, w) has power |v − p|² − w: the same convention as ours.
  std::vector<Triangulation::Weighted_point> points;
  points.reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    points.emplace_back(Kernel::Point_2(centers[i].x(), centers[i].y()), power_weights[i]);
  // Insertion along a space-filling curve, each point located from the last one. Centres already
  // in such an order (the solver's) are inserted as they come: CGAL's range insertion would sort
  // them again at every Newton step.
  std::vector<std::size_t> insertion(n);
  std::iota(insertion.begin(), insertion.end(), std::size_t{0});
  if (!in_spatial_order(centers)) {
    std::vector<Kernel::Point_2> bare(n);
    for (std::size_t i = 0; i < n; ++i) bare[i] = points[i].point();
    const auto bare_map = CGAL::make_property_map(std::as_const(bare));
    CGAL::spatial_sort(insertion.begin(), insertion.end(),
                       CGAL::Spatial_sort_traits_adapter_2<Kernel, decltype(bare_map)>(bare_map));
  }
  RegularTriangulation result;
  Triangulation triangulation;
  Triangulation::Face_handle hint;
  for (const std::size_t i : insertion) {
    const auto vertex = triangulation.insert(points[i], hint);
    if (vertex == Triangulation::Vertex_handle()) continue;
    vertex->info() = static_cast<int>(i);
    hint = vertex->face();
    // A point hidden by some of the points stays hidden by all of them: its cell is empty.
    if (stop_at_hidden && triangulation.number_of_hidden_vertices() > 0) {
      result.stopped_at_hidden = true;
      return result;
    }
  }

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
