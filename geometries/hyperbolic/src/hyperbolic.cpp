#include "sdot/geometries/hyperbolic.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <random>

#include "sdot/error.hpp"
#include "sdot/partial.hpp"
#include "sdot/quadrature.hpp"

namespace sdot {
namespace {

using Point = Hyperbolic::Point;

double mink(const Point& a, const Point& b) {
  return Hyperbolic::minkowski(a, b);
}

/// √⟨d, d⟩_M for a spacelike difference d of two hyperboloid points (0 if rounding makes it negative).
double spacelike_norm(const Point& d) {
  return std::sqrt(std::max(0.0, mink(d, d)));
}

/// Hyperbolic length of the geodesic segment [a, b]: 2 asinh(‖b − a‖_M / 2) (stable for short edges).
double length(const Point& a, const Point& b) {
  return 2 * std::asinh(spacelike_norm(b - a) / 2);
}

/// Central projection of a non-zero timelike X (x₃ > 0) onto the hyperboloid.
Point normalize(const Point& x) {
  return x / std::sqrt(-mink(x, x));
}

/// A point of the open disc given in chart coordinates, lifted to the hyperboloid.
Point lift(const Vec2& k) {
  return Point(k.x(), k.y(), 1) / std::sqrt((1 - k.x()) * (1 + k.x()) - k.y() * k.y());
}

/// Visits the quadrature points of the centrally projected flat triangle (a, b, c) of hyperboloid
/// points: visit(x, dA) with x on H² and dA = |det(a, b, c)| / (−⟨X, X⟩_M)^{3/2} · weight.
template <class Visit>
void triangle_quadrature(const Point& a, const Point& b, const Point& c, int order, Visit&& visit) {
  const Point ab = b - a, ac = c - a;
  const double jacobian = std::abs(a.dot(ab.cross(ac)));
  for (const auto& node : triangle_rule(order)) {
    const Point x = a + node.s * ab + node.t * ac;
    const double w = -mink(x, x);
    const double sw = std::sqrt(w);
    visit(Point(x / sw), node.weight * jacobian / (w * sw));
  }
}

/// The order of the collapsed Gauss rule for the cost integrand ln cosh d on a triangle whose
/// longest side is `size` (hyperbolic): chosen so that the relative error stays ≲ 1e−13
/// (measured in the tests against a 40-point rule). Larger triangles are subdivided.
int cost_order(double size) {
  if (size < 0.01) return 3;
  if (size < 0.04) return 4;
  if (size < 0.1) return 5;
  if (size < 0.25) return 7;
  if (size < 0.5) return 9;
  return 12;
}

/// ∫ ln(−⟨x, y⟩_M) dA over the projected triangle (a, b, c), subdividing triangles longer than 1.
double cost_integral(const Point& a, const Point& b, const Point& c, const Point& y) {
  const double size = std::max({spacelike_norm(b - a), spacelike_norm(c - b), spacelike_norm(a - c)});
  if (size > 1) {
    const Point ab = normalize(a + b), bc = normalize(b + c), ca = normalize(c + a);
    return cost_integral(a, ab, ca, y) + cost_integral(ab, b, bc, y) + cost_integral(ca, bc, c, y) +
           cost_integral(ab, bc, ca, y);
  }
  double sum = 0;
  triangle_quadrature(a, b, c, cost_order(size),
                      [&](const Point& x, double da) { sum += da * Hyperbolic::cost(x, y); });
  return sum;
}

/// The tangent part at y of x: x + ⟨x, y⟩_M y (Minkowski-orthogonal to y).
Point tangent_at(const Point& y, const Point& x) {
  return x + mink(x, y) * y;
}

/// The angle in [0, 2π) swept counter-clockwise (in the Klein chart) around y from a to b: in the
/// tangent plane at y, whose orientation det(y, u, v) every proper Lorentz map keeps.
double angle_around(const Point& y, const Point& a, const Point& b) {
  const Point u = tangent_at(y, a), v = tangent_at(y, b);
  const double angle = std::atan2(y.dot(u.cross(v)), mink(u, v));
  return angle < 0 ? angle + 2 * std::numbers::pi : angle;
}

/// a turned by `angle` counter-clockwise around y: cosh r y + cos θ u + sin θ (y ⊠ u), u the tangent
/// part of a and y ⊠ u = J(y × u) the Lorentzian cross product (a quarter turn in the tangent plane).
Point rotate_around(const Point& y, const Point& a, double angle) {
  const Point u = tangent_at(y, a);
  Point turned = y.cross(u);
  turned.z() = -turned.z();
  Point x = -mink(a, y) * y + std::cos(angle) * u + std::sin(angle) * turned;
  x.z() = std::sqrt(1 + x.head<2>().squaredNorm());
  return x;
}

/// The normalised sum of a cell's vertices: a point inside the (convex) cell.
Point inner_point(const std::vector<Point>& vertices) {
  Point sum = Point::Zero();
  for (const auto& v : vertices) sum += v;
  return normalize(sum);
}

}  // namespace

// ---- coordinates -------------------------------------------------------------------------

double Hyperbolic::distance(const Point& a, const Point& b) {
  return length(a, b);
}

Hyperbolic::Point Hyperbolic::from_klein(const Eigen::Vector2d& k, const std::string& field) {
  if (!k.allFinite()) throw InputError(field, "coordinate is not finite");
  const double r2 = k.squaredNorm();
  if (!(r2 < 1))
    throw InputError(field, "Klein point lies on or outside the ideal boundary (|k| = " +
                                std::to_string(std::sqrt(r2)) + ", must be < 1)");
  return lift(k);
}

Hyperbolic::Point Hyperbolic::from_poincare(const Eigen::Vector2d& p, const std::string& field) {
  if (!p.allFinite()) throw InputError(field, "coordinate is not finite");
  const double r2 = p.squaredNorm();
  if (!(r2 < 1))
    throw InputError(field, "Poincare point lies on or outside the ideal boundary (|p| = " +
                                std::to_string(std::sqrt(r2)) + ", must be < 1)");
  const double d = (1 - p.x()) * (1 + p.x()) - p.y() * p.y();
  return Point(2 * p.x(), 2 * p.y(), 1 + r2) / d;
}

namespace {
/// InputError naming `field` unless x is a finite point of the hyperboloid's upper sheet within
/// distance 230 of the origin (x3 ≤ 1e100; farther out the chart's squared norms overflow).
void check_hyperboloid_point(const Hyperbolic::Point& x, const std::string& field) {
  if (!x.allFinite()) throw InputError(field, "coordinate is not finite");
  if (!(x.z() <= 1e100)) throw InputError(field, "is too far from the origin (x3 > 1e100)");
  const double q = mink(x, x);
  if (!(x.z() > 0) || !(std::abs(q + 1) <= 1e-9 * x.squaredNorm()))
    throw InputError(field, "point is not on the hyperboloid's upper sheet (<x,x>_M = " + std::to_string(q) +
                                ", x3 = " + std::to_string(x.z()) + "; need <x,x>_M = -1 and x3 > 0)");
}
}  // namespace

Hyperbolic::Point Hyperbolic::from_hyperboloid(const Point& x, const std::string& field) {
  check_hyperboloid_point(x, field);
  Point p = x;
  p.z() = std::sqrt(1 + x.head<2>().squaredNorm());  // exact re-projection
  return p;
}

Hyperbolic::Point Hyperbolic::from_model(Model model, const Eigen::VectorXd& c, const std::string& field) {
  const Eigen::Index need = model == Model::hyperboloid ? 3 : 2;
  if (c.size() != need)
    throw InputError(field, "expected " + std::to_string(need) + " coordinates, got " + std::to_string(c.size()));
  switch (model) {
    case Model::klein:
      return from_klein(Eigen::Vector2d(c[0], c[1]), field);
    case Model::poincare:
      return from_poincare(Eigen::Vector2d(c[0], c[1]), field);
    case Model::hyperboloid:
    default:
      return from_hyperboloid(Point(c[0], c[1], c[2]), field);
  }
}

Hyperbolic::Point Hyperbolic::polar(double r, double theta) {
  return Point(std::sinh(r) * std::cos(theta), std::sinh(r) * std::sin(theta), std::cosh(r));
}

Eigen::Matrix3d Hyperbolic::boost_to(const Point& center) {
  const Eigen::Vector2d u = center.head<2>();
  const double gamma = center.z();
  Eigen::Matrix3d l;
  l.topLeftCorner<2, 2>() = Eigen::Matrix2d::Identity() + u * u.transpose() / (1 + gamma);
  l.topRightCorner<2, 1>() = u;
  l.bottomLeftCorner<1, 2>() = u.transpose();
  l(2, 2) = gamma;
  return l;
}

Eigen::Matrix3d Hyperbolic::lorentz_inverse(const Eigen::Matrix3d& l) {
  const Eigen::Vector3d j(1, 1, -1);
  return j.asDiagonal() * l.transpose() * j.asDiagonal();
}

// ---- construction ------------------------------------------------------------------------

Hyperbolic::Hyperbolic(std::span<const Point> domain) {
  std::vector<Point> vertices;
  vertices.reserve(domain.size());
  for (std::size_t k = 0; k < domain.size(); ++k) vertices.push_back(from_hyperboloid(domain[k], indexed("domain", k)));
  set_domain(std::move(vertices));
}

void Hyperbolic::set_domain(std::vector<Point> vertices) {
  if (vertices.size() < 3)
    throw InputError("domain", "a polygon needs at least 3 vertices, got " + std::to_string(vertices.size()));
  center_ = inner_point(vertices);
  boost_ = boost_to(center_);
  inverse_boost_ = lorentz_inverse(boost_);
  std::vector<Vec2> chart;
  chart.reserve(vertices.size());
  for (const auto& v : vertices) chart.push_back(to_klein(inverse_boost_ * v));
  chart_domain_ = ConvexPolygon(std::move(chart), "domain");
  domain_.clear();
  for (const auto& k : chart_domain_.vertices()) domain_.push_back(boost_ * lift(k));
}

Hyperbolic Hyperbolic::from_model(Model model, std::span<const Eigen::VectorXd> vertices) {
  std::vector<Point> points;
  points.reserve(vertices.size());
  for (std::size_t k = 0; k < vertices.size(); ++k)
    points.push_back(from_model(model, vertices[k], indexed("domain", k)));
  Hyperbolic h;
  h.set_domain(std::move(points));
  return h;
}

Hyperbolic Hyperbolic::from_klein(std::span<const Eigen::Vector2d> vertices) {
  std::vector<Eigen::VectorXd> v(vertices.begin(), vertices.end());
  return from_model(Model::klein, v);
}

Hyperbolic Hyperbolic::from_poincare(std::span<const Eigen::Vector2d> vertices) {
  std::vector<Eigen::VectorXd> v(vertices.begin(), vertices.end());
  return from_model(Model::poincare, v);
}

Hyperbolic Hyperbolic::regular_polygon(int sides, double radius, const Point& center) {
  if (sides < 3) throw InputError("sides", "a polygon needs at least 3 sides");
  if (!(radius > 0) || !std::isfinite(radius)) throw InputError("radius", "must be a positive finite number");
  const Point c = from_hyperboloid(center, "center");
  const Eigen::Matrix3d l = boost_to(c);
  std::vector<Point> vertices;
  for (int k = 0; k < sides; ++k) vertices.push_back(l * polar(radius, 2 * std::numbers::pi * k / sides));
  Hyperbolic h;
  h.set_domain(std::move(vertices));
  return h;
}

double Hyperbolic::domain_area() const {
  Cell<Point> cell{domain_, std::vector<int>(domain_.size(), -1)};
  return integrate(cell, center_).mass;
}

// ---- the Geometry concept ----------------------------------------------------------------

double Hyperbolic::cost(const Point& x, const Point& y) {
  // ln(−⟨x, y⟩_M) = ln(1 + ½⟨x − y, x − y⟩_M): accurate near the diagonal too.
  return std::log1p(0.5 * std::max(0.0, mink(x - y, x - y)));
}

void Hyperbolic::validate_sites(std::span<const Point> sites) const {
  for (std::size_t i = 0; i < sites.size(); ++i) {
    check_hyperboloid_point(sites[i], indexed("sites", i));
  }
  std::vector<std::size_t> order(sites.size());
  std::iota(order.begin(), order.end(), 0);
  auto less = [&](std::size_t a, std::size_t b) {
    return std::lexicographical_compare(sites[a].data(), sites[a].data() + 3, sites[b].data(), sites[b].data() + 3);
  };
  std::sort(order.begin(), order.end(), less);
  for (std::size_t k = 1; k < order.size(); ++k)
    if (sites[order[k]] == sites[order[k - 1]]) {
      const auto [first, second] = std::minmax(order[k], order[k - 1]);
      throw InputError(indexed("sites", second), "duplicate of sites[" + std::to_string(first) + "]");
    }
}

Eigen::VectorXd Hyperbolic::default_weights(std::span<const Point> sites) const {
  const auto& boundary = chart_domain_.vertices();
  std::vector<Vec2> z(sites.size());
  for (std::size_t i = 0; i < sites.size(); ++i) z[i] = to_klein(inverse_boost_ * sites[i]);
  // Sites strictly inside the domain: h = 0 (the Voronoi diagram) holds each site in its own cell,
  // so every cell is non-empty, and it is much nearer the solution for sites spread over the domain
  // than the τ-scaled start below (uniform sites at 10⁵: max relative mass error 1.9e3 → ~1).
  const bool all_inside = std::all_of(z.begin(), z.end(), [&](const Vec2& p) {
    return chart_domain_.contains(p, -1e-9 * (1 + chart_domain_.radius()));
  });
  if (all_inside) return Eigen::VectorXd::Zero(static_cast<Eigen::Index>(sites.size()));
  double tau = 1;
  for (std::size_t i = 0; i < sites.size(); ++i) {
    const double r = z[i].norm();
    if (!(r > 0)) continue;
    const Vec2 direction = z[i] / r;
    double reach = INFINITY;  // distance from the chart origin to the boundary along `direction`
    for (std::size_t k = 0; k < boundary.size(); ++k) {
      const Vec2& a = boundary[k];
      const Vec2 e = boundary[(k + 1) % boundary.size()] - a;
      const double inside0 = e.x() * (-a.y()) - e.y() * (-a.x());
      const double rate = e.x() * direction.y() - e.y() * direction.x();
      if (rate < 0) reach = std::min(reach, inside0 / -rate);
    }
    const double s = 0.9 * reach;  // |u_i| = 2τr / (1 + τr²) ≤ s
    tau = std::min(tau, s / (r * (2 - s * r)));
  }
  Eigen::VectorXd weights(static_cast<Eigen::Index>(sites.size()));
  for (std::size_t i = 0; i < sites.size(); ++i) {
    const double r2 = z[i].squaredNorm();
    const Point local = inverse_boost_ * sites[i];
    // −½ ln(1 − |z|²) = ln x₃ in the chart frame (exact even far away).
    weights[static_cast<Eigen::Index>(i)] = std::log(local.z()) + std::log1p(-tau * r2);
  }
  return weights;
}

Diagram<Hyperbolic::Point> Hyperbolic::build_diagram(std::span<const Point> sites,
                                                     const Eigen::VectorXd& weights) const {
  return build_diagram(sites, weights, false);
}

Diagram<Hyperbolic::Point> Hyperbolic::build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                                     bool stop_at_empty_cell) const {
  // In the chart frame x = Λx' of the domain's centre: ⟨x, e^{−h}y⟩_M = ⟨x', e^{−h}Λ⁻¹y⟩_M, and
  // the cells are found in the Klein chart k' of x' (math.md §5, "H² numerics").
  // The neighbours: minimising e^{−h_i}⟨(k, 1), y_i⟩ over i picks the faces of the hull of the
  // points P_i = e^{−h_i} y₃ (κ_i, 1) that face the origin, κ_i the Klein point of site i. Those
  // are the upper hull of the lifted points (κ_i, e^{h_i}/y₃): the regular triangulation of the
  // Klein points with power weights |κ_i|² + e^{h_i}/y₃ (docs/hyperbolic.md). Its centres do not
  // move with the weights, so each build starts from the last one's triangulation by flips.
  // The bisectors come from differences of the sites and weights (below), not from the power
  // form, whose weights carry the rounding of |c|², an error that grows like the number of sites
  // relative to the cells' masses (docs/hyperbolic.md, "Precision and the number of sites").
  const std::size_t n = sites.size();
  std::vector<Point> local(n);            // the sites in the chart frame, y₃ re-projected onto the hyperboloid
  std::vector<Eigen::Vector2d> klein(n);  // the sites' Klein points: where their cells are
  for (std::size_t i = 0; i < n; ++i) {
    const Point y = inverse_boost_ * sites[i];
    const double height = std::sqrt(1 + y.head<2>().squaredNorm());
    local[i] = Point(y.x(), y.y(), height);
    klein[i] = y.head<2>() / height;
  }
  std::vector<ChartCell> cells;
  if (has_regular_triangulation()) {
    std::vector<double> lifted(n);
    for (std::size_t i = 0; i < n; ++i)
      lifted[i] = klein[i].squaredNorm() + std::exp(weights[static_cast<Eigen::Index>(i)]) / local[i].z();
    // Cell i is where e^{−h_i}⟨X, y_i⟩ ≥ e^{−h_j}⟨X, y_j⟩ for X = (k, 1), i.e. ⟨X, m⟩_M ≥ 0 with
    // m = e^{h_j − h_i} y_i − y_j = expm1(h_j − h_i) y_i + (y_i − y_j), whose third coordinate
    // y_{i,3} − y_{j,3} = (y_i − y_j)₁₂·(y_i + y_j)₁₂ / (y_{i,3} + y_{j,3}) keeps its digits too. In
    // u = k − κ_i: m₁₂·u + m₁₂·κ_i − m₃ ≥ 0.
    const auto bisector = [&](std::size_t i, std::size_t j) {
      const double rate = std::expm1(weights[static_cast<Eigen::Index>(j)] - weights[static_cast<Eigen::Index>(i)]);
      const Point& yi = local[i];
      const Point& yj = local[j];
      const Eigen::Vector2d difference = yi.head<2>() - yj.head<2>();
      const Eigen::Vector2d normal = rate * yi.head<2>() + difference;
      const double third = rate * yi.z() + difference.dot(yi.head<2>() + yj.head<2>()) / (yi.z() + yj.z());
      return ChartLine{normal, normal.dot(klein[i]) - third};
    };
    cells = build_chart_diagram_with_fixed_centers(klein, lifted, bisector, chart_domain_, stop_at_empty_cell,
                                                   warm_start_.get());
  } else {
    // The envelope of f_i(k) = a'·(k, 1), a' = e^{−h} J Λ⁻¹ y up to x₃' > 0: adding 1 to every a'_z
    // leaves it unchanged and makes the offsets small, a'_z + 1 = −(expm1(−h) y₃' + |y'₁₂|² / (1 + y₃')),
    // computed without cancellation.
    std::vector<Vec3> dual(n);
    for (std::size_t i = 0; i < n; ++i) {
      const double h = weights[static_cast<Eigen::Index>(i)];
      const Point& y = local[i];
      const double horizontal = y.head<2>().squaredNorm();
      dual[i] = Vec3(std::exp(-h) * y.x(), std::exp(-h) * y.y(), -(std::expm1(-h) * y.z() + horizontal / (1 + y.z())));
    }
    cells = build_chart_diagram(dual, chart_domain_, klein, stop_at_empty_cell);
  }
  Diagram<Point> diagram;
  diagram.cells.resize(cells.size());
#pragma omp parallel for schedule(dynamic, 256)
  for (std::size_t i = 0; i < cells.size(); ++i) {
    auto& cell = diagram.cells[i];
    cell.neighbors = cells[i].neighbors;
    cell.vertices.reserve(cells[i].vertices.size());
    for (const auto& k : cells[i].vertices) {
      Point x = boost_ * lift(k);
      x.z() = std::sqrt(1 + x.head<2>().squaredNorm());  // back onto the hyperboloid after rounding
      cell.vertices.push_back(x);
    }
  }
  return diagram;
}

namespace {
/// The hyperbolic area of the triangle (o, a, b), signed: tan(Δ/2) = det(o, a, b) / (1 − ⟨o,a⟩ − ⟨a,b⟩ − ⟨b,o⟩).
double triangle_area(const Point& o, const Point& a, const Point& b) {
  const Point oa = a - o, ob = b - o;
  return 2 * std::atan2(o.dot(oa.cross(ob)), 1 - mink(o, a) - mink(a, b) - mink(b, o));
}
}  // namespace

CellIntegrals<Hyperbolic::Point> Hyperbolic::integrate(const Cell<Point>& cell, const Point& site,
                                                       bool with_cost) const {
  CellIntegrals<Point> result;
  const Point o = inner_point(cell.vertices);
  const std::size_t n = cell.size();
  for (std::size_t k = 0; k < n; ++k) {
    const Point& a = cell.vertices[k];
    const Point& b = cell.vertices[(k + 1) % n];
    result.mass += triangle_area(o, a, b);
    if (with_cost) result.cost += cost_integral(o, a, b, site);
    if (is_ball_arc(cell.neighbors[k])) {
      // The segment between the ball's arc and the chord ab: sector minus the triangle (y, a, b).
      // Sector: area φ(cosh r − 1), cost φ ∫₀ʳ ln cosh s sinh s ds = φ(C ln C − C + 1), C = cosh r.
      // First moment ½ ∫ n_out ds with n_out = sinh r y + cosh r u(θ), ds = sinh r dθ, and
      // ∫ u dθ = tan(φ/2)(u₀ + u₁) over an arc of angle φ (u the unit radial tangents).
      const double phi = angle_around(site, a, b);
      const Point ua = tangent_at(site, a);
      const double cosh_r = -mink(a, site), sinh_r2 = mink(ua, ua);
      result.mass += phi * sinh_r2 / (cosh_r + 1) - triangle_area(site, a, b);
      if (with_cost) result.cost += phi * (cosh_r * std::log(cosh_r) - cosh_r + 1) - cost_integral(site, a, b, site);
      result.first_moment += 0.5 * (phi * sinh_r2 * site + cosh_r * std::tan(phi / 2) * (ua + tangent_at(site, b)));
      continue;
    }
    // First moment: ½ L m_out with m_out = −J(a × b) / sinh L.
    const double l = length(a, b);
    if (l > 0) {
      Point n_ab = a.cross(b - a);
      n_ab.z() = -n_ab.z();
      result.first_moment -= (0.5 * l / std::sinh(l)) * n_ab;
    }
  }
  return result;
}

CellIntegrals<Hyperbolic::Point> Hyperbolic::integrate(const Cell<Point>& cell, const Point& site,
                                                       const ScalarField<Point>& rho, int order, bool with_cost) const {
  CellIntegrals<Point> result;
  const Point& a = cell.vertices[0];
  for (std::size_t k = 1; k + 1 < cell.size(); ++k)
    triangle_quadrature(a, cell.vertices[k], cell.vertices[k + 1], order, [&](const Point& x, double da) {
      const double mass = da * rho(x);
      result.mass += mass;
      result.first_moment += mass * x;
      if (with_cost) result.cost += mass * cost(x, site);
    });
  return result;
}

namespace {
/// ‖y_i − r y_j‖_M with r = e^{h_i − h_j}, i.e. e^{h_i}‖q_i − q_j‖_M, computed without cancellation:
/// ⟨n, n⟩_M = r⟨y_i − y_j, y_i − y_j⟩_M − (1 − r)² (positive whenever the bisector meets H²).
double scaled_normal_norm(const Point& yi, double wi, const Point& yj, double wj) {
  const double r = std::exp(wi - wj);
  return std::sqrt(std::max(0.0, r * mink(yi - yj, yi - yj) - (1 - r) * (1 - r)));
}
}  // namespace

double Hyperbolic::facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                const Point& site_j, double weight_j) const {
  const Point la = inverse_boost_ * a, lb = inverse_boost_ * b, yi = inverse_boost_ * site_i;
  const double l = length(la, lb);
  return std::tanh(l / 2) * -mink(yi, la + lb) / scaled_normal_norm(yi, weight_i, inverse_boost_ * site_j, weight_j);
}

double Hyperbolic::facet_weight(const Point& a, const Point& b, const Point& site_i, double weight_i,
                                const Point& site_j, double weight_j, const ScalarField<Point>& rho, int order) const {
  const Point la = inverse_boost_ * a, lb = inverse_boost_ * b, yi = inverse_boost_ * site_i;
  const double l = length(la, lb);
  if (!(l > 0)) return 0;
  const double sl = std::sinh(l);
  double integral = 0;
  for (const auto& node : gauss_legendre(order)) {
    const double t = node.x * l;
    const Point x = (std::sinh(l - t) * la + std::sinh(t) * lb) / sl;
    integral += node.weight * rho(boost_ * x) * -mink(x, yi);
  }
  return integral * l / scaled_normal_norm(yi, weight_i, inverse_boost_ * site_j, weight_j);
}

// ---- partial transport ------------------------------------------------------------------

Cell<Hyperbolic::Point> Hyperbolic::cut_by_ball(const Cell<Point>& cell, const Point& site, double weight) const {
  if (cell.empty() || !(weight > 0)) return {};
  struct Ball {
    Point y;
    double cosh_radius;
    detail::EdgeInBall<Point> clip(const Point& a, const Point& b, int) const {
      // On the geodesic x(s) = cosh s a + sinh s t, s ∈ [0, L]: −⟨x, y⟩_M = A cosh s + B sinh s
      // = R cosh(s + s₀) with R² = A² − B², tanh s₀ = B/A; inside for |s + s₀| ≤ arccosh(e^w / R).
      const double l = length(a, b);
      if (!(l > 0)) return {};
      const Point t = (b + mink(a, b) * a) / std::sinh(l);  // (b − cosh L a) / sinh L
      const double along = -mink(a, y), across = -mink(t, y);
      const double r = std::sqrt((along - across) * (along + across));
      if (!(cosh_radius > r)) return {};
      return detail::edge_interval(-std::atanh(across / along), std::acosh(cosh_radius / r), l, a, b, [&](double s) {
        Point x = std::cosh(s) * a + std::sinh(s) * t;
        x.z() = std::sqrt(1 + x.head<2>().squaredNorm());
        return x;
      });
    }
    double angle(const Point& a, const Point& b) const { return angle_around(y, a, b); }
    Point rotate(const Point& a, double angle) const { return rotate_around(y, a, angle); }
    Point boundary_point() const {
      const Point u = tangent_at(y, Point::UnitX());
      const double sinh_r = std::sqrt((cosh_radius - 1) * (cosh_radius + 1));
      Point x = cosh_radius * y + (sinh_r / std::sqrt(mink(u, u))) * u;
      x.z() = std::sqrt(1 + x.head<2>().squaredNorm());
      return x;
    }
    bool contains_site(const Cell<Point>& polygon) const {
      for (std::size_t k = 0; k < polygon.size(); ++k)
        if (polygon.vertices[k].cross(polygon.vertices[(k + 1) % polygon.size()]).dot(y) < 0) return false;
      return true;
    }
  };
  return detail::cut_cell_by_ball(cell, Ball{site, std::exp(weight)});
}

Cell<Hyperbolic::Point> Hyperbolic::with_sampled_arcs(const Cell<Point>& cell, const Point& site, int pieces) const {
  return detail::sample_ball_arcs(
      cell, pieces, [&](const Point& a, const Point& b) { return angle_around(site, a, b); },
      [&](const Point& a, double angle) { return rotate_around(site, a, angle); });
}

double Hyperbolic::arc_weight(const Cell<Point>& cell, const Point& site) const {
  // |∇c| = tanh r on the circle and ds = sinh r dθ: each arc gives cosh r · θ.
  double weight = 0;
  for (std::size_t k = 0; k < cell.size(); ++k)
    if (is_ball_arc(cell.neighbors[k])) {
      const Point& a = cell.vertices[k];
      weight += -mink(a, site) * angle_around(site, a, cell.vertices[(k + 1) % cell.size()]);
    }
  return weight;
}

std::pair<double, double> Hyperbolic::cost_range(const Cell<Point>& cell, const Point& site) const {
  double nearest = INFINITY, farthest = 1;  // of −⟨x, y⟩_M = cosh d
  bool inside = true;
  const std::size_t n = cell.size();
  for (std::size_t k = 0; k < n; ++k) {
    const Point& a = cell.vertices[k];
    const Point& b = cell.vertices[(k + 1) % n];
    if (a.cross(b).dot(site) < 0) inside = false;
    nearest = std::min(nearest, -mink(a, site));
    farthest = std::max(farthest, -mink(a, site));
    const double l = length(a, b);
    if (!(l > 0)) continue;
    const Point t = (b + mink(a, b) * a) / std::sinh(l);
    const double along = -mink(a, site), across = -mink(t, site);
    const double s = -std::atanh(across / along);  // where the distance to the site is least
    if (s > 0 && s < l) nearest = std::min(nearest, std::sqrt((along - across) * (along + across)));
  }
  return {inside ? 0.0 : std::log(nearest), std::log(farthest)};
}

Hyperbolic::Point Hyperbolic::centroid(const CellIntegrals<Point>& integrals) const {
  return normalize(integrals.first_moment);
}

std::vector<Hyperbolic::Point> Hyperbolic::uniform_samples(std::size_t count, std::uint64_t seed) const {
  std::mt19937_64 random(seed);
  const double r = chart_domain_.radius();
  const double max_jacobian = std::pow(1 - r * r, -1.5);
  std::uniform_real_distribution<double> uniform(-r, r), unit(0, 1);
  std::vector<Point> samples;
  samples.reserve(count);
  while (samples.size() < count) {
    const Eigen::Vector2d k(uniform(random), uniform(random));
    if (!chart_domain_.contains(k) || unit(random) * max_jacobian > std::pow(1 - k.squaredNorm(), -1.5)) continue;
    samples.push_back(boost_ * from_klein(k));
  }
  return samples;
}

}  // namespace sdot
