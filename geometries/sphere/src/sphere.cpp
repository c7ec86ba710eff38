// The sphere S² with the cost −ln⟨x, y⟩ (math.md §1, §2, §5).
#include "sdot/geometries/sphere.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <mutex>
#include <numbers>
#include <optional>
#include <random>
#include <string>

#include "sdot/cap_tree.hpp"
#include "sdot/error.hpp"
#include "sdot/quadrature.hpp"

namespace sdot {

struct Sphere::HullCache {
  std::mutex mutex;
  HullTriangulation surface;
};

std::shared_ptr<Sphere::HullCache> Sphere::make_hull_cache() {
  return std::make_shared<HullCache>();
}
namespace {

constexpr double pi = std::numbers::pi;
constexpr int arc_label = boundary_label(0);  // the cap's boundary circle

double cross2(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}

/// A right-handed orthonormal frame (t1, t2, c): t1 × t2 = c. Counter-clockwise in the gnomonic
/// chart v ↦ (t1 v₁ + t2 v₂ + c)/|·| is counter-clockwise seen from outside the sphere.
Eigen::Matrix3d frame_at(const Vec3& c) {
  const Vec3 helper = std::abs(c.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  const Vec3 t1 = (helper - helper.dot(c) * c).normalized();
  Eigen::Matrix3d frame;
  frame.col(0) = t1;
  frame.col(1) = c.cross(t1);
  frame.col(2) = c;
  return frame;
}

/// atan2(y, x), by its Taylor series where |y| ≤ x/20: the small angles of the cells' triangles
/// and arcs (10⁵ sites and more) are most of the integration's calls, and the series is several
/// times cheaper than the library's atan2. Its first omitted term is below 4e-20 of the angle.
double small_angle_atan2(double y, double x) {
  if (!(x > 0 && std::abs(y) <= 0.05 * x)) return std::atan2(y, x);
  const double t = y / x, t2 = t * t;
  return t * (1 + t2 * (-1.0 / 3 + t2 * (1.0 / 5 + t2 * (-1.0 / 7 + t2 * (1.0 / 9 + t2 * (-1.0 / 11 + t2 / 13))))));
}

/// Signed area of the spherical triangle abc (positive when counter-clockwise seen from outside),
/// Van Oosterom–Strackee with det(a, b, c) = det(a, b − a, c − a) for accuracy on small triangles.
double triangle_area(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double det = a.dot((b - a).cross(c - a));
  return 2 * small_angle_atan2(det, 1 + a.dot(b) + b.dot(c) + c.dot(a));
}

/// Angle swept counter-clockwise (seen from outside) around `center` from a to b (in (−π, π]).
double arc_angle(const Vec3& a, const Vec3& b, const Vec3& center) {
  return std::atan2(center.dot(a.cross(b)), a.dot(b) - a.dot(center) * b.dot(center));
}

/// The angle of a ball arc (partial transport) from a to b around `center`, in [0, 2π).
double ball_arc_angle(const Vec3& a, const Vec3& b, const Vec3& center) {
  const double angle = arc_angle(a, b, center);
  return angle < 0 ? angle + 2 * pi : angle;
}

/// Point at angle θ counter-clockwise around `center` from a.
Vec3 rotate_about(const Vec3& a, const Vec3& center, double theta) {
  const double along = a.dot(center);
  const Vec3 radial = a - along * center;
  return along * center + std::cos(theta) * radial + std::sin(theta) * center.cross(radial);
}

/// Accurate −ln⟨x, p⟩ = ½ ln(1 + tan²θ) for any positive multiple x of a unit vector.
double log_cost(const Vec3& x, const Vec3& p) {
  const double c = x.dot(p);
  if (!(c > 0)) return INFINITY;
  const double u = x.cross(p).squaredNorm() / (c * c);
  if (u > 1e-3) return 0.5 * std::log1p(u);
  // The series of log1p, several times cheaper near the site, where the cost quadrature's nodes
  // lie; its first omitted term is below 2e-19 of the value.
  return 0.5 * u * (1 + u * (-1.0 / 2 + u * (1.0 / 3 + u * (-1.0 / 4 + u * (1.0 / 5 - u / 6)))));
}

/// Makes `cell` the square |v|∞ ≤ half of the chart, in its existing buffers: the builders reuse
/// one cell per thread instead of allocating its vectors per site (with clip() writing in place,
/// a 10⁶-site diagram rebuilt from its previous hull went from 0.71 to 0.63 s).
void set_chart_square(ChartCell& cell, double half) {
  cell.vertices.assign({{-half, -half}, {half, -half}, {half, half}, {-half, half}});
  cell.neighbors.assign({boundary_label(0), boundary_label(1), boundary_label(2), boundary_label(3)});
}

bool has_boundary_edge(const ChartCell& cell) {
  return std::any_of(cell.neighbors.begin(), cell.neighbors.end(), [](int l) { return is_boundary(l); });
}

/// Maps a cell of the gnomonic chart with frame `frame` to unit vectors.
Cell<Vec3> to_sphere(const ChartCell& chart, const Eigen::Matrix3d& frame) {
  Cell<Vec3> cell;
  if (chart.empty()) return cell;
  cell.vertices.reserve(chart.size());
  for (const auto& v : chart.vertices) cell.vertices.push_back((frame * Vec3(v.x(), v.y(), 1)).normalized());
  cell.neighbors = chart.neighbors;
  return cell;
}

/// Sites in a uniform 3-D grid over [−1, 1]³ (bins sorted by index), for neighbour searches.
class SiteGrid {
 public:
  explicit SiteGrid(std::span<const Vec3> points) {
    const double n = static_cast<double>(points.size());
    size_ = std::max(1, static_cast<int>(std::min(std::sqrt(n / 12.0), std::cbrt(8 * n))));
    width_ = 2.0 / size_;
    const std::size_t bins = static_cast<std::size_t>(size_) * size_ * size_;
    start_.assign(bins + 1, 0);
    std::vector<int> key(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      key[i] = index(coordinate(points[i].x()), coordinate(points[i].y()), coordinate(points[i].z()));
      ++start_[key[i] + 1];
    }
    for (std::size_t b = 0; b < bins; ++b) start_[b + 1] += start_[b];
    items_.resize(points.size());
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < points.size(); ++i) items_[fill[key[i]]++] = static_cast<int>(i);
  }
  [[nodiscard]] int size() const { return size_; }
  /// The k-th site in bin order.
  [[nodiscard]] int site(std::size_t k) const { return items_[k]; }
  [[nodiscard]] double width() const { return width_; }
  [[nodiscard]] int coordinate(double x) const {
    return std::clamp(static_cast<int>(std::floor((x + 1) / width_)), 0, size_ - 1);
  }
  [[nodiscard]] int index(int x, int y, int z) const { return (x * size_ + y) * size_ + z; }
  /// Calls f(j) for every site in the bins at Chebyshev distance exactly r from bin (x, y, z).
  template <class F>
  void ring(int x, int y, int z, int r, F&& f) const {
    for (int dx = -r; dx <= r; ++dx) {
      const int ix = x + dx;
      if (ix < 0 || ix >= size_) continue;
      for (int dy = -r; dy <= r; ++dy) {
        const int iy = y + dy;
        if (iy < 0 || iy >= size_) continue;
        const bool face = std::abs(dx) == r || std::abs(dy) == r;
        for (int dz = -r; dz <= r; dz += face ? 1 : std::max(2 * r, 1)) {
          const int iz = z + dz;
          if (iz < 0 || iz >= size_) continue;
          const int b = index(ix, iy, iz);
          for (int k = start_[b]; k < start_[b + 1]; ++k) f(items_[k]);
        }
      }
    }
  }
  /// Calls f(j) for every site in the bins meeting the box [lo, hi].
  template <class F>
  void box(const Vec3& lo, const Vec3& hi, F&& f) const {
    box_positions(lo, hi, [&](int k) { f(items_[static_cast<std::size_t>(k)]); });
  }
  /// Calls f(k) for the bin-order position k (see site()) of every site in the bins meeting the
  /// box [lo, hi].
  template <class F>
  void box_positions(const Vec3& lo, const Vec3& hi, F&& f) const {
    for (int ix = coordinate(lo.x()); ix <= coordinate(hi.x()); ++ix)
      for (int iy = coordinate(lo.y()); iy <= coordinate(hi.y()); ++iy)
        for (int iz = coordinate(lo.z()); iz <= coordinate(hi.z()); ++iz) {
          const int b = index(ix, iy, iz);
          for (int k = start_[b]; k < start_[b + 1]; ++k) f(k);
        }
  }

 private:
  int size_ = 1;
  double width_ = 2;
  std::vector<int> start_, items_;
};

/// A kd-tree over the sites with the largest scale e^{h} per node, for exact branch-and-bound
/// "which sites beat level L at x" queries: e^{h_j}⟨x, p_j⟩ > L. Each node keeps a cone (unit
/// axis c, angular radius α) containing its sites, so max_j ⟨x, p_j⟩ ≤ cos(max(0, ∠(x, c) − α)).
class ScaleTree {
 public:
  ScaleTree(std::span<const Vec3> points, std::span<const double> scales)
      : points_(points), scales_(scales), tree_(points), max_scale_(tree_.nodes().size(), 0.0) {
    const auto& order = tree_.order();
    for (std::size_t n = 0; n < tree_.nodes().size(); ++n) {
      const auto& node = tree_.nodes()[n];
      for (int k = node.begin; k < node.end; ++k)
        max_scale_[n] = std::max(max_scale_[n], scales[static_cast<std::size_t>(order[static_cast<std::size_t>(k)])]);
    }
  }
  template <class Found>
  void above(const Vec3& x, double level, Found&& found) const {
    tree_.traverse(
        [&](const CapTree::Node& node, int index) {
          const double scale = max_scale_[static_cast<std::size_t>(index)];
          const double c = x.dot(node.axis);
          if (c >= node.cos_radius) return scale > level;  // x inside the cone
          const double bound = c * node.cos_radius + std::sqrt(std::max(0.0, 1 - c * c)) * node.sin_radius;
          return scale * bound > level;
        },
        [&](int j) {
          if (scales_[static_cast<std::size_t>(j)] * x.dot(points_[static_cast<std::size_t>(j)]) > level) found(j);
        });
  }

 private:
  std::span<const Vec3> points_;
  std::span<const double> scales_;
  CapTree tree_;
  std::vector<double> max_scale_;
};

/// What to subtract from heights before forming e^h p, given the largest: cells and facet weights
/// depend on height differences only. A damped-Newton trial step can spread heights by hundreds,
/// and from h ≈ 236 the triple products of e^h p in the hull's predicates overflow (Qhull crashed
/// on points of norm 1e156, found by tests/stress/stress_test.cpp); such heights are taken
/// relative to the largest. Ordinary heights are used as they are, with their usual rounding.
double height_offset(double largest) {
  return largest > 100 ? largest : 0;
}

/// Clips the chart cell of site i (gnomonic chart at p_i with tangent frame t1, t2) with the
/// half-plane ⟨X, q_i − q_j⟩ ≥ 0, X = t1 v₁ + t2 v₂ + p_i, divided by e^{h_j} and written without
/// cancellation: −⟨p_j − p_i, t⟩·v + expm1(h_i − h_j) + |p_i − p_j|²/2 ≥ 0.
struct HalfPlane {
  Vec2 normal;
  double offset;
};
inline HalfPlane bisector(const Eigen::Matrix3d& frame, const Vec3& p_i, double hi, const Vec3& pj, double hj) {
  const Vec3 d = pj - p_i;
  return {Vec2(-d.dot(frame.col(0)), -d.dot(frame.col(1))), std::expm1(hi - hj) + 0.5 * d.squaredNorm()};
}

/// The neighbours of a vertex of a closed triangulated surface in counter-clockwise order seen
/// from outside, appended to `ring`, from `first`, a half-edge out of the vertex (3t + k: corner
/// k of triangle t). False when the surface is not closed around the vertex.
bool hull_neighbours(const HullTriangulation& surface, int first, std::vector<int>& ring) {
  if (first < 0) return false;
  int edge = first;
  do {
    const auto t = static_cast<std::size_t>(edge / 3);
    const auto k = static_cast<std::size_t>(edge % 3);
    ring.push_back(surface.triangles[t][(k + 1) % 3]);
    // The half-edge into the vertex from the triangle's third corner, reversed: the next neighbour.
    edge = surface.opposite[3 * t + (k + 2) % 3];
    if (edge < 0 || ring.size() > surface.triangles.size()) return false;
  } while (edge != first);
  return true;
}

/// Largest |v| over the chart cell's vertices.
double chart_radius(const ChartCell& cell) {
  double r2 = 0;
  for (const auto& v : cell.vertices) r2 = std::max(r2, v.squaredNorm());
  return std::sqrt(r2);
}

/// Largest piece (chord) of the fan triangles before quadrature: larger ones are subdivided.
constexpr double largest_piece = 0.3;

/// Quadrature nodes of a cell: calls f(x, dA) with x a unit vector. Fan from the normalised
/// vertex mean o; great-circle edges give centrally projected flat triangles (o, a, b), split
/// into m² sub-triangles when larger than `largest_piece`, each with the collapsed Gauss rule
/// (dA = det(o, a, b)/|X|³ ds dt); cap-circle arcs give curved triangles X = o + s(γ(t) − o),
/// split into m × m pieces with a tensor Gauss–Legendre rule (dA = s·det(o, γ, γ')/|X|³ ds dt).
/// `order` may depend on the piece size (`order_for(size)`).
template <class Order, class F>
void for_each_node(const Sphere& sphere, const Cell<Vec3>& cell, Order&& order_for, F&& f, const Vec3* site = nullptr) {
  Vec3 o = Vec3::Zero();
  for (const auto& v : cell.vertices) o += v;
  o.normalize();
  const std::size_t n = cell.size();
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3& a = cell.vertices[k];
    const Vec3& b = cell.vertices[(k + 1) % n];
    const bool ball_arc = site && is_ball_arc(cell.neighbors[k]);
    if (!ball_arc && !sphere.is_circle_arc(cell.neighbors[k])) {
      const Vec3 ab = a - o, ac = b - o;
      const double det = o.dot(ab.cross(ac));
      if (det == 0) continue;
      const double size = std::max({ab.norm(), ac.norm(), (b - a).norm()});
      const int m = std::max(1, static_cast<int>(std::ceil(size / largest_piece)));
      const auto& triangle = triangle_rule(order_for(size / m));
      const double scale = det / (m * m);
      auto sub = [&](double s0, double t0, double ds1, double dt1, double ds2, double dt2) {
        for (const auto& node : triangle) {
          const double s = s0 + node.s * ds1 + node.t * ds2, t = t0 + node.s * dt1 + node.t * dt2;
          const Vec3 x = o + s * ab + t * ac;
          const double r = x.norm();
          f(Vec3(x / r), node.weight * scale / (r * r * r));
        }
      };
      const double h = 1.0 / m;
      for (int u = 0; u < m; ++u)
        for (int v = 0; u + v < m; ++v) {
          sub(u * h, v * h, h, 0, 0, h);                             // (u,v) (u+1,v) (u,v+1)
          if (u + v + 2 <= m) sub((u + 1) * h, v * h, 0, h, -h, h);  // (u+1,v) (u+1,v+1) (u,v+1)
        }
    } else {
      const Vec3& c = ball_arc ? *site : sphere.center();
      const double phi = ball_arc ? ball_arc_angle(a, b, c) : arc_angle(a, b, c);
      const double sine = ball_arc ? a.cross(c).norm() : std::sin(sphere.cap_angle());
      const double size = std::max({(a - o).norm(), (b - o).norm(), phi * sine});
      const int m = std::max(1, static_cast<int>(std::ceil(size / largest_piece)));
      const auto& line = gauss_legendre(order_for(size / m));
      const double h = 1.0 / m;
      for (int pt = 0; pt < m; ++pt)
        for (const auto& nt : line) {
          const double t = (pt + nt.x) * h;
          const Vec3 g = rotate_about(a, c, t * phi);
          const Vec3 dg = phi * c.cross(g);
          const double det = o.dot(g.cross(dg));
          for (int ps = 0; ps < m; ++ps)
            for (const auto& ns : line) {
              const double s = (ps + ns.x) * h;
              const Vec3 x = o + s * (g - o);
              const double r = x.norm();
              f(Vec3(x / r), ns.weight * nt.weight * h * h * s * det / (r * r * r));
            }
        }
    }
  }
}

/// Quadrature order for the uniform transport cost, from the piece size (chord): the integrand
/// is smooth, so small pieces need few points for ~1e-14 relative accuracy.
int cost_order(double size) {
  if (size < 0.02) return 4;
  if (size < 0.06) return 5;
  if (size < 0.15) return 6;
  return 8;
}

/// ∫ −ln⟨x, p⟩ dA over a cell with great-arc edges only that lies close to its site p: within
/// tan²θ ≤ 10⁻³ (θ ≈ 1.8°; every cell of 10⁴ or more well-spread sites), otherwise nullopt.
/// In the gnomonic chart at p (x ↦ x/⟨x, p⟩, |x'|² = tan²θ) the edges are segments, and in polar
/// coordinates about p the radial integral is closed: ∫₀^R −ln(cos θ) sin θ dθ = F(tan²R) with
/// F(t) = 1 − c + c ln c, c = (1 + t)^(−1/2). Along an edge at signed distance h from p, with
/// arc length s from the foot of the perpendicular, t = h² + s² and dφ = h ds / t, so the cell's
/// cost is Σ_edges ∫ h F(t)/t ds. F(t)/t is a power series in t (whose first terms cancel in
/// floating point), hence a polynomial in s, integrated exactly by Gauss–Legendre: 5–7 points per
/// edge instead of a 2-D rule on each fan triangle.
std::optional<double> small_cell_cost(const Cell<Vec3>& cell, const Vec3& p) {
  constexpr double largest_t = 1e-3;
  const std::size_t n = cell.size();
  // Chart positions relative to p, as 3-D vectors orthogonal to p.
  constexpr std::size_t stack_size = 16;
  std::array<Vec3, stack_size> stack_chart;
  std::vector<Vec3> heap_chart;
  Vec3* chart = stack_chart.data();
  if (n > stack_size) {
    heap_chart.resize(n);
    chart = heap_chart.data();
  }
  double t_max = 0;
  for (std::size_t k = 0; k < n; ++k) {
    if (is_boundary(cell.neighbors[k])) return std::nullopt;  // a cap-circle or ball arc
    const Vec3& x = cell.vertices[k];
    const double c = x.dot(p);
    if (!(c > 0)) return std::nullopt;
    chart[k] = (x - c * p) / c;
    t_max = std::max(t_max, chart[k].squaredNorm());
  }
  if (!(t_max <= largest_t)) return std::nullopt;
  // F(t)/t = Σ_k series[k] t^(k+1); with 6 terms the first omitted one is below 2e-18 of the
  // value at t ≤ 10⁻³. A polynomial of degree 2·terms in s needs terms + 1 Gauss points.
  static constexpr std::array<double, 6> series = {1.0 / 8,     -1.0 / 6,       71.0 / 384,
                                                   -31.0 / 160, 3043.0 / 15360, -2689.0 / 13440};
  const int terms = t_max <= 1e-5 ? 4 : t_max <= 1e-4 ? 5 : 6;
  static const std::array<std::vector<QuadratureNode1>, 3> rules = {gauss_legendre(5), gauss_legendre(6),
                                                                    gauss_legendre(7)};
  const auto& rule = rules[static_cast<std::size_t>(terms - 4)];
  double cost = 0, magnitude = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3& a = chart[k];
    const Vec3& b = chart[(k + 1) % n];
    const Vec3 d = b - a;
    const double length = d.norm();
    if (length == 0) continue;
    const Vec3 direction = d / length;
    const double h = p.dot(a.cross(direction));  // positive for a counter-clockwise edge
    const double s_a = a.dot(direction);
    double edge = 0;
    for (const auto& node : rule) {
      const double s = s_a + node.x * length, t = h * h + s * s;
      double value = series[static_cast<std::size_t>(terms - 1)];
      for (int j = terms - 2; j >= 0; --j) value = series[static_cast<std::size_t>(j)] + t * value;
      edge += node.weight * t * value;
    }
    cost += h * length * edge;
    magnitude += std::abs(h * length * edge);
  }
  // A site far outside its (small) cell: the signed fan from p cancels, losing digits; the 2-D
  // rule, fanned from the cell's own centre, does not.
  if (!(magnitude <= 2 * cost)) return std::nullopt;
  return cost;
}

}  // namespace

// ---- construction ----------------------------------------------------------------------

Sphere Sphere::cap(const Point& center, double angle) {
  if (!center.allFinite()) throw InputError("domain.center", "coordinate is not finite");
  if (!(center.norm() > 0)) throw InputError("domain.center", "is the zero vector");
  if (!(angle > 0 && angle < pi / 2))
    throw InputError("domain.angle", "must be in (0, π/2) radians, got " + std::to_string(angle));
  Sphere sphere;
  sphere.domain_ = Domain::cap;
  sphere.center_ = center.normalized();
  sphere.angle_ = angle;
  sphere.frame_ = frame_at(sphere.center_);
  const double half = 1.5 * std::tan(angle);
  sphere.chart_domain_ = ConvexPolygon::rectangle(-half, -half, half, half);
  return sphere;
}

Sphere Sphere::polygon(std::vector<Point> vertices) {
  if (vertices.size() < 3)
    throw InputError("domain", "a polygon needs at least 3 vertices, got " + std::to_string(vertices.size()));
  Vec3 sum = Vec3::Zero();
  for (std::size_t k = 0; k < vertices.size(); ++k) {
    if (!vertices[k].allFinite()) throw InputError(indexed("domain", k), "vertex is not finite");
    if (!(vertices[k].norm() > 0)) throw InputError(indexed("domain", k), "is the zero vector");
    vertices[k].normalize();
    sum += vertices[k];
  }
  if (!(sum.norm() > 1e-12)) throw InputError("domain", "the polygon must lie in an open hemisphere");
  Sphere sphere;
  sphere.domain_ = Domain::polygon;
  sphere.center_ = sum.normalized();
  sphere.frame_ = frame_at(sphere.center_);
  std::vector<Vec2> chart;
  for (std::size_t k = 0; k < vertices.size(); ++k) {
    const Vec3 local = sphere.frame_.transpose() * vertices[k];
    if (!(local.z() > 1e-9))
      throw InputError(indexed("domain", k), "the polygon must lie in an open hemisphere (it is too large)");
    chart.emplace_back(local.x() / local.z(), local.y() / local.z());
  }
  sphere.chart_domain_ = ConvexPolygon(std::move(chart), "domain");
  for (const auto& v : sphere.chart_domain_.vertices())
    sphere.vertices_.push_back((sphere.frame_ * Vec3(v.x(), v.y(), 1)).normalized());
  return sphere;
}

double Sphere::domain_area() const {
  switch (domain_) {
    case Domain::cap:
      return 4 * pi * std::pow(std::sin(angle_ / 2), 2);
    case Domain::polygon: {
      double area = 0;
      for (std::size_t k = 1; k + 1 < vertices_.size(); ++k)
        area += triangle_area(vertices_[0], vertices_[k], vertices_[k + 1]);
      return area;
    }
    case Domain::sphere:
    default:
      return 4 * pi;
  }
}

double Sphere::cost(const Point& x, const Point& y) {
  return log_cost(x.normalized(), y.normalized());
}

// ---- sites -----------------------------------------------------------------------------

void Sphere::validate_sites(std::span<const Point> sites) const {
  std::vector<Vec3> p(sites.size());
  for (std::size_t i = 0; i < sites.size(); ++i) {
    if (!sites[i].allFinite()) throw InputError(indexed("sites", i), "coordinate is not finite");
    double norm = sites[i].norm();
    if (!(norm > 0 && std::isfinite(norm))) norm = sites[i].stableNorm();  // |x|² under- or overflowed
    if (!(norm > 0)) throw InputError(indexed("sites", i), "is the zero vector (a site is a direction in R³)");
    // The geometry normalises sites by their norm, whose square overflows or underflows beyond.
    if (!(norm <= 1e150 && norm >= 1e-150))
      throw InputError(indexed("sites", i), "has a length outside [1e-150, 1e150]; scale it towards unit length");
    p[i] = sites[i] / norm;
  }
  // Duplicates after normalisation (closer than 1e-14): search the grid around each site.
  {
    const SiteGrid grid(p);
    const double tolerance = 1e-14;
    const Vec3 slack = Vec3::Constant(tolerance);
    // In the grid's bin order, so that neighbouring queries read neighbouring memory (in the
    // caller's order each query missed the cache three times; 10⁶ random sites: the solve starts
    // 0.1 s sooner).
    std::vector<Vec3> binned(p.size());
    for (std::size_t k = 0; k < p.size(); ++k) binned[k] = p[static_cast<std::size_t>(grid.site(k))];
    std::size_t first_bad = sites.size(), partner = 0;
#pragma omp parallel for schedule(static)
    for (std::size_t k = 0; k < sites.size(); ++k) {
      const auto i = static_cast<std::size_t>(grid.site(k));
      std::size_t found = sites.size();
      grid.box_positions(binned[k] - slack, binned[k] + slack, [&](int other) {
        const auto j = static_cast<std::size_t>(grid.site(static_cast<std::size_t>(other)));
        if (j < i && (binned[k] - binned[static_cast<std::size_t>(other)]).norm() <= tolerance)
          found = std::min(found, j);
      });
      if (found < sites.size()) {
#pragma omp critical
        if (i < first_bad) first_bad = i, partner = found;
      }
    }
    if (first_bad < sites.size())
      throw InputError(indexed("sites", first_bad),
                       "duplicate of sites[" + std::to_string(partner) + "] (after normalisation)");
  }
  if (domain_ == Domain::sphere) {
    const std::string message =
        "all sites lie in a closed hemisphere; on the whole sphere the origin must be strictly inside the "
        "convex hull of the sites, otherwise a Laguerre cell is unbounded and the cost −ln⟨x, y⟩ is infinite on "
        "part of it (add sites, or use a cap or polygon domain)";
    if (p.size() < 4) throw InputError("sites", message);
    // Cheap sufficient test: the sites nearest the 4 directions of a regular tetrahedron span a
    // tetrahedron that strictly contains the origin. Otherwise decide with the convex hull.
    const Vec3 directions[4] = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
    Eigen::Matrix3d m;
    Vec3 v0 = Vec3::Zero();
    for (int d = 0; d < 4; ++d) {
      std::size_t best = 0;
      double best_dot = -INFINITY;
      for (std::size_t i = 0; i < p.size(); ++i)
        if (const double dot = p[i].dot(directions[d]); dot > best_dot) best_dot = dot, best = i;
      if (d == 0)
        v0 = p[best];
      else
        m.col(d - 1) = p[best] - v0;
    }
    // 0 = v0 + m λ; barycentric coordinates (1 − Σλ, λ) must all be positive.
    const Vec3 lambda = m.fullPivLu().solve(-v0);
    const bool inside = (m * lambda + v0).norm() < 1e-12 && lambda.minCoeff() > 1e-9 && 1 - lambda.sum() > 1e-9;
    if (!inside) {
      bool ok = false;
      try {
        ok = convex_hull_3d(p).max_facet_offset < -1e-12;
      } catch (const Error&) {
        ok = false;  // degenerate hull: all sites on one plane through... or near it
      }
      if (!ok) throw InputError("sites", message);
    }
    return;
  }
  // Cap or polygon: every point of the domain must see some site at distance < π/2. Checked on
  // the Voronoi diagram: the minimum of ⟨x, p_i⟩ over cell i (attained on its boundary) is > 0.
  const Diagram<Point> voronoi = build_diagram(sites, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(p.size())));
  for (std::size_t i = 0; i < p.size(); ++i) {
    const auto& cell = voronoi.cells[i];
    double lowest = INFINITY;
    for (std::size_t k = 0; k < cell.size(); ++k) {
      const Vec3& a = cell.vertices[k];
      lowest = std::min(lowest, a.dot(p[i]));
      if (!is_circle_arc(cell.neighbors[k])) continue;
      // f(θ) = K + U cos θ + V sin θ along the arc; its minimum over the circle is at θ*.
      const double phi = arc_angle(a, cell.vertices[(k + 1) % cell.size()], center_);
      const Vec3 radial = a - a.dot(center_) * center_;
      const double u = radial.dot(p[i]), v = center_.cross(radial).dot(p[i]);
      double theta = std::atan2(v, u) + pi;
      if (theta >= 2 * pi) theta -= 2 * pi;
      if (theta <= phi) lowest = std::min(lowest, a.dot(center_) * center_.dot(p[i]) - std::hypot(u, v));
    }
    if (!(lowest > 1e-12))
      throw InputError("sites", "part of the source domain is at distance >= π/2 from every site (near sites[" +
                                    std::to_string(i) + "]), where the cost −ln⟨x, y⟩ is infinite");
  }
}

Eigen::VectorXd Sphere::default_weights(std::span<const Point> sites) const {
  const auto n = static_cast<Eigen::Index>(sites.size());
  Eigen::VectorXd weights = Eigen::VectorXd::Zero(n);
  if (domain_ == Domain::sphere) return weights;
  // math.md §3 (S²-cap, κ = +1): z_i the chart coordinates, h_i = ½ln(1 + |z|²) − ln(1 + τ|z|²);
  // then u_i = 2τz_i/(1 − τ|z_i|²) lies in W_i, and τ is chosen so that every u_i is in the domain.
  std::vector<Vec2> z(sites.size());
  std::vector<char> visible(sites.size(), 0);
  double tau = 1;
  for (std::size_t i = 0; i < sites.size(); ++i) {
    const Vec3 local = frame_.transpose() * sites[i].normalized();
    if (!(local.z() > 1e-9)) continue;
    visible[i] = 1;
    z[i] = local.head<2>() / local.z();
    const double length = z[i].norm();
    if (length == 0) continue;
    const Vec2 direction = z[i] / length;
    double exit = INFINITY;  // distance from the chart origin to the domain boundary along z_i
    if (domain_ == Domain::cap) {
      exit = std::tan(angle_);
    } else {
      const auto& boundary = chart_domain_.vertices();
      for (std::size_t k = 0; k < boundary.size(); ++k) {
        const Vec2& a = boundary[k];
        const Vec2& b = boundary[(k + 1) % boundary.size()];
        const double rate = cross2(b - a, direction);
        if (rate < 0) exit = std::min(exit, cross2(b - a, -a) / -rate);
      }
    }
    const double target = 0.9 * exit;
    tau = std::min(tau, target / (2 * length + target * length * length));
  }
  double lowest = INFINITY;
  for (std::size_t i = 0; i < sites.size(); ++i) {
    if (!visible[i]) continue;
    const double r2 = z[i].squaredNorm();
    weights[static_cast<Eigen::Index>(i)] = 0.5 * std::log1p(r2) - std::log1p(tau * r2);
    lowest = std::min(lowest, weights[static_cast<Eigen::Index>(i)]);
  }
  // Sites behind the domain's hemisphere: no guarantee; give them the lowest height.
  for (std::size_t i = 0; i < sites.size(); ++i)
    if (!visible[i]) weights[static_cast<Eigen::Index>(i)] = std::isfinite(lowest) ? lowest : 0;
  return weights;
}

// ---- diagrams --------------------------------------------------------------------------

Diagram<Sphere::Point> Sphere::build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights) const {
  return build_diagram(sites, weights, false);
}

Diagram<Sphere::Point> Sphere::build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                             bool stop_at_empty_cell) const {
  if (domain_ == Domain::sphere) return build_whole_sphere(sites, weights, stop_at_empty_cell);
  return build_in_chart(sites, weights);
}

Diagram<Sphere::Point> Sphere::build_whole_sphere(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                                  bool stop_at_empty_cell) const {
  const std::size_t n = sites.size();
  std::vector<Vec3> p(n);
  std::vector<double> h(n);
  const double offset = n > 0 ? height_offset(weights.maxCoeff()) : 0;
  const auto site_count = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t k = 0; k < site_count; ++k) {
    const auto i = static_cast<std::size_t>(k);
    p[i] = sites[i].normalized();
    h[i] = weights[static_cast<Eigen::Index>(i)] - offset;
  }
  Diagram<Point> diagram;
  diagram.cells.resize(n);
  if (n < 4) return diagram;  // never bounded (validate_sites rejects this)

  // Clips `cell` by site j unless the half-plane contains the disk |v| ≤ radius around the
  // cell (cheap rejection); keeps `radius` an upper bound of max |v| over the cell.
  auto clip_with = [&](ChartCell& cell, double& radius, const Eigen::Matrix3d& frame, std::size_t i, int j) {
    const HalfPlane half = bisector(frame, p[i], h[i], p[static_cast<std::size_t>(j)], h[static_cast<std::size_t>(j)]);
    if (half.offset >= half.normal.norm() * radius) return;
    clip(cell, half.normal, half.offset, j);
    radius = chart_radius(cell);
  };

  const double spacing = std::sqrt(4 * pi / static_cast<double>(n));
  const bool use_hull = builder_ != Builder::clipping;
  if (use_hull) {
    std::vector<Vec3> q(n);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t k = 0; k < site_count; ++k)
      q[static_cast<std::size_t>(k)] = std::exp(h[static_cast<std::size_t>(k)]) * p[static_cast<std::size_t>(k)];
    Hull3 hull;
    HullTriangulation start;  // taken, not copied: a concurrent build then finds none and starts afresh
    {
      const std::lock_guard lock(hull_cache_->mutex);
      start = std::move(hull_cache_->surface);
    }
    // From the previous hull; where a reflex edge stays stuck there (blub and brain_48k, once per
    // solve), from scratch by insertion, which does not get stuck; Qhull last.
    const bool from_previous = !start.triangles.empty();
    // The cells come from the surface, so the hull's vertex adjacency is not needed.
    std::optional<Hull3> grown = convex_hull_3d_by_flips(q, std::move(start), stop_at_empty_cell, false);
    if (!grown && from_previous) grown = convex_hull_3d_by_flips(q, {}, stop_at_empty_cell, false);
    if (grown) {
      hull = std::move(*grown);
    } else {
      try {
        hull = convex_hull_3d(q, true);
      } catch (const Error&) {
        return diagram;  // degenerate: all cells empty, so the line search rejects this step
      }
    }
    // The surface goes back to the cache once the cells are built (they walk it).
    auto keep_surface = [&] {
      const std::lock_guard lock(hull_cache_->mutex);
      hull_cache_->surface = std::move(hull.surface);
    };
    // An empty cell (the caller rejects these weights), or the hemisphere condition violated.
    // A point inside the hull is an empty cell: a caller that rejects those needs no cells at all.
    if (hull.stopped_at_inside || !(hull.max_facet_offset < 0) ||
        (stop_at_empty_cell && std::find(hull.is_vertex.begin(), hull.is_vertex.end(), 0) != hull.is_vertex.end())) {
      keep_surface();
      return diagram;
    }
    const double m = -hull.max_facet_offset;
    const auto count = static_cast<std::ptrdiff_t>(n);
    const auto& triangles = hull.surface.triangles;
    // One half-edge out of each hull vertex (3t + k: corner k of triangle t is the vertex).
    std::vector<int> outgoing(n, -1);
    for (std::size_t t = 0; t < triangles.size(); ++t)
      for (std::size_t k = 0; k < 3; ++k)
        outgoing[static_cast<std::size_t>(triangles[t][k])] = static_cast<int>(3 * t + k);
#pragma omp parallel
    {
      ChartCell cell;
      std::vector<int> ring;  // the hull neighbours of a vertex, counter-clockwise seen from outside
      std::vector<Vec2> normals;
      std::vector<double> offsets;
#pragma omp for schedule(dynamic, 256)
      for (std::ptrdiff_t s = 0; s < count; ++s) {
        const auto i = static_cast<std::size_t>(s);
        if (!hull.is_vertex[i]) continue;  // q_i inside the hull: empty cell
        // On W_i, ⟨x, p_i⟩ ≥ m e^{−h_i}, so |v| ≤ √(e^{2h_i}/m² − 1) in the chart at p_i (math.md §5).
        const double scale = std::exp(h[i]) / m;
        const double half = 1.1 * std::sqrt(std::max(scale * scale - 1, 0.0)) + 1e-9;
        const Eigen::Matrix3d frame = frame_at(p[i]);
        // The cell straight from the hull: its edges are the bisectors with the hull neighbours,
        // in their order around the vertex (clipping a square by the same bisectors, as below,
        // gives the same cell at several times the cost).
        ring.clear(), normals.clear(), offsets.clear();
        if (!hull_neighbours(hull.surface, outgoing[i], ring)) continue;  // never for a closed hull
        for (int j : ring) {
          const HalfPlane line =
              bisector(frame, p[i], h[i], p[static_cast<std::size_t>(j)], h[static_cast<std::size_t>(j)]);
          normals.push_back(line.normal), offsets.push_back(line.offset);
        }
        if (!cell_from_ordered_lines(cell, normals, offsets, ring, half)) {
          // A corner too close to call (near-degenerate sites): clip a square by the neighbours.
          set_chart_square(cell, half);
          double radius = chart_radius(cell);
          for (int j : ring) {
            clip_with(cell, radius, frame, i, j);
            if (cell.empty()) break;
          }
          if (has_boundary_edge(cell)) continue;  // cannot happen when 0 is inside the hull
        }
        diagram.cells[i] = to_sphere(cell, frame);
      }
    }
    keep_surface();
    return diagram;
  }

  // Clipping, certified: each cell starts as a square of the chart at p_i clipped by the sites
  // of the nearest grid bins (nearest first); then, while some site j beats site i at a vertex x
  // of the cell (e^{h_j}⟨x, p_j⟩ > e^{h_i}⟨x, p_i⟩, found exactly by a kd-tree with the largest
  // e^{h} per node), the cell is clipped by it. A half-plane that cuts a convex polygon excludes
  // one of its vertices, so the loop ends with the exact cell whatever the heights.
  const SiteGrid grid(p);
  std::vector<double> scale(n);
  for (std::size_t i = 0; i < n; ++i) scale[i] = std::exp(h[i]);
  const ScaleTree tree(p, scale);
  const double initial_half = std::min(4 * spacing, 2.0);
  constexpr double largest_half = 1e4;
  const auto count = static_cast<std::ptrdiff_t>(n);
  std::atomic<bool> found_empty{false};
#pragma omp parallel
  {
    std::vector<std::pair<double, int>> candidates;
    std::vector<int> processed, pending;
    ChartCell cell;
#pragma omp for schedule(dynamic, 256)
    for (std::ptrdiff_t s = 0; s < count; ++s) {
      if (stop_at_empty_cell && found_empty.load(std::memory_order_relaxed)) continue;
      const auto i = static_cast<std::size_t>(grid.site(static_cast<std::size_t>(s)));  // grid order: locality
      const Eigen::Matrix3d frame = frame_at(p[i]);
      const int bx = grid.coordinate(p[i].x()), by = grid.coordinate(p[i].y()), bz = grid.coordinate(p[i].z());
      candidates.clear();
      for (int r = 0; r < 2; ++r)
        grid.ring(bx, by, bz, r, [&](int j) {
          if (static_cast<std::size_t>(j) != i)
            candidates.emplace_back((p[static_cast<std::size_t>(j)] - p[i]).squaredNorm(), j);
        });
      // The nearest few bound the cell almost always; the certification below adds any other.
      constexpr std::size_t seeds = 16;
      if (candidates.size() > seeds) {
        std::nth_element(candidates.begin(), candidates.begin() + seeds, candidates.end());
        candidates.resize(seeds);
      }
      std::sort(candidates.begin(), candidates.end());
      double half = initial_half;
      for (;;) {
        set_chart_square(cell, half);
        double radius = chart_radius(cell);
        processed.clear();
        for (const auto& [distance2, j] : candidates) {
          clip_with(cell, radius, frame, i, j);
          processed.push_back(j);
          if (cell.empty()) break;
        }
        std::sort(processed.begin(), processed.end());
        while (!cell.empty()) {
          pending.clear();
          for (const auto& v : cell.vertices) {
            const Vec3 x = (frame * Vec3(v.x(), v.y(), 1)).normalized();
            // Slightly below the vertex's own level: the sites defining the vertex tie with i
            // there and are skipped as processed; clipping by a near-tie is harmless.
            const double level = scale[i] * x.dot(p[i]) * (1 - 1e-14);
            tree.above(x, level, [&](int j) {
              if (static_cast<std::size_t>(j) != i && !std::binary_search(processed.begin(), processed.end(), j))
                pending.push_back(j);
            });
          }
          if (pending.empty()) break;
          std::sort(pending.begin(), pending.end());
          pending.erase(std::unique(pending.begin(), pending.end()), pending.end());
          for (int j : pending) {
            clip_with(cell, radius, frame, i, j);
            if (cell.empty()) break;
          }
          processed.insert(processed.end(), pending.begin(), pending.end());
          std::sort(processed.begin(), processed.end());
        }
        if (cell.empty()) {
          if (half < largest_half) {  // the cell may lie outside the square: look again, wider
            half = largest_half;
            continue;
          }
          break;
        }
        if (has_boundary_edge(cell)) {
          if (half < largest_half) {
            half = std::min(8 * half, largest_half);
            continue;
          }
          cell.vertices.clear(), cell.neighbors.clear();  // unbounded: the sites are in a closed hemisphere
          break;
        }
        // Found with a large square: redo with a tight one for accuracy.
        if (half > 8 * radius && half > initial_half) {
          half = std::max(2 * radius, initial_half);
          continue;
        }
        break;
      }
      if (cell.empty()) found_empty.store(true, std::memory_order_relaxed);
      diagram.cells[i] = to_sphere(cell, frame);
    }
  }
  return diagram;
}

Diagram<Sphere::Point> Sphere::build_in_chart(std::span<const Point> sites, const Eigen::VectorXd& weights) const {
  const std::size_t n = sites.size();
  std::vector<Vec3> dual(n), p(n);
  std::vector<double> h(n);
  const double offset = n > 0 ? height_offset(weights.maxCoeff()) : 0;
  for (std::size_t i = 0; i < n; ++i) {
    p[i] = sites[i].normalized();
    h[i] = weights[static_cast<Eigen::Index>(i)] - offset;
    dual[i] = frame_.transpose() * (std::exp(h[i]) * p[i]);
  }
  // Neighbour candidates from the chart's regular triangulation; each cell is the chart domain
  // clipped by them, with the half-planes ⟨X, q_i − q_j⟩ ≥ 0 written without cancellation:
  // (q_i − q_j)e^{−h_j} = expm1(h_i − h_j) p_i + (p_i − p_j).
  const Adjacency candidates = chart_adjacency(dual, chart_domain_);
  std::vector<ChartCell> chart(n);
  const auto& boundary = chart_domain_.vertices();
  const auto count_all = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(dynamic, 256)
  for (std::ptrdiff_t s = 0; s < count_all; ++s) {
    const auto i = static_cast<std::size_t>(s);
    const auto neighbors = candidates.of(i);
    if (neighbors.empty()) continue;
    ChartCell& cell = chart[i];
    cell.vertices.assign(boundary.begin(), boundary.end());
    cell.neighbors.resize(boundary.size());
    for (std::size_t k = 0; k < boundary.size(); ++k) cell.neighbors[k] = boundary_label(static_cast<int>(k));
    for (int j : neighbors) {
      if (j >= static_cast<int>(n)) continue;  // a helper function of chart_adjacency
      const auto u = static_cast<std::size_t>(j);
      const Vec3 difference = frame_.transpose() * (std::expm1(h[i] - h[u]) * p[i] + (p[i] - p[u]));
      clip(cell, difference.head<2>(), difference.z(), j);
      if (cell.empty()) break;
    }
  }
  Diagram<Point> diagram;
  diagram.cells.resize(n);
  if (domain_ == Domain::polygon) {
    for (std::size_t i = 0; i < n; ++i) diagram.cells[i] = to_sphere(chart[i], frame_);
    return diagram;
  }
  // Cap: intersect each chart polygon with the disk |v| ≤ tan(angle) exactly; the parts of the
  // circle become edges labelled `arc_label`, split so that each spans at most 90°.
  const double radius = std::tan(angle_);
  const double radius2 = radius * radius;
  const auto count = static_cast<std::ptrdiff_t>(n);
#pragma omp parallel for schedule(dynamic, 256)
  for (std::ptrdiff_t s = 0; s < count; ++s) {
    const ChartCell& polygon = chart[static_cast<std::size_t>(s)];
    if (polygon.empty()) continue;
    ChartCell disk_cell;
    const std::size_t m = polygon.size();
    bool contains_center = true;
    for (std::size_t k = 0; k < m; ++k) {
      const Vec2& a = polygon.vertices[k];
      const Vec2& b = polygon.vertices[(k + 1) % m];
      if (cross2(b - a, -a) < 0) contains_center = false;
      const Vec2 d = b - a;
      const double qa = d.squaredNorm(), qb = a.dot(d), qc = a.squaredNorm() - radius2;
      if (qa == 0) {
        if (qc <= 0) {
          disk_cell.vertices.push_back(a);
          disk_cell.neighbors.push_back(polygon.neighbors[k]);
        }
        continue;
      }
      const double discriminant = qb * qb - qa * qc;
      if (discriminant <= 0) continue;
      const double root = std::sqrt(discriminant);
      double t0 = (-qb - root) / qa, t1 = (-qb + root) / qa;
      if (t0 < 1e-13) t0 = 0;
      if (t1 > 1 - 1e-13) t1 = 1;
      if (!(t0 < t1) || t1 <= 0 || t0 >= 1) continue;
      disk_cell.vertices.push_back(t0 == 0 ? a : Vec2(a + t0 * d));
      disk_cell.neighbors.push_back(polygon.neighbors[k]);
      if (t1 < 1) {
        disk_cell.vertices.push_back(a + t1 * d);
        disk_cell.neighbors.push_back(arc_label);
      }
    }
    if (disk_cell.vertices.empty()) {
      if (!contains_center) continue;  // disjoint from the cap
      for (int k = 0; k < 4; ++k) {    // the whole cap
        disk_cell.vertices.emplace_back(radius * std::cos(k * pi / 2), radius * std::sin(k * pi / 2));
        disk_cell.neighbors.push_back(arc_label);
      }
    }
    // Split circle arcs longer than 90°.
    ChartCell split;
    const std::size_t size = disk_cell.size();
    for (std::size_t k = 0; k < size; ++k) {
      const Vec2& a = disk_cell.vertices[k];
      split.vertices.push_back(a);
      split.neighbors.push_back(disk_cell.neighbors[k]);
      if (disk_cell.neighbors[k] != arc_label) continue;
      const Vec2& b = disk_cell.vertices[(k + 1) % size];
      double phi = std::atan2(cross2(a, b), a.dot(b));
      if (phi < -1e-12) phi += 2 * pi;
      const int pieces = static_cast<int>(std::ceil(phi / (pi / 2) - 1e-9));
      const double start = std::atan2(a.y(), a.x());
      for (int piece = 1; piece < pieces; ++piece) {
        const double theta = start + phi * piece / pieces;
        split.vertices.emplace_back(radius * std::cos(theta), radius * std::sin(theta));
        split.neighbors.push_back(arc_label);
      }
    }
    if (split.size() < 3) continue;
    diagram.cells[static_cast<std::size_t>(s)] = to_sphere(split, frame_);
  }
  return diagram;
}

// ---- partial transport ------------------------------------------------------------------

Cell<Sphere::Point> Sphere::cut_by_ball(const Cell<Point>& cell, const Point& site, double weight) const {
  if (cell.empty() || !(weight > 0)) return {};
  // The ball {x : −ln⟨x, p⟩ ≤ w} is the cap ⟨x, p⟩ ≥ e^{−w} of angular radius α = arccos e^{−w} < π/2.
  struct Ball {
    const Sphere& sphere;
    Vec3 p;
    double cos_radius, sin_radius;
    detail::EdgeInBall<Vec3> clip(const Vec3& a, const Vec3& b, int label) const {
      if (sphere.is_circle_arc(label)) {
        // On the cap's circle x(θ) = a rotated by θ about c: ⟨x, p⟩ = K + U cos θ + V sin θ.
        const Vec3& c = sphere.center();
        const double length = arc_angle(a, b, c);
        const Vec3 radial = a - a.dot(c) * c;
        const double k = a.dot(c) * c.dot(p), u = radial.dot(p), v = c.cross(radial).dot(p), r = std::hypot(u, v);
        if (!(r > 0) || !(r + k > cos_radius)) return {};
        if (k - r >= cos_radius) return {true, true, true, a, b};  // the whole circle is in the ball
        double center = std::atan2(v, u);
        const double half = std::acos((cos_radius - k) / r);
        if (center + half < 0) center += 2 * pi;
        return detail::edge_interval(center, half, length, a, b,
                                     [&](double theta) { return rotate_about(a, c, theta); });
      }
      // On the great arc x(θ) = cos θ a + sin θ t, θ ∈ [0, L]: ⟨x, p⟩ = R cos(θ − θ*), inside the
      // cap for |θ − θ*| ≤ arccos(cos α / R).
      const Vec3 normal = a.cross(b - a);
      const double s = normal.norm();
      if (!(s > 0)) return {};
      const double length = std::atan2(s, a.dot(b));
      const Vec3 tangent = (normal / s).cross(a);
      const double u = a.dot(p), v = tangent.dot(p), r = std::hypot(u, v);
      if (!(r > cos_radius)) return {};
      double center = std::atan2(v, u);
      const double half = std::acos(cos_radius / r);
      if (center + half < 0) center += 2 * pi;  // the arc lies within θ ∈ [0, π)
      return detail::edge_interval(center, half, length, a, b,
                                   [&](double theta) { return Vec3(std::cos(theta) * a + std::sin(theta) * tangent); });
    }
    double angle(const Vec3& a, const Vec3& b) const { return ball_arc_angle(a, b, p); }
    Vec3 rotate(const Vec3& a, double theta) const { return rotate_about(a, p, theta); }
    Vec3 boundary_point() const { return cos_radius * p + sin_radius * frame_at(p).col(0); }
    bool contains_site(const Cell<Vec3>& polygon) const {
      for (std::size_t k = 0; k < polygon.size(); ++k)
        if (p.dot(polygon.vertices[k].cross(polygon.vertices[(k + 1) % polygon.size()])) < 0) return false;
      return true;
    }
  };
  const double cos_radius = std::exp(-weight);
  // sin α = √(1 − e^{−2w}) = √(−expm1(−2w)), accurate for small w.
  return detail::cut_cell_by_ball(cell,
                                  Ball{*this, site.normalized(), cos_radius, std::sqrt(-std::expm1(-2 * weight))});
}

Cell<Sphere::Point> Sphere::with_sampled_arcs(const Cell<Point>& cell, const Point& site, int pieces) const {
  const Vec3 p = site.normalized();
  return detail::sample_ball_arcs(
      cell, pieces, [&](const Vec3& a, const Vec3& b) { return ball_arc_angle(a, b, p); },
      [&](const Vec3& a, double angle) { return rotate_about(a, p, angle); });
}

double Sphere::arc_weight(const Cell<Point>& cell, const Point& site) const {
  // |∇c| = tan α on the circle and ds = sin α dφ: each arc gives cos α · φ.
  const Vec3 p = site.normalized();
  double weight = 0;
  for (std::size_t k = 0; k < cell.size(); ++k)
    if (is_ball_arc(cell.neighbors[k])) {
      const Vec3& a = cell.vertices[k];
      weight += a.dot(p) * ball_arc_angle(a, cell.vertices[(k + 1) % cell.size()], p);
    }
  return weight;
}

double Sphere::ball_radius(double weight) {
  return weight > 0 ? std::acos(std::exp(-weight)) : 0;
}

std::pair<double, double> Sphere::cost_range(const Cell<Point>& cell, const Point& site) const {
  // The cost grows with the distance: its extremes are those of ⟨x, p⟩ over the cell, the largest
  // at p itself (inside) or on an edge, the smallest at a vertex or on a cap arc.
  const Vec3 p = site.normalized();
  double nearest = -1, farthest = 2;
  bool inside = true;
  const std::size_t n = cell.size();
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3& a = cell.vertices[k];
    const Vec3& b = cell.vertices[(k + 1) % n];
    if (p.dot(a.cross(b)) < 0) inside = false;
    farthest = std::min(farthest, a.dot(p));
    nearest = std::max(nearest, a.dot(p));
    if (is_circle_arc(cell.neighbors[k])) {
      // Along the cap's circle ⟨x, p⟩ = K + U cos θ + V sin θ (as in validate_sites).
      const double phi = arc_angle(a, b, center_);
      const Vec3 radial = a - a.dot(center_) * center_;
      const double u = radial.dot(p), v = center_.cross(radial).dot(p);
      double theta = std::atan2(v, u);
      if (theta < 0) theta += 2 * pi;
      if (theta <= phi) nearest = std::max(nearest, a.dot(center_) * center_.dot(p) + std::hypot(u, v));
      theta = std::atan2(v, u) + pi;
      if (theta >= 2 * pi) theta -= 2 * pi;
      if (theta <= phi) farthest = std::min(farthest, a.dot(center_) * center_.dot(p) - std::hypot(u, v));
      continue;
    }
    const Vec3 normal = a.cross(b - a);
    const double s = normal.norm();
    if (!(s > 0)) continue;
    const Vec3 tangent = (normal / s).cross(a);
    const double theta = std::atan2(tangent.dot(p), a.dot(p));
    if (theta > 0 && theta < std::atan2(s, a.dot(b))) nearest = std::max(nearest, std::hypot(a.dot(p), tangent.dot(p)));
  }
  auto cost_at = [](double cosine) { return cosine > 0 ? -std::log(cosine) : INFINITY; };
  return {inside ? 0.0 : cost_at(nearest), cost_at(farthest)};
}

// ---- integrals -------------------------------------------------------------------------

CellIntegrals<Sphere::Point> Sphere::integrate(const Cell<Point>& cell, const Point& site, bool with_cost) const {
  CellIntegrals<Point> result;
  const std::size_t n = cell.size();
  if (n < 3) return result;
  const Vec3 p = site.normalized();
  const Vec3& x0 = cell.vertices[0];
  double area = 0;
  Vec3 moment = Vec3::Zero();
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3& a = cell.vertices[k];
    const Vec3& b = cell.vertices[(k + 1) % n];
    if (k >= 1 && k + 1 < n) area += triangle_area(x0, a, b);
    const bool ball_arc = is_ball_arc(cell.neighbors[k]);
    if (ball_arc || is_circle_arc(cell.neighbors[k])) {
      // The segment between the circle arc and the great arc ab: sector minus triangle; its
      // first moment from the arc's inward conormal (c − cos α x)/sin α (math.md §2 extended).
      // The cap's circle, or the site's ball (partial transport), of angular radius α.
      const Vec3& c = ball_arc ? p : center_;
      const double phi = ball_arc ? ball_arc_angle(a, b, c) : arc_angle(a, b, c);
      const double sin_a = ball_arc ? a.cross(c).norm() : std::sin(angle_);
      const double cos_a = ball_arc ? a.dot(c) : std::cos(angle_);
      // 1 − cos α = sin²α / (1 + cos α) for the balls, without cancellation when they are small.
      const double sin_half = std::sin(angle_ / 2);
      const double one_minus_cos = ball_arc ? sin_a * sin_a / (1 + cos_a) : 2 * sin_half * sin_half;
      area += phi * one_minus_cos - triangle_area(c, a, b);
      moment += 0.5 * (phi * sin_a * sin_a * c - cos_a * c.cross(a - b));
    } else {
      // ½ L n_in with n_in = a × b / |a × b| for a counter-clockwise edge.
      const Vec3 normal = a.cross(b - a);
      const double s = normal.norm();
      if (s > 0) moment += (0.5 * small_angle_atan2(s, a.dot(b)) / s) * normal;
    }
  }
  result.mass = area;
  result.first_moment = moment;
  if (!with_cost) return result;  // the cost quadrature is most of this function's time
  if (const auto cost = small_cell_cost(cell, p)) {
    result.cost = *cost;
    return result;
  }
  double cost = 0;
  for_each_node(
      *this, cell, cost_order, [&](const Vec3& x, double w) { cost += w * log_cost(x, p); }, &p);
  result.cost = cost;
  return result;
}

CellIntegrals<Sphere::Point> Sphere::integrate(const Cell<Point>& cell, const Point& site,
                                               const ScalarField<Point>& rho, int order, bool with_cost) const {
  CellIntegrals<Point> result;
  if (cell.size() < 3) return result;
  const Vec3 p = site.normalized();
  for_each_node(
      *this, cell, [order](double) { return order; },
      [&](const Vec3& x, double w) {
        const double m = w * rho(x);
        result.mass += m;
        result.first_moment += m * x;
        if (with_cost) result.cost += m * log_cost(x, p);
      });
  return result;
}

double Sphere::facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i, const Point& site_j,
                            double weight_j) const {
  const double offset = height_offset(std::max(weight_i, weight_j));  // the ratio below is scale-free
  const Vec3 qi = std::exp(weight_i - offset) * site_i.normalized();
  const double gap = (qi - std::exp(weight_j - offset) * site_j.normalized()).norm();
  const Vec3 normal = a.cross(b - a);
  const double s = normal.norm();
  if (s == 0 || gap == 0) return 0;
  // ∫_arc x ds = (b − a) × n̂ (math.md §2).
  return qi.dot((b - a).cross(normal / s)) / gap;
}

double Sphere::facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i, const Point& site_j,
                            double weight_j, const ScalarField<Point>& rho, int order) const {
  const double offset = height_offset(std::max(weight_i, weight_j));  // the ratio below is scale-free
  const Vec3 qi = std::exp(weight_i - offset) * site_i.normalized();
  const double gap = (qi - std::exp(weight_j - offset) * site_j.normalized()).norm();
  const Vec3 normal = a.cross(b - a);
  const double s = normal.norm();
  if (s == 0 || gap == 0) return 0;
  const double length = std::atan2(s, a.dot(b));
  const Vec3 tangent = (normal / s).cross(a);  // unit tangent at a, towards b
  double integral = 0;
  for (const auto& node : gauss_legendre(order)) {
    const double theta = node.x * length;
    const Vec3 x = std::cos(theta) * a + std::sin(theta) * tangent;
    integral += node.weight * rho(x) * x.dot(qi);
  }
  return integral * length / gap;
}

std::vector<Sphere::Point> Sphere::edge_points(const Cell<Point>& cell, std::size_t k, int count) const {
  const Vec3& a = cell.vertices[k];
  const Vec3& b = cell.vertices[(k + 1) % cell.size()];
  std::vector<Point> points;
  count = std::max(count, 2);
  if (is_circle_arc(cell.neighbors[k])) {
    const double phi = arc_angle(a, b, center_);
    for (int m = 0; m < count; ++m) points.push_back(rotate_about(a, center_, phi * m / (count - 1)));
  } else {
    const Vec3 normal = a.cross(b - a);
    const double s = normal.norm();
    if (s == 0) return {a, b};
    const double length = std::atan2(s, a.dot(b));
    const Vec3 tangent = (normal / s).cross(a);
    for (int m = 0; m < count; ++m) {
      const double theta = length * m / (count - 1);
      points.push_back(std::cos(theta) * a + std::sin(theta) * tangent);
    }
  }
  return points;
}

std::vector<Sphere::Point> Sphere::uniform_samples(std::size_t count, std::uint64_t seed) {
  std::mt19937_64 random(seed);
  std::normal_distribution<double> normal(0, 1);
  std::vector<Point> samples(count);
  for (auto& s : samples) {
    do s = Point(normal(random), normal(random), normal(random));
    while (s.norm() < 1e-6);
    s.normalize();
  }
  return samples;
}

Sphere::Builder Sphere::builder_from_name(std::string_view name) {
  if (name == "automatic") return Builder::automatic;
  if (name == "clipping") return Builder::clipping;
  if (name == "hull") return Builder::hull;
  throw InputError("builder", "must be \"automatic\", \"clipping\" or \"hull\", got \"" + std::string(name) + "\"");
}

}  // namespace sdot
