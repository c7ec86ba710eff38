#include "sdot/quadrature.hpp"

#include <cmath>
#include <map>
#include <mutex>
#include <numbers>

#include "sdot/error.hpp"

namespace sdot {
namespace {

void check_order(int order) {
  if (order < 1 || order > 64) throw InputError("quadrature_order", "must be in [1, 64], got " + std::to_string(order));
}

std::vector<QuadratureNode1> compute_gauss_legendre(int n) {
  std::vector<QuadratureNode1> nodes(n);
  for (int i = 0; i < n; ++i) {
    // Newton iteration on P_n from the Chebyshev-like initial guess.
    double x = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
    double derivative = 1;
    for (int iteration = 0; iteration < 100; ++iteration) {
      double p0 = 1, p1 = x;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      if (n == 1) p0 = 1, p1 = x;
      derivative = n * (x * p1 - p0) / (x * x - 1);
      const double step = p1 / derivative;
      x -= step;
      if (std::abs(step) < 1e-16) break;
    }
    double p0 = 1, p1 = x;
    for (int k = 2; k <= n; ++k) {
      const double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
      p0 = p1;
      p1 = p2;
    }
    derivative = n * (x * p1 - p0) / (x * x - 1);
    const double weight = 2 / ((1 - x * x) * derivative * derivative);
    nodes[i] = {(1 - x) / 2, weight / 2};
  }
  return nodes;
}

}  // namespace

const std::vector<QuadratureNode1>& gauss_legendre(int order) {
  check_order(order);
  static std::mutex mutex;
  static std::map<int, std::vector<QuadratureNode1>> cache;
  std::lock_guard lock(mutex);
  auto it = cache.find(order);
  if (it == cache.end()) it = cache.emplace(order, compute_gauss_legendre(order)).first;
  return it->second;
}

const std::vector<QuadratureNode2>& triangle_rule(int order) {
  check_order(order);
  static std::mutex mutex;
  static std::map<int, std::vector<QuadratureNode2>> cache;
  const auto& line = gauss_legendre(order);
  std::lock_guard lock(mutex);
  auto it = cache.find(order);
  if (it == cache.end()) {
    std::vector<QuadratureNode2> nodes;
    nodes.reserve(line.size() * line.size());
    // Duffy map (u, v) ↦ (s, t) = (u(1 − v), uv), Jacobian u.
    for (const auto& a : line)
      for (const auto& b : line) nodes.push_back({a.x * (1 - b.x), a.x * b.x, a.weight * b.weight * a.x});
    it = cache.emplace(order, std::move(nodes)).first;
  }
  return it->second;
}

}  // namespace sdot
