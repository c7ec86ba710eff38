#include "sdot/geometries/plane.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "sdot/error.hpp"
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
  for (std::size_t i = 0; i < sites.size(); ++i)
    if (!sites[i].allFinite()) throw InputError(indexed("sites", i), "coordinate is not finite");
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
  diagram.cells =
      build_power_diagram(centers, power_weights, ConvexPolygon(std::move(shifted)), {}, stop_at_empty_cell);
  for (auto& cell : diagram.cells)
    for (auto& v : cell.vertices) v += origin;
  return diagram;
}

CellIntegrals<Plane::Point> Plane::integrate(const Cell<Point>& cell, const Point& site, bool) const {
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
