// The shared cell builder: Qhull for neighbour candidates, half-plane clipping for the cells.
#include "sdot/chart_diagram.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <numeric>

#include <Eigen/Dense>

#include "sdot/error.hpp"

#include "regular_triangulation.hpp"  // declarations only: the definitions need CGAL

extern "C" {
#include <libqhull_r/qhull_ra.h>
}

namespace sdot {
namespace {

double cross(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Runs Qhull on 3-D points and calls `visit(facet)` for each facet; errors become sdot::Error.
template <class Visit>
void run_qhull(std::span<const Vec3> points, Visit&& visit) {
  std::vector<coordT> coords(points.size() * 3);
  for (std::size_t i = 0; i < points.size(); ++i)
    for (int d = 0; d < 3; ++d) coords[3 * i + d] = points[i][d];

  char* message = nullptr;
  std::size_t message_size = 0;
  FILE* errfile = open_memstream(&message, &message_size);
  qhT qh_storage;
  qhT* qh = &qh_storage;
  qh_zero(qh, errfile);
  char flags[] = "qhull Qt";
  const int exit_code =
      qh_new_qhull(qh, 3, static_cast<int>(points.size()), coords.data(), False, flags, nullptr, errfile);
  std::string error;
  if (exit_code == 0) {
    facetT* facet = nullptr;
    FORALLfacets {
      visit(qh, facet);
    }
  }
  qh_freeqhull(qh, !qh_ALL);
  int curlong = 0, totlong = 0;
  qh_memfreeshort(qh, &curlong, &totlong);
  std::fclose(errfile);
  if (exit_code != 0) error.assign(message, message_size);
  std::free(message);
  if (exit_code != 0) {
    const auto end = error.find('\n');
    throw Error("convex hull failed (Qhull error " + std::to_string(exit_code) + "): " + error.substr(0, end));
  }
}

// Turns per-facet vertex triples into CSR adjacency (sorted, unique) for `count` points. On a
// closed, consistently oriented surface (`oriented_surface`) each edge a–b is a→b in exactly one
// of its two triangles, so recording a→b alone lists every neighbour once: half the entries, and
// nothing to de-duplicate (should a list hold a neighbour twice all the same, both directions
// are recorded instead). The lists are sorted on all cores.
Adjacency triangles_to_adjacency(const std::vector<std::array<int, 3>>& triangles, std::size_t count,
                                 bool oriented_surface = false) {
  Adjacency adjacency;
  adjacency.offsets.assign(count + 1, 0);
  for (const auto& t : triangles)
    for (int v : t) adjacency.offsets[v + 1] += oriented_surface ? 1 : 2;
  for (std::size_t i = 0; i < count; ++i) adjacency.offsets[i + 1] += adjacency.offsets[i];
  adjacency.neighbors.resize(adjacency.offsets[count]);
  std::vector<int> fill(adjacency.offsets.begin(), adjacency.offsets.end() - 1);
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      adjacency.neighbors[fill[a]++] = b;
      if (!oriented_surface) adjacency.neighbors[fill[b]++] = a;
    }
  const auto vertices = static_cast<std::ptrdiff_t>(count);
  bool repeated = false;
#pragma omp parallel for schedule(static, 4096) reduction(|| : repeated)
  for (std::ptrdiff_t i = 0; i < vertices; ++i) {
    const auto first = adjacency.neighbors.begin() + adjacency.offsets[i];
    const auto last = adjacency.neighbors.begin() + adjacency.offsets[i + 1];
    std::sort(first, last);
    if (std::adjacent_find(first, last) != last) repeated = true;
  }
  if (oriented_surface) return repeated ? triangles_to_adjacency(triangles, count) : adjacency;
  // De-duplicate each sorted list in place, then compact.
  std::size_t write = 0;
  int begin = adjacency.offsets[0];
  for (std::size_t i = 0; i < count; ++i) {
    const int end = adjacency.offsets[i + 1];
    const auto first = adjacency.neighbors.begin() + begin;
    const auto last = std::unique(first, adjacency.neighbors.begin() + end);
    adjacency.offsets[i] = static_cast<int>(write);
    for (auto it = first; it != last; ++it) adjacency.neighbors[write++] = *it;
    begin = end;
  }
  adjacency.offsets[count] = static_cast<int>(write);
  adjacency.neighbors.resize(write);
  return adjacency;
}

// Orients Qhull's triangles counter-clockwise seen from outside (the origin is inside) and
// links the opposite half-edges; empty when the triangles do not form a closed 2-manifold.
HullTriangulation oriented_surface(std::span<const Vec3> points, std::vector<std::array<int, 3>> triangles) {
  HullTriangulation s;
  for (auto& t : triangles)
    if (points[t[0]].dot(points[t[1]].cross(points[t[2]])) < 0) std::swap(t[1], t[2]);
  std::vector<std::pair<std::uint64_t, int>> half_edges(3 * triangles.size());
  auto key = [](int a, int b) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) | static_cast<std::uint32_t>(b);
  };
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (int k = 0; k < 3; ++k)
      half_edges[3 * t + k] = {key(triangles[t][k], triangles[t][(k + 1) % 3]), static_cast<int>(3 * t + k)};
  std::sort(half_edges.begin(), half_edges.end());
  std::vector<int> opposite(half_edges.size(), -1);
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (int k = 0; k < 3; ++k) {
      const std::uint64_t reverse = key(triangles[t][(k + 1) % 3], triangles[t][k]);
      const auto it = std::lower_bound(half_edges.begin(), half_edges.end(), std::make_pair(reverse, -1));
      if (it == half_edges.end() || it->first != reverse) return s;                        // not closed
      if (std::next(it) != half_edges.end() && std::next(it)->first == reverse) return s;  // not manifold
      opposite[3 * t + k] = it->second;
    }
  s.triangles = std::move(triangles);
  s.opposite = std::move(opposite);
  return s;
}

}  // namespace

ConvexPolygon::ConvexPolygon(std::vector<Vec2> vertices, const std::string& field) : vertices_(std::move(vertices)) {
  const std::size_t n = vertices_.size();
  if (n < 3) throw InputError(field, "a polygon needs at least 3 vertices, got " + std::to_string(n));
  for (std::size_t i = 0; i < n; ++i)
    if (!vertices_[i].allFinite()) throw InputError(indexed(field, i), "vertex is not finite");
  double scale = 0;
  for (const auto& v : vertices_) scale = std::max(scale, v.cwiseAbs().maxCoeff());
  for (std::size_t i = 0; i < n; ++i)
    if ((vertices_[i] - vertices_[(i + 1) % n]).norm() <= 1e-14 * std::max(scale, 1.0))
      throw InputError(indexed(field, (i + 1) % n), "vertex coincides with the previous one");
  if (area() < 0) std::reverse(vertices_.begin(), vertices_.end());
  const double a = area();
  if (!(a > 1e-14 * std::max(scale * scale, 1e-300))) throw InputError(field, "polygon is degenerate (zero area)");
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2& p = vertices_[(i + n - 1) % n];
    const Vec2& q = vertices_[i];
    const Vec2& r = vertices_[(i + 1) % n];
    const double turn = cross(q - p, r - q);
    if (turn < -1e-12 * (q - p).norm() * (r - q).norm())
      throw InputError(indexed(field, i), "polygon is not convex at this vertex");
  }
}

ConvexPolygon ConvexPolygon::rectangle(double x0, double y0, double x1, double y1) {
  return ConvexPolygon({{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}});
}

double ConvexPolygon::area() const {
  double twice = 0;
  for (std::size_t i = 0; i < vertices_.size(); ++i)
    twice += cross(vertices_[i] - vertices_[0], vertices_[(i + 1) % vertices_.size()] - vertices_[0]);
  return twice / 2;
}

Vec2 ConvexPolygon::centroid() const {
  Vec2 moment = Vec2::Zero();
  double twice = 0;
  const Vec2& o = vertices_[0];
  for (std::size_t i = 1; i + 1 < vertices_.size(); ++i) {
    const double c = cross(vertices_[i] - o, vertices_[i + 1] - o);
    twice += c;
    moment += c * (vertices_[i] + vertices_[i + 1] - 2 * o) / 3;
  }
  return o + moment / twice;
}

bool ConvexPolygon::contains(const Vec2& p, double slack) const {
  for (std::size_t i = 0; i < vertices_.size(); ++i) {
    const Vec2& a = vertices_[i];
    const Vec2& b = vertices_[(i + 1) % vertices_.size()];
    if (cross(b - a, p - a) < -slack * (b - a).norm()) return false;
  }
  return true;
}

double ConvexPolygon::radius() const {
  double r = 0;
  for (const auto& v : vertices_) r = std::max(r, v.norm());
  return r;
}

bool cell_from_ordered_lines(ChartCell& cell, std::span<const Vec2> normals, std::span<const double> offsets,
                             std::span<const int> labels, double bound) {
  const std::size_t n = normals.size();
  if (n < 3 || offsets.size() != n || labels.size() != n) return false;
  cell.vertices.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t previous = k == 0 ? n - 1 : k - 1;
    const Vec2& a = normals[previous];
    const Vec2& b = normals[k];
    const double det = a.x() * b.y() - a.y() * b.x();
    if (!(det > 0)) return false;
    const Vec2 v((offsets[k] * a.y() - offsets[previous] * b.y()) / det,
                 (offsets[previous] * b.x() - offsets[k] * a.x()) / det);
    if (!(std::abs(v.x()) <= bound && std::abs(v.y()) <= bound)) return false;
    cell.vertices[k] = v;
  }
  // Edge k runs from vertex k to vertex k + 1 along line k, in the direction of its inward normal
  // turned clockwise.
  for (std::size_t k = 0; k < n; ++k) {
    const Vec2 along = cell.vertices[k + 1 == n ? 0 : k + 1] - cell.vertices[k];
    if (along.x() * normals[k].y() - along.y() * normals[k].x() < 0) return false;
  }
  cell.neighbors.assign(labels.begin(), labels.end());
  return true;
}

void clip(ChartCell& cell, const Vec2& normal, double offset, int label) {
  const std::size_t n = cell.vertices.size();
  if (n == 0) return;
  thread_local std::vector<double> side;
  side.resize(n);
  bool all_inside = true, all_outside = true;
  for (std::size_t k = 0; k < n; ++k) {
    side[k] = normal.dot(cell.vertices[k]) + offset;
    all_inside = all_inside && side[k] >= 0;
    all_outside = all_outside && side[k] < 0;
  }
  if (all_inside) return;
  if (all_outside) {
    cell.vertices.clear();
    cell.neighbors.clear();
    return;
  }
  // Written by index into buffers sized for the most the loop can emit (two per edge; a convex
  // cell gives at most n + 1), without a push_back's capacity check per vertex.
  thread_local ChartCell out;
  out.vertices.resize(2 * n);
  out.neighbors.resize(2 * n);
  Vec2* vertices = out.vertices.data();
  int* neighbors = out.neighbors.data();
  std::size_t count = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t next = k + 1 == n ? 0 : k + 1;
    const double s = side[k], t = side[next];
    const Vec2& p = cell.vertices[k];
    const Vec2& q = cell.vertices[next];
    if (s >= 0) {
      vertices[count] = p;
      neighbors[count++] = t < 0 && s == 0 ? label : cell.neighbors[k];
      if (t < 0 && s != 0) {
        vertices[count] = p + (s / (s - t)) * (q - p);
        neighbors[count++] = label;
      }
    } else if (t > 0) {
      vertices[count] = p + (s / (s - t)) * (q - p);
      neighbors[count++] = cell.neighbors[k];
    }
  }
  if (count < 3) {
    cell.vertices.clear();
    cell.neighbors.clear();
    return;
  }
  out.vertices.resize(count);
  out.neighbors.resize(count);
  std::swap(cell.vertices, out.vertices);
  std::swap(cell.neighbors, out.neighbors);
}

Adjacency chart_adjacency(std::span<const Vec3> dual, const ConvexPolygon& domain) {
  const std::size_t n = dual.size();
  // Lifted points of the regular triangulation; their lower hull is the triangulation.
  std::vector<Vec3> lifted(n + 4);
  Vec2 center = Vec2::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    lifted[i] = Vec3(dual[i].x() / 2, dual[i].y() / 2, -dual[i].z());
    center += lifted[i].head<2>();
  }
  center /= static_cast<double>(std::max<std::size_t>(n, 1));
  double spread = 0;
  for (std::size_t i = 0; i < n; ++i) spread = std::max(spread, (lifted[i].head<2>() - center).norm());
  // Four dummy functions around the cloud make the hull full-dimensional whatever the sites
  // (one site, collinear sites); they lie below the envelope on the domain, so never win there.
  double lower_bound = INFINITY;  // ≤ max_i f_i on the domain
  for (const auto& v : domain.vertices()) lower_bound = std::min(lower_bound, dual[0].head<2>().dot(v) + dual[0].z());
  const double radius = 2 * spread + 1e-3 * (1 + center.norm()) + 1;
  const Vec2 corners[4] = {{1, 1}, {-1, 1}, {-1, -1}, {1, -1}};
  for (int k = 0; k < 4; ++k) {
    const Vec2 slope = 2 * (center + radius * corners[k]);
    double highest = -INFINITY;
    for (const auto& v : domain.vertices()) highest = std::max(highest, slope.dot(v));
    const double margin = 1 + std::abs(lower_bound) + std::abs(highest);
    const double offset = lower_bound - highest - margin;
    lifted[n + k] = Vec3(slope.x() / 2, slope.y() / 2, -offset);
  }
  std::vector<std::array<int, 3>> triangles;
  triangles.reserve(2 * n + 8);
  run_qhull(lifted, [&](qhT* qh, facetT* facet) {
    if (facet->normal[2] >= 0) return;  // only the lower hull is the triangulation
    std::array<int, 3> t{};
    int count = 0;
    vertexT *vertex = nullptr, **vertexp = nullptr;
    FOREACHvertex_(facet->vertices) {
      if (count < 3) t[count] = qh_pointid(qh, vertex->point);
      ++count;
    }
    if (count == 3) triangles.push_back(t);
  });
  // Indices >= n are the dummies; they are kept so that a site whose only Laguerre neighbours
  // are dummies (it covers the whole domain) still has candidates and is not taken as empty.
  return triangles_to_adjacency(triangles, n + 4);
}

std::vector<ChartCell> build_chart_diagram(std::span<const Vec3> dual, const ConvexPolygon& domain,
                                           const Adjacency& candidates) {
  const std::size_t n = dual.size();
  std::vector<ChartCell> cells(n);
  const auto& boundary = domain.vertices();
  // A site that is no vertex of the lower hull has no candidates and an empty cell.
#pragma omp parallel for schedule(dynamic, 256)
  for (std::size_t i = 0; i < n; ++i) {
    const auto neighbors = candidates.of(i);
    if (neighbors.empty()) continue;
    ChartCell& cell = cells[i];
    cell.vertices.assign(boundary.begin(), boundary.end());
    cell.neighbors.resize(boundary.size());
    for (std::size_t k = 0; k < boundary.size(); ++k) cell.neighbors[k] = boundary_label(static_cast<int>(k));
    for (int j : neighbors) {
      if (j >= static_cast<int>(n)) continue;  // a dummy: below the envelope on the domain
      const Vec3 difference = dual[i] - dual[j];
      clip(cell, difference.head<2>(), difference.z(), j);
      if (cell.vertices.empty()) break;
    }
  }
  return cells;
}

namespace {

// A kd-tree over the sites' anchors (their positions in the chart, where their cells are), for
// exact branch-and-bound "who is lowest below the envelope at v" queries. With f_j(v) = c_j·v + b_j
// (b_j = (w_j − |c_j|²)/2, so pow_j(v) = |v|² − 2 f_j(v)), each node keeps a reference point v₀
// (its anchor box centre), max_j f_j(v₀) and the box of the c_j; then over the node
// f_j(v) ≤ max_j f_j(v₀) + max_{c ∈ box} c·(v − v₀), a bound whose slack shrinks like
// (node size)·|v − v₀| — as for a Euclidean kd-tree — in every geometry, even where the power
// weights vary a lot across the chart (Klein and gnomonic charts).
class PowerTree {
 public:
  PowerTree(std::span<const Vec2> centers, std::span<const double> weights, std::span<const Vec2> anchors)
      : centers_(centers), weights_(weights), anchors_(anchors), order_(centers.size()) {
    std::iota(order_.begin(), order_.end(), 0);
    nodes_.reserve(2 * centers.size() / leaf_size + 2);
    build(0, static_cast<int>(centers.size()));
  }

  /// The j minimising pow_j(v) = |v − c_j|² − w_j among those with pow_j(v) < bound, or −1.
  [[nodiscard]] int lowest(const Vec2& v, double bound) const {
    int best = -1;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    const double v_sq = v.squaredNorm();
    while (top > 0) {
      const Node& node = nodes_[stack[--top]];
      if (lower_bound(node, v, v_sq) >= bound) continue;
      if (node.left < 0) {
        for (int k = node.begin; k < node.end; ++k) {
          const int j = order_[k];
          const double power = (v - centers_[j]).squaredNorm() - weights_[j];
          if (power < bound) bound = power, best = j;
        }
      } else if (lower_bound(nodes_[node.left], v, v_sq) <= lower_bound(nodes_[node.right], v, v_sq)) {
        stack[top++] = node.right;  // the more promising child is visited first
        stack[top++] = node.left;
      } else {
        stack[top++] = node.left;
        stack[top++] = node.right;
      }
    }
    return best;
  }

  /// Site indices in tree (spatially coherent) order.
  [[nodiscard]] const std::vector<int>& order() const { return order_; }

  /// The up to `count` sites whose anchors are nearest to `v` (Euclidean), unordered.
  void nearest(const Vec2& v, std::size_t count, std::vector<std::pair<double, int>>& heap) const {
    heap.clear();
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& node = nodes_[stack[--top]];
      if (heap.size() == count && box_distance(node, v) >= heap.front().first) continue;
      if (node.left < 0) {
        for (int k = node.begin; k < node.end; ++k) {
          const int j = order_[k];
          const double d = (v - anchors_[j]).squaredNorm();
          if (heap.size() < count) {
            heap.emplace_back(d, j);
            std::push_heap(heap.begin(), heap.end());
          } else if (d < heap.front().first) {
            std::pop_heap(heap.begin(), heap.end());
            heap.back() = {d, j};
            std::push_heap(heap.begin(), heap.end());
          }
        }
      } else if (box_distance(nodes_[node.left], v) <= box_distance(nodes_[node.right], v)) {
        stack[top++] = node.right;  // nearer child first
        stack[top++] = node.left;
      } else {
        stack[top++] = node.left;
        stack[top++] = node.right;
      }
    }
  }

 private:
  static constexpr int leaf_size = 8;
  struct Node {
    Vec2 low = Vec2::Zero(), high = Vec2::Zero();              // anchor box
    Vec2 slope_low = Vec2::Zero(), slope_high = Vec2::Zero();  // box of the c_j
    Vec2 reference = Vec2::Zero();                             // v₀
    double max_at_reference = 0;                               // max_j f_j(v₀)
    int begin = 0, end = 0, left = -1, right = -1;
  };

  static double box_distance(const Node& node, const Vec2& v) {
    return (node.low - v).cwiseMax(v - node.high).cwiseMax(0.0).squaredNorm();
  }
  static double lower_bound(const Node& node, const Vec2& v, double v_sq) {
    const Vec2 offset = v - node.reference;
    const double largest = node.max_at_reference +
                           std::max(node.slope_low.x() * offset.x(), node.slope_high.x() * offset.x()) +
                           std::max(node.slope_low.y() * offset.y(), node.slope_high.y() * offset.y());
    return v_sq - 2 * largest;
  }

  int build(int begin, int end) {
    const int index = static_cast<int>(nodes_.size());
    nodes_.push_back({});
    Node node;
    node.low = node.slope_low = Vec2::Constant(INFINITY);
    node.high = node.slope_high = Vec2::Constant(-INFINITY);
    for (int k = begin; k < end; ++k) {
      const int j = order_[k];
      node.low = node.low.cwiseMin(anchors_[j]);
      node.high = node.high.cwiseMax(anchors_[j]);
      node.slope_low = node.slope_low.cwiseMin(centers_[j]);
      node.slope_high = node.slope_high.cwiseMax(centers_[j]);
    }
    node.reference = (node.low + node.high) / 2;
    // f_j(v₀) = (|v₀|² − pow_j(v₀)) / 2, evaluated in the accurate power form.
    node.max_at_reference = -INFINITY;
    for (int k = begin; k < end; ++k) {
      const int j = order_[k];
      const double power = (node.reference - centers_[j]).squaredNorm() - weights_[j];
      node.max_at_reference = std::max(node.max_at_reference, (node.reference.squaredNorm() - power) / 2);
    }
    // Round-off guard: the bound must stay a bound.
    node.max_at_reference += 1e-12 * (std::abs(node.max_at_reference) + 1e-300);
    node.begin = begin;
    node.end = end;
    if (end - begin > leaf_size) {
      const int axis = (node.high - node.low).x() >= (node.high - node.low).y() ? 0 : 1;
      const int middle = (begin + end) / 2;
      std::nth_element(order_.begin() + begin, order_.begin() + middle, order_.begin() + end,
                       [&](int a, int b) { return anchors_[a][axis] < anchors_[b][axis]; });
      node.left = build(begin, middle);
      node.right = build(middle, end);
    }
    nodes_[index] = node;
    return index;
  }

  std::span<const Vec2> centers_;
  std::span<const double> weights_;
  std::span<const Vec2> anchors_;
  std::vector<int> order_;
  std::vector<Node> nodes_;
};

}  // namespace

bool has_regular_triangulation() {
#ifdef SDOT_HAVE_CGAL
  return true;
#else
  return false;
#endif
}

#ifdef SDOT_HAVE_CGAL
namespace {

/// A number that increases with the angle of `d` ≠ 0 from the x axis, counter-clockwise over
/// [0, 2π) → [0, 4) (cheaper than atan2, for sorting).
double pseudo_angle(const Vec2& d) {
  const double p = d.x() / (std::abs(d.x()) + std::abs(d.y()));
  return d.y() < 0 ? 3 + p : 1 - p;
}

/// Cell i straight from its Laguerre neighbours when it lies inside the domain, in coordinates
/// u = v − `center`: `line(j)` is the bisector with neighbour j, {u : normal·u + offset ≥ 0} on
/// the cell's side, so the edges in counter-clockwise order are the neighbours by the angle of
/// −normal (the outward normal), and each vertex is where consecutive ones cross
/// (cell_from_ordered_lines). False for a cell that reaches the domain's boundary, and where
/// cell_from_ordered_lines declines: the caller clips.
template <class Line>
bool cell_inside_domain(ChartCell& cell, const Vec2& center, std::span<const int> neighbors, const Line& line,
                        const std::vector<Vec2>& boundary) {
  struct Entry {
    double angle;
    ChartLine line;
    int label;
  };
  thread_local std::vector<Entry> lines;
  thread_local std::vector<Vec2> normals;
  thread_local std::vector<double> offsets;
  thread_local std::vector<int> labels;
  lines.clear();
  for (int j : neighbors) {
    const ChartLine bisector = line(j);
    if (!(bisector.normal.x() != 0 || bisector.normal.y() != 0)) return false;  // equal centres: one is hidden
    lines.push_back({pseudo_angle(-bisector.normal), bisector, j});
  }
  // insertion sort: a few lines, and stable, so equal angles keep a fixed order (and are declined)
  for (std::size_t k = 1; k < lines.size(); ++k)
    for (std::size_t m = k; m > 0 && lines[m - 1].angle > lines[m].angle; --m) std::swap(lines[m - 1], lines[m]);
  normals.clear(), offsets.clear(), labels.clear();
  for (const Entry& entry : lines)
    normals.push_back(entry.line.normal), offsets.push_back(entry.line.offset), labels.push_back(entry.label);
  double bound = 0;  // the domain's extent around the centre: a cell inside it is within
  for (const Vec2& corner : boundary) bound = std::max(bound, (corner - center).cwiseAbs().maxCoeff());
  thread_local ChartCell work;
  if (!cell_from_ordered_lines(work, normals, offsets, labels, bound)) return false;
  // Inside the domain when every vertex is on the inner side of every domain edge.
  for (const Vec2& v : work.vertices)
    for (std::size_t k = 0; k < boundary.size(); ++k) {
      const Vec2 a = boundary[k] - center, b = boundary[k + 1 == boundary.size() ? 0 : k + 1] - center;
      if ((b - a).x() * (v - a).y() - (b - a).y() * (v - a).x() <= 0) return false;
    }
  cell.vertices.resize(work.vertices.size());
  for (std::size_t k = 0; k < work.vertices.size(); ++k) cell.vertices[k] = work.vertices[k] + center;
  cell.neighbors.assign(work.neighbors.begin(), work.neighbors.end());
  return true;
}

/// A cell: read off its neighbours when it lies inside the domain (cell_inside_domain), else the
/// domain clipped by its neighbours' bisectors `line(j)`, in coordinates u = v − `center`.
/// The clipping runs in a per-thread buffer; the cell gets exactly-sized copies (the buffers'
/// capacity, grown by every cell the thread clipped, would otherwise stay with the cells).
template <class Line>
void clip_cell(ChartCell& cell, const Vec2& center, std::span<const int> neighbors, const Line& line,
               const std::vector<Vec2>& boundary) {
  if (cell_inside_domain(cell, center, neighbors, line, boundary)) return;
  thread_local ChartCell work;
  work.vertices.resize(boundary.size());
  work.neighbors.resize(boundary.size());
  for (std::size_t k = 0; k < boundary.size(); ++k) {
    work.vertices[k] = boundary[k] - center;
    work.neighbors[k] = boundary_label(static_cast<int>(k));
  }
  for (int j : neighbors) {
    const ChartLine bisector = line(j);
    // A bisector beyond double range (overflowed weights): no cell, which a line search rejects.
    if (!bisector.normal.allFinite() || !std::isfinite(bisector.offset)) work.vertices.clear();
    if (!work.vertices.empty()) clip(work, bisector.normal, bisector.offset, j);
    if (work.vertices.empty()) {
      cell.vertices.clear();
      cell.neighbors.clear();
      return;
    }
  }
  cell.vertices.resize(work.vertices.size());
  for (std::size_t k = 0; k < work.vertices.size(); ++k) cell.vertices[k] = work.vertices[k] + center;
  cell.neighbors.assign(work.neighbors.begin(), work.neighbors.end());
}

/// The power bisector of sites i and j in coordinates u = v − c_i: −2d·u + |d|² + w_i − w_j ≥ 0
/// with d = c_j − c_i, without cancellation between large terms.
struct PowerBisector {
  std::span<const Vec2> centers;
  std::span<const double> power_weight;
  std::size_t i;
  ChartLine operator()(int j) const {
    const auto k = static_cast<std::size_t>(j);
    const Vec2 d = centers[k] - centers[i];
    return {-2 * d, d.squaredNorm() + power_weight[i] - power_weight[k]};
  }
};

/// The cells over `domain` whose neighbours are those of the regular triangulation of
/// `topology_centers` and `topology_weights`, kept in `warm_start` when given; cell i is built
/// in coordinates u = v − `cell_center(i)` by the bisectors `cell_lines(i)(j)`.
template <class CellCenter, class CellLines>
std::vector<ChartCell> cells_over_triangulation(std::span<const Vec2> topology_centers,
                                                std::span<const double> topology_weights, const ConvexPolygon& domain,
                                                bool stop_at_empty_cell, std::size_t own_cells,
                                                PowerDiagramWarmStart* warm_start, const CellCenter& cell_center,
                                                const CellLines& cell_lines) {
  const std::size_t n = topology_centers.size();
  // From the last triangulation when it has the same centres (taken, not copied: a concurrent
  // build finds none and starts from scratch), else from scratch, and where flips cannot finish.
  std::optional<detail::RegularTriangulation> flipped;
  std::uint64_t fingerprint = 0;
  detail::SiteTriangulation surface;
  if (warm_start) {
    fingerprint = detail::centers_fingerprint(topology_centers);
    {
      const std::lock_guard lock(warm_start->mutex);
      if (warm_start->count == n && warm_start->fingerprint == fingerprint) surface = std::move(warm_start->surface);
    }
    // More flips than sites: a start that far off is not worth finishing.
    if (!surface.triangles.empty())
      flipped = detail::regular_triangulation_by_flips(topology_centers, topology_weights, surface, n);
  }
  auto triangulation = flipped ? std::move(*flipped)
                               : detail::regular_triangulation(topology_centers, topology_weights, stop_at_empty_cell,
                                                               warm_start != nullptr);
  if (warm_start && !flipped && !triangulation.triangles.empty())
    surface = detail::SiteTriangulation{std::move(triangulation.triangles), {}};
  if (warm_start && !surface.triangles.empty()) {
    const std::lock_guard lock(warm_start->mutex);
    warm_start->count = n, warm_start->fingerprint = fingerprint;
    warm_start->surface = std::move(surface);
  }
  std::vector<ChartCell> cells(n);  // after the triangulation, whose memory is freed by then
  // A hidden site has an empty cell: a line search rejects the step without the other cells.
  if (triangulation.stopped_at_hidden ||
      (stop_at_empty_cell &&
       std::find(triangulation.is_vertex.begin(), triangulation.is_vertex.end(), 0) != triangulation.is_vertex.end()))
    return cells;
  std::atomic<bool> found_empty{false};
  // In the triangulation's storage order, close to its (Hilbert) insertion order: neighbouring
  // cells share their neighbours' data in cache.
  const auto& order = triangulation.order;
#pragma omp parallel for schedule(dynamic, 256)
  for (std::size_t position = 0; position < order.size(); ++position) {
    if (stop_at_empty_cell && found_empty.load(std::memory_order_relaxed)) continue;
    const auto i = static_cast<std::size_t>(order[position]);
    clip_cell(cells[i], cell_center(i), triangulation.neighbors.of(i), cell_lines(i), domain.vertices());
    if (cells[i].vertices.empty() && i < own_cells) found_empty.store(true, std::memory_order_relaxed);
  }
  return cells;
}

/// The cells of the power diagram of `centers` and `power_weight` over `domain`, each in
/// coordinates u = v − c_i, from their regular triangulation.
std::vector<ChartCell> power_diagram_by_triangulation(std::span<const Vec2> centers,
                                                      std::span<const double> power_weight, const ConvexPolygon& domain,
                                                      bool stop_at_empty_cell, std::size_t own_cells,
                                                      PowerDiagramWarmStart* warm_start) {
  return cells_over_triangulation(
      centers, power_weight, domain, stop_at_empty_cell, own_cells, warm_start,
      [&](std::size_t i) { return centers[i]; },
      [&](std::size_t i) {
        return PowerBisector{centers, power_weight, i};
      });
}

}  // namespace
#endif

std::shared_ptr<PowerDiagramWarmStart> make_power_diagram_warm_start() {
  return std::make_shared<PowerDiagramWarmStart>();
}

namespace {
/// True when every centre and weight is finite. Weights beyond double range (e^h overflowing in
/// a line search's trial step, or a user's start) have no diagram: the builders then return
/// empty cells, which a line search rejects, instead of feeding infinities to the predicates.
bool all_finite(std::span<const Vec2> centers, std::span<const double> weights) {
  return std::all_of(centers.begin(), centers.end(), [](const Vec2& c) { return c.allFinite(); }) &&
         std::all_of(weights.begin(), weights.end(), [](double w) { return std::isfinite(w); });
}
}  // namespace

std::vector<ChartCell> build_power_diagram(std::span<const Vec2> centers, std::span<const double> power_weight,
                                           const ConvexPolygon& domain, std::span<const Vec2> anchors,
                                           bool stop_at_empty_cell, PowerDiagramMethod method, std::size_t own_cells,
                                           PowerDiagramWarmStart* warm_start) {
  if (method == PowerDiagramMethod::regular_triangulation && !has_regular_triangulation())
    throw InputError("method", "this build of sdot has no regular triangulation (configure with SDOT_WITH_CGAL=ON)");
  if (!all_finite(centers, power_weight)) return std::vector<ChartCell>(centers.size());
#ifdef SDOT_HAVE_CGAL
  if (method != PowerDiagramMethod::kd_tree)
    return power_diagram_by_triangulation(centers, power_weight, domain, stop_at_empty_cell, own_cells, warm_start);
#else
  (void)warm_start;  // only triangulations are kept
#endif
  // Each cell starts as the domain clipped by the sites of the nearest centres; then, while some
  // site j is strictly below the envelope at a vertex v of the cell (pow_j(v) < pow_i(v)), the
  // cell is clipped by it. A kd-tree holding the largest w per node finds such j exactly
  // (branch and bound), so the loop ends with the exact cell whatever the weights.
  // Clipping runs in coordinates u = v − c_i, where the bisector with j is
  // −2d·u + |d|² + w_i − w_j ≥ 0 (d = c_j − c_i): no cancellation between large terms, so
  // vertices are accurate to round-off of the cell's own size.
  const std::size_t n = centers.size();
  std::vector<ChartCell> cells(n);
  if (n == 0) return cells;
  if (anchors.empty()) anchors = centers;
  const PowerTree tree(centers, power_weight, anchors);
  const auto& boundary = domain.vertices();
  const std::size_t seed_count = std::min<std::size_t>(n, 13);

  std::atomic<bool> found_empty{false};
#pragma omp parallel
  {
    std::vector<std::pair<double, int>> heap;
    std::vector<int> used, pending;
    // Cells in tree order: neighbouring cells share tree nodes and stay in cache.
#pragma omp for schedule(dynamic, 256)
    for (std::size_t position = 0; position < n; ++position) {
      if (stop_at_empty_cell && found_empty.load(std::memory_order_relaxed)) continue;
      const auto i = static_cast<std::size_t>(tree.order()[position]);
      const Vec2 center = centers[i];
      ChartCell& cell = cells[i];
      cell.vertices.resize(boundary.size());
      cell.neighbors.resize(boundary.size());
      for (std::size_t k = 0; k < boundary.size(); ++k) {
        cell.vertices[k] = boundary[k] - center;
        cell.neighbors[k] = boundary_label(static_cast<int>(k));
      }
      auto cut = [&](int j) {
        const Vec2 d = centers[static_cast<std::size_t>(j)] - center;
        clip(cell, -2 * d, d.squaredNorm() + power_weight[i] - power_weight[static_cast<std::size_t>(j)], j);
        used.push_back(j);
      };
      used.assign(1, static_cast<int>(i));
      tree.nearest(anchors[i], seed_count, heap);
      std::sort(heap.begin(), heap.end());
      for (const auto& [distance, j] : heap) {
        if (j == static_cast<int>(i)) continue;
        cut(j);
        if (cell.vertices.empty()) break;
      }
      // Clip by the site lowest below the envelope at each vertex until none is below: the
      // lowest one owns that vertex's neighbourhood, so each round removes wrong vertices.
      while (!cell.vertices.empty()) {
        pending.clear();
        for (const auto& u : cell.vertices) {
          const double own = u.squaredNorm() - power_weight[i];
          // Slack: the sites through v itself (its Laguerre neighbours) are not below it.
          const double slack = 1e-13 * (std::abs(own) + u.squaredNorm() + 1e-300);
          const int j = tree.lowest(u + center, own - slack);
          if (j >= 0 && std::find(pending.begin(), pending.end(), j) == pending.end()) pending.push_back(j);
        }
        if (pending.empty()) break;
        bool progress = false;
        for (int j : pending) {
          if (std::find(used.begin(), used.end(), j) != used.end()) continue;  // round-off: already clipped
          cut(j);
          progress = true;
          if (cell.vertices.empty()) break;
        }
        if (!progress) break;
      }
      if (cell.vertices.empty() && i < own_cells) found_empty.store(true, std::memory_order_relaxed);
      for (auto& u : cell.vertices) u += center;
    }
  }
  return cells;
}

std::vector<ChartCell> build_chart_diagram_with_fixed_centers(std::span<const Vec2> fixed_centers,
                                                              std::span<const double> fixed_power_weights,
                                                              const ChartBisector& bisector,
                                                              const ConvexPolygon& domain, bool stop_at_empty_cell,
                                                              PowerDiagramWarmStart* warm_start) {
  if (fixed_centers.size() != fixed_power_weights.size())
    throw InputError("fixed_power_weights", "there are " + std::to_string(fixed_power_weights.size()) +
                                                " power weights for " + std::to_string(fixed_centers.size()) +
                                                " fixed centres");
  if (!has_regular_triangulation())
    throw InputError("method", "this build of sdot has no regular triangulation (configure with SDOT_WITH_CGAL=ON)");
#ifdef SDOT_HAVE_CGAL
  if (!all_finite(fixed_centers, fixed_power_weights)) return std::vector<ChartCell>(fixed_centers.size());
  return cells_over_triangulation(
      fixed_centers, fixed_power_weights, domain, stop_at_empty_cell, std::numeric_limits<std::size_t>::max(),
      warm_start, [&](std::size_t i) { return fixed_centers[i]; },
      [&](std::size_t i) { return [&bisector, i](int j) { return bisector(i, static_cast<std::size_t>(j)); }; });
#else
  (void)bisector, (void)domain, (void)stop_at_empty_cell, (void)warm_start;
  return {};
#endif
}

std::vector<ChartCell> build_chart_diagram(std::span<const Vec3> dual, const ConvexPolygon& domain,
                                           std::span<const Vec2> anchors, bool stop_at_empty_cell,
                                           PowerDiagramMethod method) {
  // The affine functions as power-diagram sites: maximising f_i is minimising
  // pow_i(v) = |v|² − 2 f_i(v) = |v − c_i|² − w_i, with c_i = a_i.xy and w_i = 2 a_i.z + |c_i|².
  std::vector<Vec2> centers(dual.size());
  std::vector<double> weights(dual.size());
  for (std::size_t i = 0; i < dual.size(); ++i) {
    centers[i] = dual[i].head<2>();
    weights[i] = 2 * dual[i].z() + centers[i].squaredNorm();
  }
  return build_power_diagram(centers, weights, domain, anchors, stop_at_empty_cell, method);
}

Hull3 convex_hull_3d(std::span<const Vec3> points, bool with_surface) {
  Hull3 hull;
  hull.is_vertex.assign(points.size(), 0);
  hull.max_facet_offset = -INFINITY;
  std::vector<std::array<int, 3>> triangles;
  triangles.reserve(2 * points.size());
  run_qhull(points, [&](qhT* qh, facetT* facet) {
    hull.max_facet_offset = std::max(hull.max_facet_offset, facet->offset);
    std::array<int, 3> t{};
    int count = 0;
    vertexT *vertex = nullptr, **vertexp = nullptr;
    FOREACHvertex_(facet->vertices) {
      const int id = qh_pointid(qh, vertex->point);
      hull.is_vertex[id] = 1;
      if (count < 3) t[count] = id;
      ++count;
    }
    if (count == 3) triangles.push_back(t);
  });
  hull.edges = triangles_to_adjacency(triangles, points.size());
  if (with_surface && hull.max_facet_offset < 0) hull.surface = oriented_surface(points, std::move(triangles));
  return hull;
}

namespace {

// The surface that convex_hull_3d_by_flips grows outward to the hull: triangles (counter-clockwise
// seen from outside) with opposite half-edges, 3-1 flips leave dead slots that later 1-3 splits reuse.
class FlipSurface {
 public:
  FlipSurface(std::span<const Vec3> points, HullTriangulation& start)
      : points_(points),
        tri_(start.triangles),
        opp_(start.opposite),
        alive_(tri_.size(), 1),
        touched_(tri_.size(), 0) {}

  [[nodiscard]] const Vec3& point(int v) const { return points_[static_cast<std::size_t>(v)]; }
  [[nodiscard]] int vertex(int h) const { return tri_[static_cast<std::size_t>(h / 3)][h % 3]; }
  [[nodiscard]] int next(int h) const { return 3 * (h / 3) + (h % 3 + 1) % 3; }
  [[nodiscard]] int prev(int h) const { return 3 * (h / 3) + (h % 3 + 2) % 3; }
  [[nodiscard]] int twin(int h) const { return opp_[static_cast<std::size_t>(h)]; }
  [[nodiscard]] bool alive(int h) const { return alive_[static_cast<std::size_t>(h / 3)] != 0; }
  [[nodiscard]] int half_edges() const { return static_cast<int>(opp_.size()); }

  [[nodiscard]] bool faces_out(int a, int b, int c) const { return point(a).dot(point(b).cross(point(c))) > 0; }
  /// d lies above the plane of (a, b, c), counter-clockwise from outside; the relative tolerance
  /// keeps nearly coplanar points (co-circular cells) from flipping back and forth.
  [[nodiscard]] bool above(int a, int b, int c, int d) const { return side(a, b, c, d) > 0; }
  [[nodiscard]] bool below(int a, int b, int c, int d) const { return side(a, b, c, d) < 0; }
  /// Half-edge h = a→b of (a, b, c) is reflex when the apex d across it lies above (a, b, c).
  [[nodiscard]] bool reflex(int h) const { return above(vertex(h), vertex(next(h)), vertex(prev(h)), apex(twin(h))); }
  [[nodiscard]] int apex(int h) const { return vertex(prev(h)); }
  /// Neither triangle of the edge of h has changed since the surface was made: its reflex test
  /// gives what it gave then (it reads those two triangles and nothing else that changes).
  [[nodiscard]] bool untouched(int h) const {
    return touched_[static_cast<std::size_t>(h / 3)] == 0 && touched_[static_cast<std::size_t>(twin(h) / 3)] == 0;
  }

  /// Degree of the vertex that h leaves, counted up to `cap`.
  [[nodiscard]] int degree(int h, int cap) const {
    int count = 0;
    for (int g = h;;) {
      if (++count >= cap) return count;
      g = twin(prev(g));
      if (g == h) return count;
    }
  }

  /// Flips h = a→b of (a, b, c) and (b, a, d) to (a, d, c) and (d, b, c).
  void flip(int h, std::vector<int>& stack) {
    const int g = twin(h);
    const int t = h / 3, t2 = g / 3;
    const int a = vertex(h), b = vertex(next(h)), c = apex(h), d = apex(g);
    const int o_ad = twin(next(g)), o_db = twin(prev(g)), o_bc = twin(next(h)), o_ca = twin(prev(h));
    set(t, {a, d, c});   // a→d, d→c, c→a
    set(t2, {d, b, c});  // d→b, b→c, c→d
    link(3 * t + 0, o_ad);
    link(3 * t + 1, 3 * t2 + 2);
    link(3 * t + 2, o_ca);
    link(3 * t2 + 0, o_db);
    link(3 * t2 + 1, o_bc);
    for (int e : {3 * t + 0, 3 * t + 2, 3 * t2 + 0, 3 * t2 + 1}) stack.push_back(e);
  }

  /// Removes the degree-3 vertex a that h = a→b leaves: (a, b, c), (b, a, d), (a, c, d) become (b, c, d).
  void remove_vertex(int h, std::vector<int>& stack) {
    const int g = twin(h), h3 = twin(prev(h));
    const int t = h / 3;
    const int b = vertex(next(h)), c = apex(h), d = apex(g);
    const int o_bc = twin(next(h)), o_db = twin(prev(g)), o_cd = twin(next(h3));
    set(t, {b, c, d});
    link(3 * t + 0, o_bc);
    link(3 * t + 1, o_cd);
    link(3 * t + 2, o_db);
    kill(g / 3);
    kill(h3 / 3);
    for (int e : {3 * t + 0, 3 * t + 1, 3 * t + 2}) stack.push_back(e);
  }

  /// Splits triangle t = (x, y, z) at p into (x, y, p), (y, z, p), (z, x, p).
  void split(int t, int p, std::vector<int>& stack) {
    const auto [x, y, z] = tri_[static_cast<std::size_t>(t)];
    const int o_xy = twin(3 * t + 0), o_yz = twin(3 * t + 1), o_zx = twin(3 * t + 2);
    const int t4 = new_triangle(), t5 = new_triangle();
    set(t, {x, y, p});
    set(t4, {y, z, p});
    set(t5, {z, x, p});
    link(3 * t + 0, o_xy);
    link(3 * t4 + 0, o_yz);
    link(3 * t5 + 0, o_zx);
    link(3 * t + 1, 3 * t4 + 2);
    link(3 * t4 + 1, 3 * t5 + 2);
    link(3 * t5 + 1, 3 * t + 2);
    for (int e : {3 * t + 0, 3 * t4 + 0, 3 * t5 + 0}) stack.push_back(e);
  }

  /// The live triangle whose cone from the origin holds the direction of p, by walking from
  /// triangle `from`; -1 when the walk does not arrive within `max_steps`.
  [[nodiscard]] int locate(int p, int from, int max_steps) const {
    int t = from;
    for (int step = 0; step < max_steps; ++step) {
      bool inside = true;
      for (int i = 0; i < 3; ++i) {
        const int k = (i + step) % 3;  // rotating the first edge tried keeps the walk from cycling
        const auto& v = tri_[static_cast<std::size_t>(t)];
        if (point(p).dot(point(v[k]).cross(point(v[(k + 1) % 3]))) < 0) {
          t = twin(3 * t + k) / 3;
          inside = false;
          break;
        }
      }
      if (inside) return t;
    }
    return -1;
  }
  [[nodiscard]] int any_live_triangle() const {
    return static_cast<int>(std::find(alive_.begin(), alive_.end(), 1) - alive_.begin());
  }

  /// +1 when d lies above the plane of (a, b, c), −1 below, 0 within the relative tolerance.
  [[nodiscard]] int side(int a, int b, int c, int d) const {
    const Vec3 ab = point(b) - point(a), ac = point(c) - point(a), ad = point(d) - point(a);
    const double volume = ab.cross(ac).dot(ad), tolerance = 1e-12 * ab.norm() * ac.norm() * ad.norm();
    return volume > tolerance ? 1 : (volume < -tolerance ? -1 : 0);
  }

  /// Drops dead slots and renumbers the half-edges.
  void compact() {
    std::vector<int> slot(tri_.size(), -1);
    int count = 0;
    for (std::size_t t = 0; t < tri_.size(); ++t)
      if (alive_[t]) slot[t] = count++;
    std::vector<int> opposite(3 * static_cast<std::size_t>(count));
    for (std::size_t t = 0; t < tri_.size(); ++t) {
      if (!alive_[t]) continue;
      const auto s = static_cast<std::size_t>(slot[t]);
      tri_[s] = tri_[t];
      for (std::size_t k = 0; k < 3; ++k) {
        const int o = opp_[3 * t + k];
        opposite[3 * s + k] = 3 * slot[static_cast<std::size_t>(o / 3)] + o % 3;
      }
    }
    tri_.resize(static_cast<std::size_t>(count));
    opp_ = std::move(opposite);
    alive_.assign(tri_.size(), 1);
    touched_.assign(tri_.size(), 1);  // the slots are renumbered: no earlier test applies
    free_.clear();
  }

 private:
  void set(int t, std::array<int, 3> corners) {
    tri_[static_cast<std::size_t>(t)] = corners;
    touched_[static_cast<std::size_t>(t)] = 1;
  }
  void link(int h, int g) { opp_[static_cast<std::size_t>(h)] = g, opp_[static_cast<std::size_t>(g)] = h; }
  void kill(int t) {
    alive_[static_cast<std::size_t>(t)] = 0;
    free_.push_back(t);
  }
  int new_triangle() {
    if (!free_.empty()) {
      const int t = free_.back();
      free_.pop_back();
      alive_[static_cast<std::size_t>(t)] = 1;
      return t;
    }
    tri_.push_back({});
    opp_.resize(opp_.size() + 3, -1);
    alive_.push_back(1);
    touched_.push_back(1);
    return static_cast<int>(tri_.size()) - 1;
  }

  std::span<const Vec3> points_;
  std::vector<std::array<int, 3>>& tri_;
  std::vector<int>& opp_;
  std::vector<char> alive_;
  std::vector<char> touched_;  // per triangle slot: set (or made) since the surface was made
  std::vector<int> free_;
};

// The Morton (Z-order) code of the direction of x, 10 bits per axis.
std::uint32_t morton_code(const Vec3& x) {
  const Vec3 u = x.normalized();
  std::uint32_t code = 0;
  std::array<std::uint32_t, 3> cell{};
  for (int k = 0; k < 3; ++k)
    cell[static_cast<std::size_t>(k)] = static_cast<std::uint32_t>(std::clamp((u[k] + 1) * 512, 0.0, 1023.0));
  for (int bit = 9; bit >= 0; --bit)
    for (std::size_t k = 0; k < 3; ++k) code = (code << 1) | ((cell[k] >> bit) & 1u);
  return code;
}

// The tetrahedron on the points farthest along four tetrahedral directions, oriented outward:
// the start of an incremental hull. Empty when it does not hold the origin strictly inside.
HullTriangulation tetrahedron_around_origin(std::span<const Vec3> points) {
  HullTriangulation s;
  if (points.size() < 4) return s;
  const std::array<Vec3, 4> directions{Vec3(1, 1, 1), Vec3(1, -1, -1), Vec3(-1, 1, -1), Vec3(-1, -1, 1)};
  std::array<int, 4> corner{};
  for (std::size_t k = 0; k < 4; ++k) {
    double best = -INFINITY;
    for (std::size_t i = 0; i < points.size(); ++i)
      if (const double reach = points[i].dot(directions[k]) / points[i].norm(); reach > best)
        best = reach, corner[k] = static_cast<int>(i);
  }
  auto q = [&](int v) -> const Vec3& { return points[static_cast<std::size_t>(v)]; };
  const auto [a, b, c, d] = corner;
  // (a, b, c) counter-clockwise from outside has d behind it: swap when it does not
  std::array<int, 4> v{a, b, c, d};
  if ((q(b) - q(a)).cross(q(c) - q(a)).dot(q(d) - q(a)) > 0) std::swap(v[1], v[2]);
  s.triangles = {{v[0], v[1], v[2]}, {v[1], v[0], v[3]}, {v[2], v[1], v[3]}, {v[0], v[2], v[3]}};
  for (const auto& t : s.triangles)
    if (!(q(t[0]).dot(q(t[1]).cross(q(t[2]))) > 0)) return {};  // the origin is not strictly inside
  s = oriented_surface(points, s.triangles);
  return s;
}

}  // namespace

std::optional<Hull3> convex_hull_3d_by_flips(std::span<const Vec3> points, HullTriangulation start, bool stop_at_inside,
                                             bool with_edges) {
  const std::size_t n = points.size();
  if (start.triangles.empty()) start = tetrahedron_around_origin(points);
  if (start.triangles.empty() || start.opposite.size() != 3 * start.triangles.size()) return std::nullopt;
  std::vector<char> on_surface(n, 0);
  for (const auto& t : start.triangles)
    for (int v : t) {
      if (v < 0 || static_cast<std::size_t>(v) >= n) return std::nullopt;
      on_surface[static_cast<std::size_t>(v)] = 1;
    }
  FlipSurface surface(points, start);
  bool facing_in = false;
  const auto start_triangles = static_cast<std::ptrdiff_t>(start.triangles.size());
#pragma omp parallel for schedule(static, 4096) reduction(|| : facing_in)
  for (std::ptrdiff_t k = 0; k < start_triangles; ++k) {
    const auto& t = start.triangles[static_cast<std::size_t>(k)];
    if (!surface.faces_out(t[0], t[1], t[2])) facing_in = true;
  }
  if (facing_in) return std::nullopt;

  // Every operation below only adds volume (a reflex edge's flip, removing a vertex below its
  // neighbours' triangle, splitting a triangle at a point above it), so the surface grows to the
  // hull and a point found inside once stays inside: the flips end, at the hull (up to the
  // tolerance of `above`).
  // Past this many operations Qhull is cheaper anyway.
  const std::size_t max_operations = 16 * std::max(start.triangles.size(), 2 * n) + 1024;
  std::size_t operations = 0;
  std::vector<int> stack;
  bool stopped = false;  // at a point inside (with `stop_at_inside`)
  // The surface as it is, still star-shaped and facing out everywhere: a start for the next call.
  auto stopped_hull = [&]() {
    surface.compact();
    Hull3 hull;
    hull.is_vertex = std::move(on_surface);
    hull.stopped_at_inside = true;
    hull.surface = std::move(start);
    return hull;
  };
  // The start's edges are tested at once, in parallel: after a Newton step most of them are still
  // convex. Per half-edge: 0 when it is not the one of its edge that the loop below visits, 1 for a
  // convex edge, 2 for a reflex one. Only the edges that operations changed are tested again.
  const int start_half_edges = surface.half_edges();
  std::vector<char> start_edge(static_cast<std::size_t>(start_half_edges), 0);
#pragma omp parallel for schedule(static, 4096)
  for (int h = 0; h < start_half_edges; ++h)
    if (h < surface.twin(h)) start_edge[static_cast<std::size_t>(h)] = surface.reflex(h) ? 2 : 1;
  auto settle = [&]() {
    while (!stack.empty()) {
      const int h = stack.back();
      stack.pop_back();
      if (!surface.alive(h) || !surface.reflex(h)) continue;
      const int g = surface.twin(h);
      const int a = surface.vertex(h), b = surface.vertex(g), c = surface.apex(h), d = surface.apex(g);
      if (c == d) continue;
      if (surface.faces_out(a, d, c) && surface.faces_out(d, b, c)) {
        surface.flip(h, stack);
      } else {
        // The quad is not convex seen from the origin: its reflex corner (a or b) lies under the
        // others and leaves the hull once its degree is 3; until then other flips may reach it.
        const int corner = surface.faces_out(a, d, c) ? g : h;  // the half-edge leaving that corner
        const int v = surface.vertex(corner);
        const int x = surface.vertex(surface.next(corner)), y = surface.apex(corner),
                  z = surface.apex(surface.twin(corner));
        if (surface.degree(corner, 4) != 3 || !surface.faces_out(x, y, z) || !surface.below(x, y, z, v)) continue;
        surface.remove_vertex(corner, stack);
        on_surface[static_cast<std::size_t>(v)] = 0;
        if (stop_at_inside) {
          stopped = true;
          return true;
        }
      }
      if (++operations > max_operations) return false;
    }
    return true;
  };
  // Each edge of the start once, from the last half-edge down, its consequences settled before the
  // next: as a stack filled with them all would take them. An edge still convex and unchanged is
  // skipped, as that stack would skip it.
  for (int h = start_half_edges - 1; h >= 0; --h) {
    const char edge = start_edge[static_cast<std::size_t>(h)];
    if (edge == 0 || (edge == 1 && (operations == 0 || surface.untouched(h)))) continue;
    stack.push_back(h);
    if (!settle()) return std::nullopt;
    if (stopped) return stopped_hull();
  }

  // Points off the start (empty cells of the previous diagram): inserted where they lie above the
  // surface, which is then settled again.
  // Visited in Morton order of their directions, so that each walk starts near its goal (from
  // scratch in index order the walks made it 15× slower on 134k shuffled points).
  std::vector<std::pair<std::uint32_t, int>> missing;
  for (std::size_t i = 0; i < n; ++i)
    if (!on_surface[i]) missing.emplace_back(morton_code(points[i]), static_cast<int>(i));
  std::sort(missing.begin(), missing.end());
  int last = surface.any_live_triangle();
  for (const auto& [code, p] : missing) {
    const auto i = static_cast<std::size_t>(p);
    if (!surface.alive(3 * last)) last = surface.any_live_triangle();
    const int t = surface.locate(p, last, surface.half_edges() + 64);
    if (t < 0) return std::nullopt;
    last = t;
    const int h = 3 * t;
    if (!surface.above(surface.vertex(h), surface.vertex(h + 1), surface.vertex(h + 2), p)) continue;
    surface.split(t, p, stack);
    on_surface[i] = 1;
    if (!settle()) return std::nullopt;
    if (stopped) return stopped_hull();
  }

  // The final check, every live edge convex, and the largest facet offset: in parallel (both
  // reductions are exact, so the result does not depend on the thread count).
  // An unchanged edge of the start is tested once, as settle saw it; a changed one from both sides.
  const int half_edges = surface.half_edges();
  bool reflex_left = false;
#pragma omp parallel for schedule(static, 4096) reduction(|| : reflex_left)
  for (int h = 0; h < half_edges; ++h)
    if (surface.alive(h) && (surface.untouched(h) && h < start_half_edges ? start_edge[static_cast<std::size_t>(h)] == 2
                                                                          : surface.reflex(h)))
      reflex_left = true;
  if (reflex_left) return std::nullopt;
  surface.compact();
  Hull3 hull;
  hull.is_vertex = std::move(on_surface);
  double max_offset = -INFINITY;
  bool degenerate = false;
  const auto triangle_count = static_cast<std::ptrdiff_t>(start.triangles.size());
#pragma omp parallel for schedule(static, 4096) reduction(max : max_offset) reduction(|| : degenerate)
  for (std::ptrdiff_t k = 0; k < triangle_count; ++k) {
    const auto& t = start.triangles[static_cast<std::size_t>(k)];
    const Vec3 normal = (surface.point(t[1]) - surface.point(t[0])).cross(surface.point(t[2]) - surface.point(t[0]));
    const double length = normal.norm();
    if (!surface.faces_out(t[0], t[1], t[2]) || !(length > 0)) {
      degenerate = true;
      continue;
    }
    max_offset = std::max(max_offset, -normal.dot(surface.point(t[0])) / length);
  }
  if (degenerate) return std::nullopt;
  hull.max_facet_offset = max_offset;
  if (with_edges) hull.edges = triangles_to_adjacency(start.triangles, n, true);
  hull.surface = std::move(start);
  return hull;
}

}  // namespace sdot
