// CGAL's 2-D regular triangulation (exact predicates, inexact constructions; the constructions are
// never used: cells are clipped from the neighbour lists in double precision).
#include "regular_triangulation.hpp"

#include "power_predicate.hpp"

#include <CGAL/Convex_hull_traits_adapter_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Regular_triangulation_2.h>
#include <CGAL/Regular_triangulation_face_base_2.h>
#include <CGAL/Regular_triangulation_vertex_base_2.h>
#include <CGAL/Spatial_sort_traits_adapter_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/ch_akl_toussaint.h>
#include <CGAL/property_map.h>
#include <CGAL/spatial_sort.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <utility>

namespace sdot::detail {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;

/// The kernel's power test behind the semi-static filter of power_predicate.hpp; the kernel's own
/// (interval, then exact) only where the filter cannot tell.
struct FilteredPowerTest {
  using WeightedPoint = Kernel::Weighted_point_2;
  using result_type = CGAL::Oriented_side;
  CGAL::Oriented_side operator()(const WeightedPoint& p, const WeightedPoint& q, const WeightedPoint& r,
                                 const WeightedPoint& t) const {
    const auto& a = p.point();
    const auto& b = q.point();
    const auto& c = r.point();
    const auto& d = t.point();
    if (const auto sign = power_test_sign_by_filter(a.x(), a.y(), p.weight(), b.x(), b.y(), q.weight(), c.x(), c.y(),
                                                    r.weight(), d.x(), d.y(), t.weight()))
      return *sign > 0 ? CGAL::ON_POSITIVE_SIDE : CGAL::ON_NEGATIVE_SIDE;
    return exact(p, q, r, t);
  }
  // The tests of fewer points (collinear and coincident configurations) are rare.
  CGAL::Oriented_side operator()(const WeightedPoint& p, const WeightedPoint& q, const WeightedPoint& t) const {
    return exact(p, q, t);
  }
  CGAL::Oriented_side operator()(const WeightedPoint& p, const WeightedPoint& t) const { return exact(p, t); }
  Kernel::Power_side_of_oriented_power_circle_2 exact;
};

/// The kernel, with FilteredPowerTest as its power test.
struct Traits : Kernel {
  using Power_side_of_oriented_power_circle_2 = FilteredPowerTest;
  [[nodiscard]] FilteredPowerTest power_side_of_oriented_power_circle_2_object() const { return {}; }
};

using VertexBase =
    CGAL::Triangulation_vertex_base_with_info_2<int, Traits, CGAL::Regular_triangulation_vertex_base_2<Traits>>;
using FaceBase = CGAL::Regular_triangulation_face_base_2<Traits>;
using Triangulation = CGAL::Regular_triangulation_2<Traits, CGAL::Triangulation_data_structure_2<VertexBase, FaceBase>>;

inline std::size_t at(int i) {
  return static_cast<std::size_t>(i);
}

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

/// Inserts the sites `members` (indices into `centers`) into `triangulation` along a
/// space-filling curve, each located from the last one. Members already in such an order (the
/// solver's sites are) are inserted as they come: CGAL's range insertion would sort them again at
/// every Newton step. False when it stopped at a hidden site (only with `stop_at_hidden`), or
/// because another part raised `stop`.
bool insert_sites(Triangulation& triangulation, std::span<const Vec2> centers, std::span<const double> power_weights,
                  std::vector<int> members, bool stop_at_hidden, std::atomic<bool>& stop) {
  std::vector<Vec2> member_centers(members.size());
  for (std::size_t k = 0; k < members.size(); ++k) member_centers[k] = centers[at(members[k])];
  if (!in_spatial_order(member_centers)) {
    std::vector<Kernel::Point_2> bare(members.size());
    for (std::size_t k = 0; k < members.size(); ++k)
      bare[k] = Kernel::Point_2(member_centers[k].x(), member_centers[k].y());
    std::vector<std::size_t> insertion(members.size());
    std::iota(insertion.begin(), insertion.end(), std::size_t{0});
    const auto bare_map = CGAL::make_property_map(std::as_const(bare));
    CGAL::spatial_sort(insertion.begin(), insertion.end(),
                       CGAL::Spatial_sort_traits_adapter_2<Kernel, decltype(bare_map)>(bare_map));
    std::vector<int> sorted(members.size());
    for (std::size_t k = 0; k < members.size(); ++k) sorted[k] = members[insertion[k]];
    members = std::move(sorted);
  }
  Triangulation::Face_handle hint;
  std::size_t inserted = 0;
  for (const int i : members) {
    // CGAL's weighted point (p, w) has power |v − p|² − w: the same convention as ours.
    const auto vertex = triangulation.insert(
        Triangulation::Weighted_point(Kernel::Point_2(centers[at(i)].x(), centers[at(i)].y()), power_weights[at(i)]),
        hint);
    if (vertex == Triangulation::Vertex_handle()) continue;
    vertex->info() = i;
    hint = vertex->face();
    if (!stop_at_hidden) continue;
    // A point hidden by some of the points stays hidden by all of them: its cell is empty.
    if (triangulation.number_of_hidden_vertices() > 0) {
      stop = true;
      return false;
    }
    if (++inserted % 1024 == 0 && stop.load(std::memory_order_relaxed)) return false;
  }
  return true;
}

/// Adds the edges of `triangulation` at the sites that `owns` to the adjacency: counting
/// (`fill` null: adjacency.offsets[i + 1] += degree) or filling (at fill[i]).
template <class Owns>
void add_edges(const Triangulation& triangulation, Owns&& owns, Adjacency& adjacency, std::vector<int>* fill) {
  for (auto e = triangulation.finite_edges_begin(); e != triangulation.finite_edges_end(); ++e) {
    const auto& face = e->first;
    const int a = face->vertex(face->cw(e->second))->info(), b = face->vertex(face->ccw(e->second))->info();
    for (const auto& [from, to] : {std::pair{a, b}, std::pair{b, a}}) {
      if (!owns(from)) continue;
      if (fill)
        adjacency.neighbors[at((*fill)[at(from)]++)] = to;
      else
        ++adjacency.offsets[at(from) + 1];
    }
  }
}

/// The sites that one half leaves out, in a grid of bins, each with the box and the largest
/// weight of its sites: a triangle is regular with respect to all of them when it is with
/// respect to each bin's bound, or else to each site of the bins it cannot rule out.
struct LeftOut {
  Vec2 low, high, extent;  // the sites' box
  double max_weight = -std::numeric_limits<double>::infinity();
  int columns = 1, rows = 1;
  std::vector<int> start, sites;  // the bins' sites, bin by bin
  std::vector<Vec2> bin_low, bin_high;
  std::vector<double> bin_weight;
  // The same bounds for blocks of block × block bins.
  static constexpr int block = 8;
  int block_columns = 1;
  std::vector<Vec2> block_low, block_high;
  std::vector<double> block_weight;

  [[nodiscard]] bool empty() const { return sites.empty(); }

  void build(std::span<const Vec2> centers, std::span<const double> weights, std::vector<int> members) {
    constexpr double infinity = std::numeric_limits<double>::infinity();
    low = Vec2(infinity, infinity), high = -low;
    for (int i : members) {
      low = low.cwiseMin(centers[at(i)]), high = high.cwiseMax(centers[at(i)]);
      max_weight = std::max(max_weight, weights[at(i)]);
    }
    if (members.empty()) return;
    // About 16 sites per bin.
    const double side = std::sqrt(16 * std::max((high - low).prod(), 1e-300) / static_cast<double>(members.size()));
    extent = (high - low).cwiseMax(1e-300);
    columns = std::clamp(static_cast<int>(extent.x() / side) + 1, 1, 4096);
    rows = std::clamp(static_cast<int>(extent.y() / side) + 1, 1, 4096);
    const auto bins = at(columns * rows);
    auto bin_of = [&](int i) {
      const Vec2 t = (centers[at(i)] - low).cwiseQuotient(extent);
      const int column = std::min(columns - 1, static_cast<int>(t.x() * columns));
      const int row = std::min(rows - 1, static_cast<int>(t.y() * rows));
      return at(row * columns + column);
    };
    start.assign(bins + 1, 0);
    for (int i : members) ++start[bin_of(i) + 1];
    for (std::size_t b = 0; b < bins; ++b) start[b + 1] += start[b];
    sites.resize(members.size());
    std::vector<int> fill(start.begin(), start.end() - 1);
    bin_low.assign(bins, Vec2(infinity, infinity));
    bin_high.assign(bins, Vec2(-infinity, -infinity));
    bin_weight.assign(bins, -infinity);
    for (int i : members) {
      const auto b = bin_of(i);
      sites[at(fill[b]++)] = i;
      bin_low[b] = bin_low[b].cwiseMin(centers[at(i)]), bin_high[b] = bin_high[b].cwiseMax(centers[at(i)]);
      bin_weight[b] = std::max(bin_weight[b], weights[at(i)]);
    }
    block_columns = (columns + block - 1) / block;
    const auto blocks = at(block_columns * ((rows + block - 1) / block));
    block_low.assign(blocks, Vec2(infinity, infinity));
    block_high.assign(blocks, Vec2(-infinity, -infinity));
    block_weight.assign(blocks, -infinity);
    for (int row = 0; row < rows; ++row)
      for (int column = 0; column < columns; ++column) {
        const auto b = at(row * columns + column), k = at(row / block * block_columns + column / block);
        block_low[k] = block_low[k].cwiseMin(bin_low[b]), block_high[k] = block_high[k].cwiseMax(bin_high[b]);
        block_weight[k] = std::max(block_weight[k], bin_weight[b]);
      }
  }
};

/// Squared distance from `point` to the box [low, high].
double box_distance2(const Vec2& point, const Vec2& low, const Vec2& high) {
  return (low - point).cwiseMax(point - high).cwiseMax(0.0).squaredNorm();
}

/// Sites in two halves, split at the median abscissa, for two triangulations that can run in
/// parallel. Each half is triangulated with the other half's sites within `margin` of the split
/// and those near the set's boundary (ghosts). A site's neighbours are right when every triangle
/// at it is regular with respect to the sites left out too.
struct Split {
  double median = 0, margin = 0;
  std::array<LeftOut, 2> left_out;   // per half
  std::vector<char> half;            // per site: 0 left of the median, 1 right
  std::vector<char> boundary_ghost;  // per site: bit h set when half h takes it in as a ghost
};

/// Sites from which the diagram is built as two halves; below it, one triangulation.
constexpr std::size_t parallel_size = 20000;

bool make_split(std::span<const Vec2> centers, std::span<const double> power_weights, Split& split) {
  const std::size_t n = centers.size();
  std::vector<double> xs(n);
  Vec2 low = centers[0], high = centers[0];
  for (std::size_t i = 0; i < n; ++i) {
    xs[i] = centers[i].x();
    low = low.cwiseMin(centers[i]), high = high.cwiseMax(centers[i]);
  }
  std::nth_element(xs.begin(), xs.begin() + static_cast<std::ptrdiff_t>(n / 2), xs.end());
  split.median = xs[n / 2];
  const Vec2 extent = high - low;
  if (!(extent.x() > 0 && extent.y() > 0) || !std::isfinite(extent.x() + extent.y())) return false;
  // A typical cell's diameter is about sqrt(area / n); the margin holds a few rows of cells.
  split.margin = 8 * std::sqrt(extent.x() * extent.y() / static_cast<double>(n));
  // Weights that differ by much more than the margin's square move cells across it, and the halves
  // would not certify. H²'s centres, far outside its chart's domain, come with such weights (their
  // spread is about 480 margin² at 3·10⁵ sites, the plane's about 10 margin²).
  const auto [lightest, heaviest] = std::minmax_element(power_weights.begin(), power_weights.end());
  if (!(*heaviest - *lightest <= 40 * split.margin * split.margin)) return false;
  split.half.resize(n);
  std::array<std::size_t, 2> count{};
  std::array<std::vector<int>, 2> left_out;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = centers[i].x();
    split.half[i] = x < split.median ? 0 : 1;
    ++count[at(split.half[i])];
    if (x >= split.median + split.margin) left_out[0].push_back(static_cast<int>(i));
    if (x < split.median - split.margin) left_out[1].push_back(static_cast<int>(i));
  }
  if (count[0] < n / 4 || count[1] < n / 4) return false;  // many equal abscissae
  // Sites near the boundary of the set that a half would leave out join it as ghosts: the
  // triangles along the convex hull are slivers whose circles reach far along the boundary
  // (radius 172 at 10⁵ sites in the unit square). "Near" is: in a bin of side 4·sqrt(area/n)
  // (about 16 sites) next to an empty bin or to the grid's edge, or next to such a bin. The
  // extreme points of what a half leaves out join it too: its triangulation then has the convex
  // hull of all the sites.
  const double side = 4 * std::sqrt(extent.x() * extent.y() / static_cast<double>(n));
  const int columns = std::clamp(static_cast<int>(extent.x() / side) + 1, 1, 8192);
  const int rows = std::clamp(static_cast<int>(extent.y() / side) + 1, 1, 8192);
  auto bin_of = [&](std::size_t i) {
    const Vec2 t = (centers[i] - low).cwiseQuotient(extent);
    return std::pair{std::min(columns - 1, static_cast<int>(t.x() * columns)),
                     std::min(rows - 1, static_cast<int>(t.y() * rows))};
  };
  std::vector<int> bin_count(at(columns * rows), 0);
  for (std::size_t i = 0; i < n; ++i) {
    const auto [column, row] = bin_of(i);
    ++bin_count[at(row * columns + column)];
  }
  auto any_neighbor = [&](int column, int row, auto&& test) {
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc) {
        const int c = column + dc, r = row + dr;
        if (test(c, r)) return true;
      }
    return false;
  };
  std::vector<char> edge(bin_count.size(), 0), near_edge(bin_count.size(), 0);
  for (int row = 0; row < rows; ++row)
    for (int column = 0; column < columns; ++column)
      edge[at(row * columns + column)] = any_neighbor(column, row, [&](int c, int r) {
        return c < 0 || r < 0 || c >= columns || r >= rows || bin_count[at(r * columns + c)] == 0;
      });
  for (int row = 0; row < rows; ++row)
    for (int column = 0; column < columns; ++column)
      near_edge[at(row * columns + column)] = any_neighbor(column, row, [&](int c, int r) {
        return c >= 0 && r >= 0 && c < columns && r < rows && edge[at(r * columns + c)];
      });
  std::vector<Kernel::Point_2> points(n);
  for (std::size_t i = 0; i < n; ++i) points[i] = Kernel::Point_2(centers[i].x(), centers[i].y());
  const auto point_map = CGAL::make_property_map(std::as_const(points));
  split.boundary_ghost.assign(n, 0);
  for (std::size_t h = 0; h < 2; ++h) {
    std::vector<int> hull;
    CGAL::ch_akl_toussaint(left_out[h].begin(), left_out[h].end(), std::back_inserter(hull),
                           CGAL::Convex_hull_traits_adapter_2<Kernel, decltype(point_map)>(point_map));
    for (int i : hull) split.boundary_ghost[at(i)] |= static_cast<char>(1 << h);
    for (int i : left_out[h]) {
      const auto [column, row] = bin_of(at(i));
      if (near_edge[at(row * columns + column)]) split.boundary_ghost[at(i)] |= static_cast<char>(1 << h);
    }
    std::erase_if(left_out[h], [&](int i) { return (split.boundary_ghost[at(i)] >> h & 1) != 0; });
    split.left_out[h].build(centers, power_weights, std::move(left_out[h]));
  }
  return true;
}

/// Whether every finite triangle of `triangulation` at a site of half `h` is regular with respect
/// to the sites the half left out. Conservative: a triangle too close to call fails the check.
bool regular_at_half(const Triangulation& triangulation, std::span<const Vec2> centers,
                     std::span<const double> power_weights, const Split& split, int h) {
  const LeftOut& left_out = split.left_out[at(h)];
  if (left_out.empty()) return true;
  // Bins and sites the close calls may look at in all, a few per site of the half: past that the
  // split is not worth it.
  std::size_t budget = 16 * split.half.size();
  for (auto f = triangulation.finite_faces_begin(); f != triangulation.finite_faces_end(); ++f) {
    if (split.half[at(f->vertex(0)->info())] != h && split.half[at(f->vertex(1)->info())] != h &&
        split.half[at(f->vertex(2)->info())] != h)
      continue;
    // The power centre c of the triangle (a, b, c) and its power ρ = |c − a|² − w_a, with
    // u = c − a from 2⟨u, b − a⟩ = |b − a|² − (w_b − w_a) and the same for c.
    const auto& pa = f->vertex(0)->point();
    const auto& pb = f->vertex(1)->point();
    const auto& pc = f->vertex(2)->point();
    const Vec2 a(pa.x(), pa.y());
    const Vec2 db = Vec2(pb.x(), pb.y()) - a, dc = Vec2(pc.x(), pc.y()) - a;
    const double rb = db.squaredNorm() - (pb.weight() - pa.weight());
    const double rc = dc.squaredNorm() - (pc.weight() - pa.weight());
    const double det = 2 * (db.x() * dc.y() - db.y() * dc.x());
    const Vec2 u((rb * dc.y() - rc * db.y()) / det, (db.x() * rc - dc.x() * rb) / det);
    if (!std::isfinite(u.x()) || !std::isfinite(u.y())) return false;  // a flat triangle
    const Vec2 center = a + u;
    const double power = u.squaredNorm() - pa.weight();
    // A left-out site s is harmless when |c − s|² − w_s ≥ ρ, with room for the round-off of c.
    auto harmless = [&](double distance2, double weight) {
      const double room = 1e-9 * (distance2 + u.squaredNorm() + std::abs(pa.weight()) + std::abs(weight));
      return distance2 - weight >= power + room;
    };
    if (harmless(box_distance2(center, left_out.low, left_out.high), left_out.max_weight)) continue;
    // Too close to call from the box of all left-out sites (the huge circles of slivers along
    // the hull come here): block by block, bin by bin, then site by site, within sqrt(ρ + max weight)
    // of c (no site farther away can be in conflict).
    const double reach = std::sqrt(std::max(0.0, 2 * (power + left_out.max_weight)));
    auto bin_range = [&](double from, double to, double low, double extent, int count) {
      auto index = [&](double v) {
        return static_cast<int>(std::clamp(std::floor((v - low) / extent * count), 0.0, count - 1.0));
      };
      return std::pair{index(from), index(to)};
    };
    const auto [first_column, last_column] =
        bin_range(center.x() - reach, center.x() + reach, left_out.low.x(), left_out.extent.x(), left_out.columns);
    const auto [first_row, last_row] =
        bin_range(center.y() - reach, center.y() + reach, left_out.low.y(), left_out.extent.y(), left_out.rows);
    constexpr int block = LeftOut::block;
    for (int block_row = first_row / block; block_row <= last_row / block; ++block_row)
      for (int block_column = first_column / block; block_column <= last_column / block; ++block_column) {
        const auto k = at(block_row * left_out.block_columns + block_column);
        if (budget-- == 0) return false;
        if (harmless(box_distance2(center, left_out.block_low[k], left_out.block_high[k]), left_out.block_weight[k]))
          continue;
        for (int row = std::max(first_row, block_row * block); row <= std::min(last_row, block_row * block + block - 1);
             ++row)
          for (int column = std::max(first_column, block_column * block);
               column <= std::min(last_column, block_column * block + block - 1); ++column) {
            const auto b = at(row * left_out.columns + column);
            if (budget-- == 0) return false;
            if (left_out.start[b] == left_out.start[b + 1] ||
                harmless(box_distance2(center, left_out.bin_low[b], left_out.bin_high[b]), left_out.bin_weight[b]))
              continue;
            const auto sites_in_bin = at(left_out.start[b + 1] - left_out.start[b]);
            if (budget < sites_in_bin) return false;
            budget -= sites_in_bin;
            for (auto i = at(left_out.start[b]); i < at(left_out.start[b + 1]); ++i) {
              const int site = left_out.sites[i];
              if (!harmless((u - (centers[at(site)] - a)).squaredNorm(), power_weights[at(site)])) return false;
            }
          }
      }
  }
  return true;
}

/// The serial triangulation of all sites.
RegularTriangulation whole_triangulation(std::span<const Vec2> centers, std::span<const double> power_weights,
                                         bool stop_at_hidden, bool with_triangles) {
  const std::size_t n = centers.size();
  RegularTriangulation result;
  std::vector<int> members(n);
  std::iota(members.begin(), members.end(), 0);
  std::atomic<bool> stop{false};
  Triangulation triangulation;
  if (!insert_sites(triangulation, centers, power_weights, std::move(members), stop_at_hidden, stop)) {
    result.stopped_at_hidden = true;
    return result;
  }
  result.is_vertex.assign(n, 0);
  result.order.reserve(triangulation.number_of_vertices());
  for (auto v = triangulation.finite_vertices_begin(); v != triangulation.finite_vertices_end(); ++v) {
    result.is_vertex[at(v->info())] = 1;
    result.order.push_back(v->info());
  }
  if (with_triangles && result.order.size() == n)
    for (auto f = triangulation.finite_faces_begin(); f != triangulation.finite_faces_end(); ++f)
      result.triangles.push_back({f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()});
  Adjacency& adjacency = result.neighbors;
  adjacency.offsets.assign(n + 1, 0);
  const auto everyone = [](int) { return true; };
  add_edges(triangulation, everyone, adjacency, nullptr);
  for (std::size_t i = 0; i < n; ++i) adjacency.offsets[i + 1] += adjacency.offsets[i];
  adjacency.neighbors.resize(at(adjacency.offsets[n]));
  std::vector<int> fill(adjacency.offsets.begin(), adjacency.offsets.end() - 1);
  add_edges(triangulation, everyone, adjacency, &fill);
  return result;
}

/// The two halves of `split` triangulated side by side (one thread each when there are two);
/// false when a half's triangles could not be certified (the caller then triangulates the whole).
bool split_triangulation(std::span<const Vec2> centers, std::span<const double> power_weights, bool stop_at_hidden,
                         bool with_triangles, const Split& split, RegularTriangulation& result) {
  const std::size_t n = centers.size();
  std::array<Triangulation, 2> halves;
  std::array<char, 2> certified{};
  std::atomic<bool> stop{false};
#pragma omp parallel for schedule(static, 1) num_threads(2)
  for (int h = 0; h < 2; ++h) {
    std::vector<int> members;
    members.reserve(n / 2 + n / 16);
    for (std::size_t i = 0; i < n; ++i) {
      const double x = centers[i].x();
      const bool ghost = h == 0 ? x < split.median + split.margin : x >= split.median - split.margin;
      if (split.half[i] == h || ghost || (split.boundary_ghost[i] >> h & 1)) members.push_back(static_cast<int>(i));
    }
    Triangulation& triangulation = halves[at(h)];
    certified[at(h)] = insert_sites(triangulation, centers, power_weights, std::move(members), stop_at_hidden, stop) &&
                       regular_at_half(triangulation, centers, power_weights, split, h);
  }
  if (stop) {
    result.stopped_at_hidden = true;
    return true;
  }
  if (!certified[0] || !certified[1]) return false;
  result.is_vertex.assign(n, 0);
  for (int h = 0; h < 2; ++h)
    for (auto v = halves[at(h)].finite_vertices_begin(); v != halves[at(h)].finite_vertices_end(); ++v)
      if (split.half[at(v->info())] == h) {
        result.is_vertex[at(v->info())] = 1;
        result.order.push_back(v->info());
      }
  // Each triangle from the half that owns its smallest vertex: the half's triangles at its own
  // sites are the ones certified.
  if (with_triangles && result.order.size() == n)
    for (int h = 0; h < 2; ++h)
      for (auto f = halves[at(h)].finite_faces_begin(); f != halves[at(h)].finite_faces_end(); ++f) {
        const std::array<int, 3> t{f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()};
        if (split.half[at(std::min({t[0], t[1], t[2]}))] == h) result.triangles.push_back(t);
      }
  Adjacency& adjacency = result.neighbors;
  adjacency.offsets.assign(n + 1, 0);
  for (int h = 0; h < 2; ++h)
    add_edges(
        halves[at(h)], [&](int i) { return split.half[at(i)] == h; }, adjacency, nullptr);
  for (std::size_t i = 0; i < n; ++i) adjacency.offsets[i + 1] += adjacency.offsets[i];
  adjacency.neighbors.resize(at(adjacency.offsets[n]));
  std::vector<int> fill(adjacency.offsets.begin(), adjacency.offsets.end() - 1);
  for (int h = 0; h < 2; ++h)
    add_edges(
        halves[at(h)], [&](int i) { return split.half[at(i)] == h; }, adjacency, &fill);
  return true;
}

/// Sorts every site's list, on all cores.
void sort_lists(Adjacency& adjacency) {
  const auto count = static_cast<std::ptrdiff_t>(adjacency.offsets.size()) - 1;
#pragma omp parallel for schedule(static, 4096)
  for (std::ptrdiff_t i = 0; i < count; ++i)
    std::sort(adjacency.neighbors.begin() + adjacency.offsets[static_cast<std::size_t>(i)],
              adjacency.neighbors.begin() + adjacency.offsets[static_cast<std::size_t>(i) + 1]);
}

/// Each triangle rotated to start at its smallest vertex, then all in the order of those vertices
/// and of their second: the same list whatever the order CGAL stored its faces in (memory
/// addresses), so that the flips from it, and the cells, are the same at every run. Linear: a
/// counting sort by the first vertex, then each vertex's few triangles by their second.
void canonical_order(std::vector<std::array<int, 3>>& triangles, std::size_t count) {
  std::vector<int> start(count + 1, 0);
  for (auto& t : triangles) {
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    ++start[at(t[0]) + 1];
  }
  for (std::size_t i = 0; i < count; ++i) start[i + 1] += start[i];
  std::vector<std::array<int, 3>> sorted(triangles.size());
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (const auto& t : triangles) sorted[at(fill[at(t[0])]++)] = t;
  for (std::size_t i = 0; i < count; ++i) std::sort(sorted.begin() + start[i], sorted.begin() + start[i + 1]);
  triangles = std::move(sorted);
}

/// The twin of every half-edge of `surface` (its vertices are below `count`): each vertex's
/// outgoing half-edges are listed, and the twin of a→b is found among b's.
void find_twins(SiteTriangulation& surface, std::size_t count) {
  const auto& triangles = surface.triangles;
  const std::size_t m = triangles.size();
  std::vector<int> first(count + 1, 0), outgoing(3 * m);
  for (const auto& t : triangles)
    for (int v : t) ++first[at(v) + 1];
  for (std::size_t i = 0; i < count; ++i) first[i + 1] += first[i];
  std::vector<int> fill(first.begin(), first.end() - 1);
  for (std::size_t k = 0; k < m; ++k)
    for (int e = 0; e < 3; ++e) outgoing[at(fill[at(triangles[k][at((e + 1) % 3)])]++)] = static_cast<int>(3 * k) + e;
  surface.twins.assign(3 * m, -1);
  const auto triangle_count = static_cast<std::ptrdiff_t>(m);
#pragma omp parallel for schedule(static, 4096)
  for (std::ptrdiff_t k = 0; k < triangle_count; ++k)
    for (int e = 0; e < 3; ++e) {
      const auto& t = triangles[at(static_cast<int>(k))];
      const int a = t[at((e + 1) % 3)], b = t[at((e + 2) % 3)];
      for (int i = first[at(b)]; i < first[at(b) + 1]; ++i) {
        const int h = outgoing[at(i)];
        if (triangles[at(h / 3)][at((h % 3 + 2) % 3)] == a) {
          surface.twins[at(static_cast<int>(3 * k) + e)] = h;
          break;
        }
      }
    }
}

}  // namespace

std::uint64_t centers_fingerprint(std::span<const Vec2> centers) {
  std::uint64_t hash = 0xcbf29ce484222325u ^ centers.size();
  for (const Vec2& c : centers)
    for (int d = 0; d < 2; ++d) {
      std::uint64_t bits;
      std::memcpy(&bits, &c[d], sizeof bits);
      hash = (hash ^ bits) * 0x100000001b3u;
      hash ^= hash >> 29;
    }
  return hash;
}

std::optional<RegularTriangulation> regular_triangulation_by_flips(std::span<const Vec2> centers,
                                                                   std::span<const double> power_weights,
                                                                   SiteTriangulation& surface, std::size_t max_flips) {
  const std::size_t n = centers.size(), m = surface.triangles.size();
  auto& triangles = surface.triangles;
  for (const auto& t : triangles)
    for (int v : t)
      if (v < 0 || at(v) >= n) return std::nullopt;
  if (surface.twins.size() != 3 * m) find_twins(surface, n);
  auto& twin = surface.twins;
  auto point = [&](int v) { return Kernel::Point_2(centers[at(v)].x(), centers[at(v)].y()); };
  auto weighted = [&](int v) { return Kernel::Weighted_point_2(point(v), power_weights[at(v)]); };
  const auto orientation = Kernel().orientation_2_object();
  const FilteredPowerTest power_test;
  // Half-edge h = 3k + e runs from vertex e + 1 to e + 2 of triangle k: it is not regular when the
  // far vertex of its twin's triangle is in conflict with triangle k.
  auto in_conflict = [&](int h) {
    const int t = twin[at(h)];
    if (t < 0) return false;
    const auto& first = triangles[at(h / 3)];
    const int e = h % 3;
    return power_test(weighted(first[at((e + 1) % 3)]), weighted(first[at((e + 2) % 3)]), weighted(first[at(e)]),
                      weighted(triangles[at(t / 3)][at(t % 3)])) == CGAL::ON_POSITIVE_SIDE;
  };
  // Every edge once, in parallel; in blocks joined in order, so that the list (and the flips, in
  // degenerate cases) does not depend on the number of threads.
  constexpr std::ptrdiff_t block_size = 8192;
  const auto half_edges = static_cast<std::ptrdiff_t>(3 * m);
  std::vector<std::vector<int>> block_conflicts(static_cast<std::size_t>((half_edges + block_size - 1) / block_size));
#pragma omp parallel for schedule(static, 1)
  for (std::ptrdiff_t block = 0; block < static_cast<std::ptrdiff_t>(block_conflicts.size()); ++block)
    for (std::ptrdiff_t h = block * block_size; h < std::min(half_edges, (block + 1) * block_size); ++h)
      if (twin[at(static_cast<int>(h))] > h && in_conflict(static_cast<int>(h)))
        block_conflicts[at(static_cast<int>(block))].push_back(static_cast<int>(h));
  std::vector<int> stack, stuck;
  for (auto it = block_conflicts.rbegin(); it != block_conflicts.rend(); ++it)
    stack.insert(stack.end(), it->rbegin(), it->rend());
  std::size_t flips = 0;
  while (!stack.empty()) {
    const int h = stack.back();
    stack.pop_back();
    if (!in_conflict(h)) continue;
    const int t = twin[at(h)];
    const int k = h / 3, e = h % 3, k2 = t / 3, e2 = t % 3;
    auto& first = triangles[at(k)];
    auto& second = triangles[at(k2)];
    const int c = first[at(e)], a = first[at((e + 1) % 3)], b = first[at((e + 2) % 3)], d = second[at(e2)];
    // The new diagonal c–d: triangles (c, a, d) and (d, b, c), both counter-clockwise, or no flip
    // (yet: a flip next to it changes the quadrilateral and tests this edge again).
    if (orientation(point(c), point(a), point(d)) != CGAL::LEFT_TURN ||
        orientation(point(d), point(b), point(c)) != CGAL::LEFT_TURN) {
      stuck.push_back(h);
      continue;
    }
    if (++flips > max_flips) return std::nullopt;
    // The outer edges: b→c and c→a of the first triangle, a→d and d→b of the second.
    const int bc = twin[at(3 * k + (e + 1) % 3)], ca = twin[at(3 * k + (e + 2) % 3)];
    const int ad = twin[at(3 * k2 + (e2 + 1) % 3)], db = twin[at(3 * k2 + (e2 + 2) % 3)];
    first = {c, a, d};   // opposite c: a→d; opposite a: d→c; opposite d: c→a
    second = {d, b, c};  // opposite d: b→c; opposite b: c→d; opposite c: d→b
    auto link = [&](int half_edge, int other) {
      twin[at(half_edge)] = other;
      if (other >= 0) twin[at(other)] = half_edge;
    };
    link(3 * k + 0, ad), link(3 * k + 2, ca), link(3 * k2 + 0, bc), link(3 * k2 + 2, db);
    link(3 * k + 1, 3 * k2 + 1);
    for (int outer : {3 * k + 0, 3 * k + 2, 3 * k2 + 0, 3 * k2 + 2}) stack.push_back(outer);
  }
  // Every edge was tested after its last change: only those left stuck can still be in conflict.
  for (int h : stuck)
    if (in_conflict(h)) return std::nullopt;
  RegularTriangulation result;
  result.is_vertex.assign(n, 0);
  Adjacency& adjacency = result.neighbors;
  adjacency.offsets.assign(n + 1, 0);
  // a's neighbours: the ends of its outgoing half-edges, and the starts of the hull edges into it.
  for (std::size_t h = 0; h < 3 * m; ++h) {
    const auto& t = triangles[h / 3];
    ++adjacency.offsets[at(t[(h + 1) % 3]) + 1];
    if (twin[h] < 0) ++adjacency.offsets[at(t[(h + 2) % 3]) + 1];
  }
  for (std::size_t i = 0; i < n; ++i) adjacency.offsets[i + 1] += adjacency.offsets[i];
  adjacency.neighbors.resize(at(adjacency.offsets[n]));
  std::vector<int> fill(adjacency.offsets.begin(), adjacency.offsets.end() - 1);
  for (std::size_t h = 0; h < 3 * m; ++h) {
    const auto& t = triangles[h / 3];
    const int a = t[(h + 1) % 3], b = t[(h + 2) % 3];
    adjacency.neighbors[at(fill[at(a)]++)] = b;
    if (twin[h] < 0) adjacency.neighbors[at(fill[at(b)]++)] = a;
    result.is_vertex[at(a)] = 1;
  }
  if (std::find(result.is_vertex.begin(), result.is_vertex.end(), 0) != result.is_vertex.end()) return std::nullopt;
  sort_lists(adjacency);
  result.order.resize(n);
  std::iota(result.order.begin(), result.order.end(), 0);
  return result;
}

RegularTriangulation regular_triangulation(std::span<const Vec2> centers, std::span<const double> power_weights,
                                           bool stop_at_hidden, bool with_triangles) {
  const std::size_t n = centers.size();
  RegularTriangulation result;
  // Large sets are triangulated as two halves at once (both cores), certified exact; the split
  // does not depend on the number of threads, so neither do the cells.
  Split split;
  bool done = false;
  if (n >= parallel_size && make_split(centers, power_weights, split)) {
    done = split_triangulation(centers, power_weights, stop_at_hidden, with_triangles, split, result);
    if (!done) result = RegularTriangulation{};
  }
  if (!done) result = whole_triangulation(centers, power_weights, stop_at_hidden, with_triangles);
  if (result.stopped_at_hidden) return result;
  if (with_triangles) canonical_order(result.triangles, n);
  // CGAL stores the faces in an order that depends on memory addresses (its internal sets are
  // keyed by handles), so the edges come in a different order from run to run. Sorted lists make
  // the clipping order, and so the cells to the last bit, the same at every run.
  sort_lists(result.neighbors);
  return result;
}

}  // namespace sdot::detail
