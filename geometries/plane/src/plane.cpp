#include "sdot/geometries/plane.hpp"

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
double cross(const Vec2& a, const Vec2& b) {
  return a.x() * b.y() - a.y() * b.x();
}
}  // namespace

Plane::Plane() : domain_(ConvexPolygon::rectangle(0, 0, 1, 1)) {
  set_chart();
}
Plane::Plane(ConvexPolygon domain) : domain_(std::move(domain)) {
  set_chart();
}

void Plane::set_chart() {
  chart_origin_ = domain_.centroid();
  chart_scale_ = 0;
  for (const auto& v : domain_.vertices()) chart_scale_ = std::max(chart_scale_, (v - chart_origin_).norm());
  if (!(chart_scale_ > 0)) chart_scale_ = 1;
}

void Plane::validate_sites(std::span<const Point> sites) const {
  // Farther than this, squared distances to the domain overflow, and the cells keep no digit.
  constexpr double max_radii = 1e100;
  for (std::size_t i = 0; i < sites.size(); ++i) {
    if (!sites[i].allFinite()) throw InputError(indexed("sites", i), "coordinate is not finite");
    if (!((sites[i] - chart_origin_).cwiseAbs().maxCoeff() <= max_radii * chart_scale_))
      throw InputError(indexed("sites", i), "is more than 1e100 domain radii from the domain's centre");
  }
  std::vector<std::size_t> order(sites.size());
  std::iota(order.begin(), order.end(), 0);
  auto less = [&](std::size_t a, std::size_t b) {
    return sites[a].x() < sites[b].x() || (sites[a].x() == sites[b].x() && sites[a].y() < sites[b].y());
  };
  std::sort(order.begin(), order.end(), less);
  for (std::size_t k = 1; k < order.size(); ++k)
    if (sites[order[k]] == sites[order[k - 1]]) {
      const auto [first, second] = std::minmax(order[k], order[k - 1]);
      throw InputError(indexed("sites", second), "duplicate of sites[" + std::to_string(first) + "]");
    }
}

Eigen::VectorXd Plane::default_weights(std::span<const Point> sites) const {
  const Vec2 center = domain_.centroid();
  const auto& boundary = domain_.vertices();
  double t = 1;
  for (const auto& site : sites) {
    if (domain_.contains(site)) continue;  // only sites outside the domain need shrinking
    const Vec2 direction = site - center;
    for (std::size_t k = 0; k < boundary.size(); ++k) {
      const Vec2& a = boundary[k];
      const Vec2& b = boundary[(k + 1) % boundary.size()];
      // Inside means cross(b − a, x − a) ≥ 0; along the ray it is inside0 + s·rate.
      const double inside0 = cross(b - a, center - a);
      const double rate = cross(b - a, direction);
      if (rate < 0) t = std::min(t, 0.99 * inside0 / -rate);
    }
  }
  Eigen::VectorXd weights(static_cast<Eigen::Index>(sites.size()));
  for (std::size_t i = 0; i < sites.size(); ++i)
    weights[static_cast<Eigen::Index>(i)] = (1 - t) * (sites[i] - center).squaredNorm() / 2;
  return weights;
}

Diagram<Plane::Point> Plane::build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights) const {
  return build_diagram(sites, weights, false);
}

Diagram<Plane::Point> Plane::build_diagram(std::span<const Point> sites, const Eigen::VectorXd& weights,
                                           bool stop_at_empty_cell) const {
  // Power form relative to the domain's centroid o: centres y_i − o and power weights 2ψ_i
  // (½|x − y_i|² − ψ_i = ½(|x − y_i|² − 2ψ_i)), accurate whatever the coordinates' magnitude.
  const Vec2 origin = domain_.centroid();
  std::vector<Vec2> centers(sites.size());
  std::vector<double> power_weights(sites.size());
  for (std::size_t i = 0; i < sites.size(); ++i) {
    centers[i] = sites[i] - origin;
    power_weights[i] = 2 * weights[static_cast<Eigen::Index>(i)];
  }
  std::vector<Vec2> shifted = domain_.vertices();
  for (auto& v : shifted) v -= origin;
  Diagram<Point> diagram;
  diagram.cells = build_power_diagram(centers, power_weights, ConvexPolygon(std::move(shifted)), {}, stop_at_empty_cell,
                                      PowerDiagramMethod::automatic, centers.size(), warm_start_.get());
  for (auto& cell : diagram.cells)
    for (auto& v : cell.vertices) v += origin;
  return diagram;
}

namespace {
/// The angle in [0, 2π) from u to v, counter-clockwise.
double turn_angle(const Vec2& u, const Vec2& v) {
  const double angle = std::atan2(cross(u, v), u.dot(v));
  return angle < 0 ? angle + 2 * std::numbers::pi : angle;
}

/// Integrals of a cell with ball arcs: a fan from the site of triangles (site, a, b) for straight
/// edges and circular sectors for arcs, all signed, so the site may lie outside the cell.
CellIntegrals<Vec2> integrate_with_arcs(const Cell<Vec2>& cell, const Vec2& site) {
  double area = 0, second = 0;
  Vec2 moment = Vec2::Zero();  // about the site
  const std::size_t n = cell.size();
  for (std::size_t k = 0; k < n; ++k) {
    const Vec2 u = cell.vertices[k] - site, v = cell.vertices[(k + 1) % n] - site;
    if (is_ball_arc(cell.neighbors[k])) {
      const double r2 = (u.squaredNorm() + v.squaredNorm()) / 2;
      const double angle = turn_angle(u, v);
      area += r2 * angle / 2;
      // ∫ over the sector of (x − y) = r³/3 ∫ (cos φ, sin φ) dφ = r³/3 · rot₋₉₀(u₁ − u₀) with u unit.
      const Vec2 d = (v - u) * (r2 / 3);
      moment += Vec2(d.y(), -d.x());
      second += r2 * r2 * angle / 4;
    } else {
      const double c = cross(u, v);
      area += c / 2;
      moment += c / 6 * (u + v);
      second += c / 12 * (u.squaredNorm() + u.dot(v) + v.squaredNorm());
    }
  }
  CellIntegrals<Vec2> result;
  result.mass = area;
  result.first_moment = area * site + moment;
  result.cost = second / 2;
  return result;
}
}  // namespace

Cell<Plane::Point> Plane::cut_by_ball(const Cell<Point>& cell, const Point& site, double weight) const {
  if (cell.empty() || !(weight > 0)) return {};
  const double radius = ball_radius(weight);
  struct Ball {
    Vec2 site;
    double radius;
    detail::EdgeInBall<Vec2> clip(const Vec2& a, const Vec2& b, int) const {
      const Vec2 d = b - a;
      const double length = d.norm();
      if (!(length > 0)) return {};
      const Vec2 direction = d / length;
      const double along = (site - a).dot(direction), across = cross(direction, site - a);
      const double half = radius * radius - across * across;
      return detail::edge_interval(along, half > 0 ? std::sqrt(half) : 0.0, length, a, b,
                                   [&](double s) { return Vec2(a + s * direction); });
    }
    double angle(const Vec2& p, const Vec2& q) const { return turn_angle(p - site, q - site); }
    Vec2 rotate(const Vec2& p, double angle) const {
      const Vec2 u = p - site;
      const double c = std::cos(angle), s = std::sin(angle);
      return site + Vec2(c * u.x() - s * u.y(), s * u.x() + c * u.y());
    }
    Vec2 boundary_point() const { return site + Vec2(radius, 0); }
    bool contains_site(const Cell<Vec2>& polygon) const {
      for (std::size_t k = 0; k < polygon.size(); ++k) {
        const Vec2& a = polygon.vertices[k];
        if (cross(polygon.vertices[(k + 1) % polygon.size()] - a, site - a) < 0) return false;
      }
      return true;
    }
  };
  return detail::cut_cell_by_ball(cell, Ball{site, radius});
}

Cell<Plane::Point> Plane::with_sampled_arcs(const Cell<Point>& cell, const Point& site, int pieces) const {
  return detail::sample_ball_arcs(
      cell, pieces, [&](const Vec2& p, const Vec2& q) { return turn_angle(p - site, q - site); },
      [&](const Vec2& p, double angle) {
        const Vec2 u = p - site;
        const double c = std::cos(angle), s = std::sin(angle);
        return Vec2(site + Vec2(c * u.x() - s * u.y(), s * u.x() + c * u.y()));
      });
}

double Plane::arc_weight(const Cell<Point>& cell, const Point& site) const {
  double angle = 0;
  for (std::size_t k = 0; k < cell.size(); ++k)
    if (is_ball_arc(cell.neighbors[k]))
      angle += turn_angle(cell.vertices[k] - site, cell.vertices[(k + 1) % cell.size()] - site);
  return angle;
}

std::pair<double, double> Plane::cost_range(const Cell<Point>& cell, const Point& site) const {
  double nearest = INFINITY, farthest = 0;
  bool inside = true;
  for (std::size_t k = 0; k < cell.size(); ++k) {
    const Vec2& a = cell.vertices[k];
    const Vec2 d = cell.vertices[(k + 1) % cell.size()] - a;
    if (cross(d, site - a) < 0) inside = false;
    const double t = d.squaredNorm() > 0 ? std::clamp((site - a).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
    nearest = std::min(nearest, cost(a + t * d, site));
    farthest = std::max(farthest, cost(a, site));
  }
  return {inside ? 0.0 : nearest, farthest};
}

CellIntegrals<Plane::Point> Plane::integrate(const Cell<Point>& cell, const Point& site, bool) const {
  if (std::any_of(cell.neighbors.begin(), cell.neighbors.end(), is_ball_arc)) return integrate_with_arcs(cell, site);
  // The cost is a by-product of the moments here, so it is always computed.
  // Area, first and second moments about the first vertex o, then shifted to the site.
  const Vec2 o = cell.vertices[0];
  double twice_area = 0, second = 0;
  Vec2 moment = Vec2::Zero();
  for (std::size_t k = 1; k + 1 < cell.size(); ++k) {
    const Vec2 u = cell.vertices[k] - o, v = cell.vertices[k + 1] - o;
    const double c = cross(u, v);
    twice_area += c;
    moment += c * (u + v);
    second += c * (u.squaredNorm() + u.dot(v) + v.squaredNorm());
  }
  CellIntegrals<Point> result;
  result.mass = twice_area / 2;
  moment /= 6;
  second /= 12;
  const Vec2 offset = o - site;
  result.first_moment = result.mass * o + moment;
  result.cost = (second + 2 * offset.dot(moment) + result.mass * offset.squaredNorm()) / 2;
  return result;
}

CellIntegrals<Plane::Point> Plane::integrate(const Cell<Point>& cell, const Point& site, const ScalarField<Point>& rho,
                                             int order, bool with_cost) const {
  const auto& rule = triangle_rule(order);
  CellIntegrals<Point> result;
  const Vec2& a = cell.vertices[0];
  for (std::size_t k = 1; k + 1 < cell.size(); ++k) {
    const Vec2 ab = cell.vertices[k] - a, ac = cell.vertices[k + 1] - a;
    const double jacobian = cross(ab, ac);
    for (const auto& node : rule) {
      const Vec2 x = a + node.s * ab + node.t * ac;
      const double mass = node.weight * jacobian * rho(x);
      result.mass += mass;
      result.first_moment += mass * x;
      if (with_cost) result.cost += mass * cost(x, site);
    }
  }
  return result;
}

double Plane::facet_weight(const Point& a, const Point& b, const Point& site_i, double, const Point& site_j,
                           double) const {
  return (b - a).norm() / (site_i - site_j).norm();
}

double Plane::facet_weight(const Point& a, const Point& b, const Point& site_i, double, const Point& site_j, double,
                           const ScalarField<Point>& rho, int order) const {
  double integral = 0;
  for (const auto& node : gauss_legendre(order)) integral += node.weight * rho(a + node.x * (b - a));
  return integral * (b - a).norm() / (site_i - site_j).norm();
}

std::vector<Plane::Point> Plane::uniform_samples(std::size_t count, std::uint64_t seed) const {
  Eigen::AlignedBox2d box;
  for (const auto& v : domain_.vertices()) box.extend(v);
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> uniform(0, 1);
  std::vector<Point> samples;
  samples.reserve(count);
  while (samples.size() < count) {
    const double x = uniform(random), y = uniform(random);
    const Point p(box.min().x() + (box.max().x() - box.min().x()) * x,
                  box.min().y() + (box.max().y() - box.min().y()) * y);
    if (domain_.contains(p)) samples.push_back(p);
  }
  return samples;
}

}  // namespace sdot
