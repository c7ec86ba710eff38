#pragma once
/// \file quadrature.hpp
/// Quadrature rules shared by the geometries: Gauss–Legendre on [0, 1] and the collapsed
/// (Duffy) Gauss rule on the reference triangle {s, t ≥ 0, s + t ≤ 1}.

#include <vector>

namespace sdot {

struct QuadratureNode1 {
  double x;       ///< in [0, 1]
  double weight;  ///< weights sum to 1
};

struct QuadratureNode2 {
  double s, t;    ///< barycentric-style coordinates: point = a + s(b − a) + t(c − a)
  double weight;  ///< weights sum to 1/2, the reference triangle's area
};

/// Gauss–Legendre rule with `order` points on [0, 1] (exact for degree 2·order − 1).
/// Cached per order; thread-safe. Throws InputError for order < 1 or > 64.
const std::vector<QuadratureNode1>& gauss_legendre(int order);

/// Collapsed Gauss rule with order² points on the reference triangle
/// (exact for polynomials of degree 2·order − 2).
const std::vector<QuadratureNode2>& triangle_rule(int order);

}  // namespace sdot
