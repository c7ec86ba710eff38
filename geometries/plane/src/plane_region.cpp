// PlaneRegion: validation and union of polygons with holes, and their convex decomposition.
#include "boost_geometry.hpp"  // first: it configures Boost.Geometry

#include "sdot/geometries/plane_region.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <set>
#include <sstream>
#include <tuple>

#include "sdot/error.hpp"

namespace sdot {
namespace {

using namespace plane_geometry;
using Vec2 = Eigen::Vector2d;

// ---------------------------------------------------------------------------------------------
// Exact orientation predicate: the sign of (b − a) × (c − a), computed exactly when the
// floating-point value is too small to be trusted (sum of exact products, Shewchuk's expansions).

void two_sum(double a, double b, double& sum, double& error) {
  sum = a + b;
  const double bv = sum - a;
  error = (a - (sum - bv)) + (b - bv);
}

int exact_orientation(const Vec2& a, const Vec2& b, const Vec2& c) {
  // (bx − ax)(cy − ay) − (by − ay)(cx − ax) = bx cy − bx ay − ax cy − by cx + by ax + ay cx.
  const double factors[6][2] = {{b.x(), c.y()},  {-b.x(), a.y()}, {-a.x(), c.y()},
                                {-b.y(), c.x()}, {b.y(), a.x()},  {a.y(), c.x()}};
  double expansion[12];
  int size = 0;
  auto grow = [&](double term) {
    for (int i = 0; i < size; ++i) {
      double sum, error;
      two_sum(term, expansion[i], sum, error);
      expansion[i] = error;
      term = sum;
    }
    expansion[size++] = term;
  };
  for (const auto& f : factors) {
    const double product = f[0] * f[1];
    grow(std::fma(f[0], f[1], -product));
    grow(product);
  }
  for (int i = size - 1; i >= 0; --i)
    if (expansion[i] != 0) return expansion[i] > 0 ? 1 : -1;
  return 0;
}

/// +1 when c is to the left of the line a → b, −1 to the right, 0 on it (exact).
int orientation(const Vec2& a, const Vec2& b, const Vec2& c) {
  const double left = (b.x() - a.x()) * (c.y() - a.y());
  const double right = (b.y() - a.y()) * (c.x() - a.x());
  const double det = left - right;
  const double bound = 3.3306690738754716e-16 * (std::abs(left) + std::abs(right));
  if (det > bound) return 1;
  if (-det > bound) return -1;
  return exact_orientation(a, b, c);
}

double signed_area(const std::vector<Vec2>& ring) {
  double twice = 0;
  for (std::size_t i = 0, n = ring.size(); i < n; ++i) {
    const Vec2& p = ring[i];
    const Vec2& q = ring[(i + 1) % n];
    twice += p.x() * q.y() - p.y() * q.x();
  }
  return twice / 2;
}

std::string format_point(const Vec2& p) {
  std::ostringstream out;
  out.precision(17);
  out << "(" << p.x() << ", " << p.y() << ")";
  return out.str();
}

// ---------------------------------------------------------------------------------------------
// Validation

/// A ring without consecutive duplicates, with the input index of each kept vertex.
struct CleanRing {
  std::vector<Vec2> points;
  std::vector<std::size_t> original;
};

/// Whether closed segments [p, q] and [r, s] share a point.
bool segments_meet(const Vec2& p, const Vec2& q, const Vec2& r, const Vec2& s) {
  const int o1 = orientation(p, q, r), o2 = orientation(p, q, s);
  const int o3 = orientation(r, s, p), o4 = orientation(r, s, q);
  if (o1 * o2 < 0 && o3 * o4 < 0) return true;
  auto on_segment = [](const Vec2& a, const Vec2& b, const Vec2& c) {  // c collinear with a, b
    return std::min(a.x(), b.x()) <= c.x() && c.x() <= std::max(a.x(), b.x()) && std::min(a.y(), b.y()) <= c.y() &&
           c.y() <= std::max(a.y(), b.y());
  };
  return (o1 == 0 && on_segment(p, q, r)) || (o2 == 0 && on_segment(p, q, s)) || (o3 == 0 && on_segment(r, s, p)) ||
         (o4 == 0 && on_segment(r, s, q));
}

/// A point shared by two segments known to meet (for the message).
Vec2 meeting_point(const Vec2& p, const Vec2& q, const Vec2& r, const Vec2& s) {
  const Vec2 d = q - p, e = s - r;
  const double den = d.x() * e.y() - d.y() * e.x();
  if (den != 0) {
    const double t = ((r - p).x() * e.y() - (r - p).y() * e.x()) / den;
    return p + std::clamp(t, 0.0, 1.0) * d;
  }
  for (const Vec2* c : {&r, &s, &p, &q})  // collinear: an endpoint inside the other segment
    if (segments_meet(*c, *c, p, q) && segments_meet(*c, *c, r, s)) return *c;
  return r;
}

/// Describes the first pair of edges of `ring` that meet improperly, or "" when there is none.
/// O(n²): only called once Boost.Geometry has found the ring invalid.
std::string find_self_intersection(const CleanRing& ring) {
  const auto& v = ring.points;
  const std::size_t n = v.size();
  auto edge_name = [&](std::size_t i) {
    return "edge " + std::to_string(ring.original[i]) + " (vertex " + std::to_string(ring.original[i]) + " to " +
           std::to_string(ring.original[(i + 1) % n]) + ")";
  };
  for (std::size_t i = 0; i < n; ++i) {  // adjacent edges folding back onto each other
    const Vec2& a = v[i];
    const Vec2& b = v[(i + 1) % n];
    const Vec2& c = v[(i + 2) % n];
    if (orientation(a, b, c) == 0 && (b - a).dot(c - b) < 0)
      return "self-intersects: " + edge_name(i) + " and " + edge_name((i + 1) % n) + " overlap (a spike at vertex " +
             std::to_string(ring.original[(i + 1) % n]) + ")";
  }
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 2; j < n; ++j) {
      if (i == 0 && j == n - 1) continue;  // adjacent through the closing edge
      const Vec2 &p = v[i], &q = v[(i + 1) % n], &r = v[j], &s = v[(j + 1) % n];
      if (segments_meet(p, q, r, s))
        return "self-intersects: " + edge_name(i) + " and " + edge_name(j) + " meet at " +
               format_point(meeting_point(p, q, r, s));
    }
  }
  return {};
}

BRing to_boost_ring(const std::vector<Vec2>& points) {
  BRing ring;
  ring.reserve(points.size());
  for (const Vec2& p : points) ring.emplace_back(p.x(), p.y());
  return ring;
}

std::vector<Vec2> from_boost_ring(const BRing& ring) {
  std::vector<Vec2> points;
  points.reserve(ring.size());
  for (const BPoint& p : ring) points.emplace_back(p.x(), p.y());
  // Boost may close rings even of an open type after some operations: drop a repeated first point.
  while (points.size() > 1 && points.front() == points.back()) points.pop_back();
  return points;
}

/// Checks one ring on its own; returns it counter-clockwise (`counter_clockwise`) or clockwise.
BRing validate_ring(const std::vector<Vec2>& input, const std::string& field, bool counter_clockwise) {
  for (std::size_t k = 0; k < input.size(); ++k)
    if (!input[k].allFinite()) throw InputError(indexed(field, k), "vertex is not finite");
  CleanRing ring;
  for (std::size_t k = 0; k < input.size(); ++k) {
    if (!ring.points.empty() && ring.points.back() == input[k]) continue;
    ring.points.push_back(input[k]);
    ring.original.push_back(k);
  }
  while (ring.points.size() > 1 && ring.points.back() == ring.points.front()) {
    ring.points.pop_back();
    ring.original.pop_back();
  }
  if (ring.points.size() < 3)
    throw InputError(field, "has fewer than 3 distinct vertices (" + std::to_string(ring.points.size()) + ")");
  bool collinear = true;
  for (std::size_t k = 2; k < ring.points.size() && collinear; ++k)
    collinear = orientation(ring.points[0], ring.points[1], ring.points[k]) == 0;
  if (collinear) throw InputError(field, "has zero area (all its vertices are collinear)");

  BRing boost_ring = to_boost_ring(ring.points);
  if (signed_area(ring.points) < 0) std::reverse(boost_ring.begin(), boost_ring.end());
  std::string reason;
  if (!bg::is_valid(boost_ring, reason)) {
    const std::string where = find_self_intersection(ring);
    throw InputError(field, where.empty() ? "is not a valid ring: " + reason : where);
  }
  if (bg::area(boost_ring) <= 0) throw InputError(field, "has zero area");
  if (!counter_clockwise) std::reverse(boost_ring.begin(), boost_ring.end());
  return boost_ring;
}

BPolygon validate_polygon(const PolygonWithHoles& input, const std::string& field) {
  BPolygon polygon;
  polygon.outer() = validate_ring(input.outer, field + ".outer", true);
  for (std::size_t h = 0; h < input.holes.size(); ++h)
    polygon.inners().push_back(validate_ring(input.holes[h], indexed(field + ".holes", h), false));
  if (polygon.inners().empty()) return polygon;
  bg::validity_failure_type failure = bg::no_failure;
  if (bg::is_valid(polygon, failure)) return polygon;

  // Name the culprit: a hole not inside the outer ring, or two holes whose interiors meet.
  BPolygon outer;
  outer.outer() = polygon.outer();
  for (std::size_t h = 0; h < polygon.inners().size(); ++h) {
    BPolygon hole;
    hole.outer() = polygon.inners()[h];
    std::reverse(hole.outer().begin(), hole.outer().end());
    if (!bg::covered_by(hole, outer))
      throw InputError(indexed(field + ".holes", h), "is not inside the outer ring (" + field + ".outer)");
  }
  for (std::size_t h = 0; h < polygon.inners().size(); ++h) {
    BPolygon hole_h;
    hole_h.outer() = polygon.inners()[h];
    std::reverse(hole_h.outer().begin(), hole_h.outer().end());
    for (std::size_t g = 0; g < h; ++g) {
      BPolygon hole_g;
      hole_g.outer() = polygon.inners()[g];
      std::reverse(hole_g.outer().begin(), hole_g.outer().end());
      if (bg::relate(hole_h, hole_g, bg::de9im::mask("T********")))
        throw InputError(indexed(field + ".holes", h), "overlaps " + indexed(field + ".holes", g));
    }
  }
  std::string reason;
  bg::is_valid(polygon, reason);
  throw InputError(field, "is not a valid polygon with holes: " + reason);
}

/// The union of `polygons`, merged in the given order or the reverse one.
BMulti union_all(const std::vector<BPolygon>& polygons, bool reversed) {
  BMulti region;
  for (std::size_t k = 0; k < polygons.size(); ++k) {
    const BPolygon& polygon = polygons[reversed ? polygons.size() - 1 - k : k];
    BMulti merged;
    bg::union_(region, polygon, merged);
    region = std::move(merged);
  }
  return region;
}

/// Exact equality (bg::equals compares with a tolerance).
bool same(const BPoint& a, const BPoint& b) {
  return a.x() == b.x() && a.y() == b.y();
}

/// Makes near-contacts exact, as the decomposition's exact predicates need: vertices closer than
/// a tolerance (1e-12 max(|coordinate|, 1)) become one, and a vertex that close to the inside of
/// an edge (of any ring) is inserted into that edge. Rounded intersection points of a union can
/// otherwise leave a vertex an ulp off the vertex or edge it touches, on the wrong side. Returns
/// whether anything changed.
bool snap(BMulti& region) {
  std::vector<BRing*> rings;
  for (BPolygon& polygon : region) {
    rings.push_back(&polygon.outer());
    for (BRing& hole : polygon.inners()) rings.push_back(&hole);
  }
  double scale = 1;
  std::vector<BPoint*> points;
  for (BRing* ring : rings)
    for (BPoint& p : *ring) {
      points.push_back(&p);
      scale = std::max({scale, std::abs(p.x()), std::abs(p.y())});
    }
  const double tolerance = 1e-12 * scale;
  bool changed = false;
  std::sort(points.begin(), points.end(), [](const BPoint* a, const BPoint* b) { return a->x() < b->x(); });
  for (std::size_t i = 0; i < points.size(); ++i)
    for (std::size_t j = i + 1; j < points.size() && points[j]->x() - points[i]->x() <= tolerance; ++j)
      if (std::abs(points[j]->y() - points[i]->y()) <= tolerance && !same(*points[j], *points[i])) {
        *points[j] = *points[i];
        changed = true;
      }
  auto clean = [](BRing& ring) {
    BRing kept;
    for (const BPoint& p : ring)
      if (kept.empty() || !same(kept.back(), p)) kept.push_back(p);
    while (kept.size() > 1 && same(kept.back(), kept.front())) kept.pop_back();
    ring = std::move(kept);
  };
  for (BRing* ring : rings) clean(*ring);

  // Vertices near the inside of edges: an R-tree of the edges' boxes, grown by the tolerance.
  using Box = bg::model::box<BPoint>;
  using Entry = std::pair<Box, std::pair<std::size_t, std::size_t>>;  // (ring, edge index)
  std::vector<Entry> boxes;
  for (std::size_t r = 0; r < rings.size(); ++r) {
    const BRing& ring = *rings[r];
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const BPoint& a = ring[i];
      const BPoint& b = ring[(i + 1) % ring.size()];
      boxes.push_back({Box(BPoint(std::min(a.x(), b.x()) - tolerance, std::min(a.y(), b.y()) - tolerance),
                           BPoint(std::max(a.x(), b.x()) + tolerance, std::max(a.y(), b.y()) + tolerance)),
                       {r, i}});
    }
  }
  const bg::index::rtree<Entry, bg::index::quadratic<16>> tree(boxes.begin(), boxes.end());
  struct Insertion {
    std::size_t ring, edge;
    double t;
    BPoint point;
  };
  std::vector<Insertion> insertions;
  std::vector<Entry> found;
  for (BRing* ring_pointer : rings) {
    for (const BPoint& v : *ring_pointer) {
      found.clear();
      tree.query(bg::index::intersects(v), std::back_inserter(found));
      for (const Entry& entry : found) {
        const BRing& ring = *rings[entry.second.first];
        const std::size_t i = entry.second.second;
        const Vec2 a(ring[i].x(), ring[i].y());
        const Vec2 b(ring[(i + 1) % ring.size()].x(), ring[(i + 1) % ring.size()].y());
        const Vec2 p(v.x(), v.y());
        if (p == a || p == b) continue;
        const double t = (p - a).dot(b - a) / (b - a).squaredNorm();
        if (t <= 0 || t >= 1 || (a + t * (b - a) - p).norm() > tolerance) continue;
        insertions.push_back({entry.second.first, i, t, v});
      }
    }
  }
  if (insertions.empty()) return changed;
  std::sort(insertions.begin(), insertions.end(), [](const Insertion& x, const Insertion& y) {
    return std::tie(x.ring, x.edge, x.t) < std::tie(y.ring, y.edge, y.t);
  });
  for (std::size_t k = 0; k < insertions.size();) {
    const std::size_t r = insertions[k].ring;
    const BRing old = *rings[r];
    BRing& ring = *rings[r];
    ring.clear();
    for (std::size_t i = 0; i < old.size(); ++i) {
      ring.push_back(old[i]);
      for (; k < insertions.size() && insertions[k].ring == r && insertions[k].edge == i; ++k)
        ring.push_back(insertions[k].point);
    }
    clean(ring);
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Trapezoidal decomposition by a sweep from left to right.

struct Edge {
  Vec2 left, right;  // left.x() < right.x()
  bool lower;        // the region lies above the edge (it is the lower side of a trapezoid)
  [[nodiscard]] double y(double x) const {
    if (x == left.x()) return left.y();
    if (x == right.x()) return right.y();
    return left.y() + (right.y() - left.y()) * ((x - left.x()) / (right.x() - left.x()));
  }
};

/// Orders edges that both cross an open vertical slab (and do not cross each other) from bottom
/// to top: the sign of y_e − y_f at the left end of their common x-range, or at its right end
/// when they meet at the left end.
struct Below {
  const std::vector<Edge>* edges;
  bool operator()(int i, int j) const {
    if (i == j) return false;
    const Edge& e = (*edges)[i];
    const Edge& f = (*edges)[j];
    int sign = e.left.x() >= f.left.x() ? orientation(f.left, f.right, e.left) : -orientation(e.left, e.right, f.left);
    if (sign == 0)
      sign =
          e.right.x() <= f.right.x() ? orientation(f.left, f.right, e.right) : -orientation(e.left, e.right, f.right);
    if (sign == 0) return i < j;  // overlapping collinear edges: cannot happen in a valid region
    return sign < 0;
  }
};

/// Appends `points` (a convex polygon, counter-clockwise up to rounding) cleaned: without
/// vertices closer than `tolerance` to the previous one, nor vertices where the boundary does not
/// turn left by more than rounding (|sin| ≤ 1e-14); nothing when fewer than 3 vertices remain.
void emit_piece(const std::vector<Vec2>& points, double tolerance, std::vector<std::vector<Vec2>>& out) {
  std::vector<Vec2> piece;
  for (const Vec2& p : points)
    if (piece.empty() || (piece.back() - p).norm() > tolerance) piece.push_back(p);
  while (piece.size() > 1 && (piece.back() - piece.front()).norm() <= tolerance) piece.pop_back();
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t i = 0; piece.size() >= 3 && i < piece.size();) {
      const std::size_t n = piece.size();
      const Vec2 in = piece[i] - piece[(i + n - 1) % n], next = piece[(i + 1) % n] - piece[i];
      if (in.x() * next.y() - in.y() * next.x() <= 1e-14 * in.norm() * next.norm()) {
        piece.erase(piece.begin() + static_cast<std::ptrdiff_t>(i));
        changed = true;
      } else {
        ++i;
      }
    }
  }
  if (piece.size() >= 3) out.push_back(std::move(piece));
}

/// The sweep. The status holds the edges crossing the current slab, bottom to top; the region
/// between a lower edge and the next edge above it is an open piece. A piece closes at a vertex
/// x when one of its two edges ends or an edge starts between them, unless it can go on as a
/// convex piece: the ended edge is continued by the next edge of the same chain, turning the
/// convex way, and nothing else starts between. A piece is thus x-monotone: a lower chain and
/// an upper chain, each convex, between two vertical sides (possibly points).
std::vector<std::vector<Vec2>> convex_decomposition(const std::vector<PolygonWithHoles>& polygons) {
  std::vector<Edge> edges;
  double scale = 1;  // as ConvexPolygon: vertices closer than ~1e-14 max(|coordinate|, 1) are one
  for (const auto& polygon : polygons)
    for (const Vec2& p : polygon.outer) scale = std::max(scale, p.cwiseAbs().maxCoeff());
  const double tolerance = 4e-14 * scale;
  auto add_ring = [&](const std::vector<Vec2>& ring) {
    for (std::size_t i = 0, n = ring.size(); i < n; ++i) {
      const Vec2& p = ring[i];
      const Vec2& q = ring[(i + 1) % n];
      if (p.x() == q.x()) continue;  // vertical edges lie on slab boundaries
      // The region is to the left of each directed edge (outer rings ccw, holes cw).
      if (p.x() < q.x())
        edges.push_back({p, q, true});
      else
        edges.push_back({q, p, false});
    }
  };
  for (const auto& polygon : polygons) {
    add_ring(polygon.outer);
    for (const auto& hole : polygon.holes) add_ring(hole);
  }
  const std::size_t m = edges.size();
  auto edge = [&](int i) -> const Edge& { return edges[static_cast<std::size_t>(i)]; };
  std::vector<int> by_left(m), by_right(m);
  for (std::size_t i = 0; i < m; ++i) by_left[i] = by_right[i] = static_cast<int>(i);
  std::sort(by_left.begin(), by_left.end(), [&](int i, int j) {
    return edge(i).left.x() < edge(j).left.x() ||
           (edge(i).left.x() == edge(j).left.x() && edge(i).left.y() < edge(j).left.y());
  });
  std::sort(by_right.begin(), by_right.end(), [&](int i, int j) { return edge(i).right.x() < edge(j).right.x(); });

  using Status = std::set<int, Below>;
  Status status(Below{&edges});
  std::vector<Status::iterator> where(m, status.end());
  std::vector<char> active(m, 0), fresh(m, 0);
  struct Piece {
    bool open = false;
    int upper = -1;           // the current upper edge (the record is stored at the lower one)
    std::vector<Vec2> lower;  // the lower chain so far, left to right
    std::vector<Vec2> upper_chain;
  };
  std::vector<Piece> open(m);
  std::vector<std::vector<Vec2>> pieces;
  std::vector<int> affected;

  auto above = [&](int e) {
    const auto it = std::next(where[static_cast<std::size_t>(e)]);
    return it == status.end() ? -1 : *it;
  };
  auto below = [&](int e) {
    const auto it = where[static_cast<std::size_t>(e)];
    return it == status.begin() ? -1 : *std::prev(it);
  };
  auto is_fresh = [&](int e) { return e >= 0 && fresh[static_cast<std::size_t>(e)]; };

  std::size_t next_left = 0, next_right = 0;
  while (next_left < m || next_right < m) {
    double x = std::numeric_limits<double>::infinity();
    if (next_left < m) x = edge(by_left[next_left]).left.x();
    if (next_right < m) x = std::min(x, edge(by_right[next_right]).right.x());
    affected.clear();
    // Edges ending at x: the pieces they bound are affected.
    const std::size_t first_right = next_right;
    for (; next_right < m && edge(by_right[next_right]).right.x() == x; ++next_right) {
      const int e = by_right[next_right];
      if (edge(e).lower) {
        affected.push_back(e);
      } else if (const int b = below(e); b >= 0 && edge(b).lower) {
        affected.push_back(b);
      }
    }
    for (std::size_t k = first_right; k < next_right; ++k) {
      const auto e = static_cast<std::size_t>(by_right[k]);
      status.erase(where[e]);
      active[e] = 0;
    }
    // Edges starting at x: a piece they land in is affected.
    const std::size_t first_left = next_left;
    for (; next_left < m && edge(by_left[next_left]).left.x() == x; ++next_left) {
      const auto e = static_cast<std::size_t>(by_left[next_left]);
      where[e] = status.insert(static_cast<int>(e)).first;
      active[e] = fresh[e] = 1;
    }
    for (std::size_t k = first_left; k < next_left; ++k) {
      const int b = below(by_left[k]);
      if (b >= 0 && !is_fresh(b) && edge(b).lower) affected.push_back(b);
    }
    std::sort(affected.begin(), affected.end());
    affected.erase(std::unique(affected.begin(), affected.end()), affected.end());
    // Fresh lower edges starting at a vertex (the ones of this event, sorted by left.y).
    auto fresh_lower_at = [&](const Vec2& v) {
      std::vector<int> found;
      auto it = std::lower_bound(by_left.begin() + static_cast<std::ptrdiff_t>(first_left),
                                 by_left.begin() + static_cast<std::ptrdiff_t>(next_left), v.y(),
                                 [&](int e, double y) { return edge(e).left.y() < y; });
      for (; it != by_left.begin() + static_cast<std::ptrdiff_t>(next_left) && edge(*it).left == v; ++it)
        if (edge(*it).lower) found.push_back(*it);
      return found;
    };

    // Each affected piece goes on (convex continuation) or closes.
    for (const int a : affected) {
      Piece& piece = open[static_cast<std::size_t>(a)];
      if (!piece.open) continue;
      const int b = piece.upper;
      const bool a_goes_on = active[static_cast<std::size_t>(a)], b_goes_on = active[static_cast<std::size_t>(b)];
      int next_a = -1, next_b = -1;
      auto continues_b = [&](int na) {  // the upper edge above `na`, when it continues b
        const int nb = above(na);
        if (b_goes_on) return nb == b ? b : -1;
        return nb >= 0 && is_fresh(nb) && !edge(nb).lower && edge(nb).left == edge(b).right &&
                       orientation(edge(b).left, edge(b).right, edge(nb).right) <= 0
                   ? nb
                   : -1;
      };
      if (a_goes_on) {
        next_a = a;
        next_b = continues_b(a);
      } else {
        for (const int na : fresh_lower_at(edge(a).right)) {
          if (orientation(edge(a).left, edge(a).right, edge(na).right) < 0) continue;  // reflex
          if ((next_b = continues_b(na)) >= 0) {
            next_a = na;
            break;
          }
        }
      }
      if (next_a >= 0 && next_b >= 0) {
        if (next_a != a) piece.lower.push_back(edge(a).right);
        if (next_b != b) piece.upper_chain.push_back(edge(b).right);
        piece.upper = next_b;
        if (next_a != a) {
          open[static_cast<std::size_t>(next_a)] = std::move(piece);
          piece = Piece{};
        }
        continue;
      }
      std::vector<Vec2> polygon = std::move(piece.lower);
      polygon.emplace_back(x, edge(a).y(x));
      polygon.emplace_back(x, edge(b).y(x));
      polygon.insert(polygon.end(), piece.upper_chain.rbegin(), piece.upper_chain.rend());
      emit_piece(polygon, tolerance, pieces);
      piece = Piece{};
    }
    // Open a piece above every active lower edge that has none.
    auto open_above = [&](int a) {
      Piece& piece = open[static_cast<std::size_t>(a)];
      if (!active[static_cast<std::size_t>(a)] || !edge(a).lower || piece.open) return;
      const int b = above(a);
      if (b < 0) return;  // cannot happen in a valid region
      piece.open = true;
      piece.upper = b;
      piece.lower = {Vec2(x, edge(a).y(x))};
      piece.upper_chain = {Vec2(x, edge(b).y(x))};
    };
    for (const int a : affected) open_above(a);
    for (std::size_t k = first_left; k < next_left; ++k) open_above(by_left[k]);
    for (std::size_t k = first_left; k < next_left; ++k) fresh[static_cast<std::size_t>(by_left[k])] = 0;
  }
  return pieces;
}

}  // namespace

PlaneRegion::PlaneRegion(std::vector<PolygonWithHoles> polygons, const std::string& field) {
  if (polygons.empty()) throw InputError(field + ".polygons", "is empty (a region needs at least one polygon)");
  std::vector<BPolygon> validated;
  double largest = 0, sum = 0;  // bounds on the union's area, to check Boost's result
  for (std::size_t i = 0; i < polygons.size(); ++i) {
    validated.push_back(validate_polygon(polygons[i], indexed(field + ".polygons", i)));
    const double polygon_area = bg::area(validated.back());
    largest = std::max(largest, polygon_area);
    sum += polygon_area;
  }
  BMulti region;
  if (validated.size() == 1) {
    region.push_back(std::move(validated[0]));
    if (!region[0].inners().empty()) {  // a hole vertex an ulp off the outer ring: make the contact exact
      BMulti snapped = region;
      if (snap(snapped) && bg::is_valid(snapped)) region = std::move(snapped);
    }
  } else {
    // Rounded intersection points can leave Boost's union slightly invalid (a vertex an ulp away
    // from the vertex it should be): snapping, and failing that the other order, repairs that.
    std::string problem;
    for (const bool reversed : {false, true}) {
      region = union_all(validated, reversed);
      snap(region);
      const double union_area = bg::area(region);
      std::string reason;
      if (!bg::is_valid(region, reason))
        problem = "Boost.Geometry's result is invalid: " + reason;
      else if (!(union_area >= largest * (1 - 1e-9) && union_area <= sum * (1 + 1e-9)))
        problem = "Boost.Geometry's result has area " + std::to_string(union_area) + ", not between " +
                  std::to_string(largest) + " and " + std::to_string(sum);
      else
        problem.clear();
      if (problem.empty()) break;
    }
    if (!problem.empty())
      throw InputError(field, "the union of the polygons failed (" + problem +
                                  "): the polygons are too nearly degenerate; move them apart or make them overlap "
                                  "clearly");
  }

  Vec2 moment = Vec2::Zero();
  lower_ = Vec2::Constant(std::numeric_limits<double>::infinity());
  upper_ = -lower_;
  area_ = 0;
  auto add_ring = [&](const std::vector<Vec2>& ring) {
    for (std::size_t i = 0, n = ring.size(); i < n; ++i) {
      const Vec2& p = ring[i];
      const Vec2& q = ring[(i + 1) % n];
      const double cross = p.x() * q.y() - p.y() * q.x();
      area_ += cross / 2;
      moment += cross * (p + q) / 6;
      lower_ = lower_.cwiseMin(p);
      upper_ = upper_.cwiseMax(p);
    }
  };
  for (const BPolygon& polygon : region) {
    PolygonWithHoles normalised;
    normalised.outer = from_boost_ring(polygon.outer());
    if (signed_area(normalised.outer) < 0) std::reverse(normalised.outer.begin(), normalised.outer.end());
    add_ring(normalised.outer);
    for (const BRing& hole : polygon.inners()) {
      normalised.holes.push_back(from_boost_ring(hole));
      auto& ring = normalised.holes.back();
      if (signed_area(ring) > 0) std::reverse(ring.begin(), ring.end());
      add_ring(ring);
    }
    polygons_.push_back(std::move(normalised));
  }
  if (!(area_ > 0)) throw InputError(field, "has zero area");
  centroid_ = moment / area_;
  pieces_ = convex_decomposition(polygons_);
  double covered = 0;
  for (const auto& piece : pieces_) covered += signed_area(piece);
  if (!(std::abs(covered - area_) <= 1e-9 * area_))
    throw InputError(field, "could not be cut into convex pieces (they cover an area of " + std::to_string(covered) +
                                " instead of " + std::to_string(area_) + "): degenerate geometry");
}

bool PlaneRegion::contains(const Vec2& x) const {
  if (!(x.x() >= lower_.x() && x.x() <= upper_.x() && x.y() >= lower_.y() && x.y() <= upper_.y())) return false;
  // Crossing parity over all rings (the polygons are interior-disjoint), exact predicates; a
  // point on an edge is inside.
  bool inside = false;
  auto crosses = [&](const std::vector<Vec2>& ring) {
    for (std::size_t i = 0, n = ring.size(); i < n; ++i) {
      const Vec2& p = ring[i];
      const Vec2& q = ring[(i + 1) % n];
      const int side = orientation(p, q, x);
      if (side == 0 && std::min(p.x(), q.x()) <= x.x() && x.x() <= std::max(p.x(), q.x()) &&
          std::min(p.y(), q.y()) <= x.y() && x.y() <= std::max(p.y(), q.y()))
        return true;  // on the boundary
      if ((p.y() > x.y()) != (q.y() > x.y()) && (p.y() < q.y() ? side > 0 : side < 0)) inside = !inside;
    }
    return false;
  };
  for (const auto& polygon : polygons_) {
    if (crosses(polygon.outer)) return true;
    for (const auto& hole : polygon.holes)
      if (crosses(hole)) return true;
  }
  return inside;
}

}  // namespace sdot
