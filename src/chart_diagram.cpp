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

// Turns per-facet vertex triples into CSR adjacency (sorted, unique) for `count` points.
Adjacency triangles_to_adjacency(const std::vector<std::array<int, 3>>& triangles, std::size_t count) {
  Adjacency adjacency;
  adjacency.offsets.assign(count + 1, 0);
  for (const auto& t : triangles)
    for (int v : t) adjacency.offsets[v + 1] += 2;
  for (std::size_t i = 0; i < count; ++i) adjacency.offsets[i + 1] += adjacency.offsets[i];
  adjacency.neighbors.resize(adjacency.offsets[count]);
  std::vector<int> fill(adjacency.offsets.begin(), adjacency.offsets.end() - 1);
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      adjacency.neighbors[fill[a]++] = b;
      adjacency.neighbors[fill[b]++] = a;
    }
  // Sort and de-duplicate each list in place, then compact.
  std::size_t write = 0;
  int begin = adjacency.offsets[0];
  for (std::size_t i = 0; i < count; ++i) {
    const int end = adjacency.offsets[i + 1];
    auto first = adjacency.neighbors.begin() + begin, last = adjacency.neighbors.begin() + end;
    std::sort(first, last);
    last = std::unique(first, last);
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
  thread_local ChartCell out;
  out.vertices.clear();
  out.neighbors.clear();
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t next = (k + 1) % n;
    const double s = side[k], t = side[next];
    const Vec2& p = cell.vertices[k];
    const Vec2& q = cell.vertices[next];
    if (s >= 0) {
      if (t >= 0) {
        out.vertices.push_back(p);
        out.neighbors.push_back(cell.neighbors[k]);
      } else if (s == 0) {
        out.vertices.push_back(p);
        out.neighbors.push_back(label);
      } else {
        out.vertices.push_back(p);
        out.neighbors.push_back(cell.neighbors[k]);
        out.vertices.push_back(p + (s / (s - t)) * (q - p));
        out.neighbors.push_back(label);
      }
    } else if (t > 0) {
      out.vertices.push_back(p + (s / (s - t)) * (q - p));
      out.neighbors.push_back(cell.neighbors[k]);
    }
  }
  if (out.vertices.size() < 3) {
    cell.vertices.clear();
    cell.neighbors.clear();
    return;
  }
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

std::vector<ChartCell> build_power_diagram(std::span<const Vec2> centers, std::span<const double> power_weight,
                                           const ConvexPolygon& domain, std::span<const Vec2> anchors,
                                           bool stop_at_empty_cell) {
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
      if (cell.vertices.empty()) found_empty.store(true, std::memory_order_relaxed);
      for (auto& u : cell.vertices) u += center;
    }
  }
  return cells;
}

std::vector<ChartCell> build_chart_diagram(std::span<const Vec3> dual, const ConvexPolygon& domain,
                                           std::span<const Vec2> anchors, bool stop_at_empty_cell) {
  // Maximising f_i is minimising pow_i(v) = |v|² − 2 f_i(v) = |v − c_i|² − w_i, with
  // c_i = a_i.xy and w_i = 2 a_i.z + |c_i|².
  std::vector<Vec2> centers(dual.size());
  std::vector<double> power_weight(dual.size());
  for (std::size_t i = 0; i < dual.size(); ++i) {
    centers[i] = dual[i].head<2>();
    power_weight[i] = 2 * dual[i].z() + centers[i].squaredNorm();
  }
  return build_power_diagram(centers, power_weight, domain, anchors, stop_at_empty_cell);
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

std::optional<Hull3> convex_hull_3d_by_flips(std::span<const Vec3> points, HullTriangulation start) {
  auto& tri = start.triangles;
  auto& opp = start.opposite;
  const std::size_t n = points.size();
  if (tri.empty() || opp.size() != 3 * tri.size()) return std::nullopt;
  std::vector<char> used(n, 0);
  for (const auto& t : tri)
    for (int v : t) {
      if (v < 0 || static_cast<std::size_t>(v) >= n) return std::nullopt;
      used[static_cast<std::size_t>(v)] = 1;
    }
  if (std::find(used.begin(), used.end(), 0) != used.end()) return std::nullopt;  // no insertion by flips
  auto q = [&](int v) -> const Vec3& { return points[static_cast<std::size_t>(v)]; };
  auto faces_out = [&](int a, int b, int c) { return q(a).dot(q(b).cross(q(c))) > 0; };
  for (const auto& t : tri)
    if (!faces_out(t[0], t[1], t[2])) return std::nullopt;
  // Edge (a, b) of (a, b, c), with d across it, is reflex when d lies above the plane of (a, b, c).
  // The relative tolerance keeps nearly coplanar pairs (co-circular cells) from flipping back and forth.
  auto reflex = [&](int h) {
    const auto t = static_cast<std::size_t>(h / 3);
    const int k = h % 3;
    const int o = opp[static_cast<std::size_t>(h)];
    const int a = tri[t][k], b = tri[t][(k + 1) % 3], c = tri[t][(k + 2) % 3];
    const int d = tri[static_cast<std::size_t>(o / 3)][(o % 3 + 2) % 3];
    const Vec3 ab = q(b) - q(a), ac = q(c) - q(a), ad = q(d) - q(a);
    return ab.cross(ac).dot(ad) > 1e-12 * ab.norm() * ac.norm() * ad.norm();
  };
  std::vector<int> stack;
  stack.reserve(opp.size());
  for (int h = 0; h < static_cast<int>(opp.size()); ++h)
    if (h < opp[static_cast<std::size_t>(h)]) stack.push_back(h);
  // flips raise the enclosed volume, so they end; past this many, Qhull is cheaper anyway
  const std::size_t max_flips = 4 * tri.size() + 1024;
  std::size_t flips = 0;
  auto link = [&](int h, int g) { opp[static_cast<std::size_t>(h)] = g, opp[static_cast<std::size_t>(g)] = h; };
  while (!stack.empty()) {
    const int h = stack.back();
    stack.pop_back();
    if (!reflex(h)) continue;
    const int t = h / 3, k = h % 3;
    const int g = opp[static_cast<std::size_t>(h)];
    const int t2 = g / 3, k2 = g % 3;
    const auto ut = static_cast<std::size_t>(t), ut2 = static_cast<std::size_t>(t2);
    const int a = tri[ut][k], b = tri[ut][(k + 1) % 3], c = tri[ut][(k + 2) % 3];
    const int d = tri[ut2][(k2 + 2) % 3];
    if (!faces_out(a, d, c) || !faces_out(d, b, c) || c == d) {
      // the quad is not convex seen from the origin: other flips may fix it, else the final check fails
      continue;
    }
    if (++flips > max_flips) return std::nullopt;
    // outer half-edges' partners, read before rewriting: a→d, d→b (in t2), b→c, c→a (in t)
    const int o_ad = opp[static_cast<std::size_t>(3 * t2 + (k2 + 1) % 3)];
    const int o_db = opp[static_cast<std::size_t>(3 * t2 + (k2 + 2) % 3)];
    const int o_bc = opp[static_cast<std::size_t>(3 * t + (k + 1) % 3)];
    const int o_ca = opp[static_cast<std::size_t>(3 * t + (k + 2) % 3)];
    tri[ut] = {a, d, c};   // edges a→d, d→c, c→a
    tri[ut2] = {d, b, c};  // edges d→b, b→c, c→d
    link(3 * t + 0, o_ad);
    link(3 * t + 1, 3 * t2 + 2);
    link(3 * t + 2, o_ca);
    link(3 * t2 + 0, o_db);
    link(3 * t2 + 1, o_bc);
    for (int e : {3 * t + 0, 3 * t + 2, 3 * t2 + 0, 3 * t2 + 1}) stack.push_back(e);
  }
  for (std::size_t h = 0; h < opp.size(); ++h)  // the final check: every edge convex
    if (reflex(static_cast<int>(h))) return std::nullopt;
  Hull3 hull;
  hull.is_vertex.assign(n, 1);
  hull.max_facet_offset = -INFINITY;
  for (const auto& t : tri) {
    const Vec3 normal = (q(t[1]) - q(t[0])).cross(q(t[2]) - q(t[0]));
    const double length = normal.norm();
    if (!(length > 0)) return std::nullopt;
    hull.max_facet_offset = std::max(hull.max_facet_offset, -normal.dot(q(t[0])) / length);
  }
  hull.edges = triangles_to_adjacency(tri, n);
  hull.surface = std::move(start);
  return hull;
}

}  // namespace sdot
