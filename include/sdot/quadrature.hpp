#pragma once
/// \file quadrature.hpp
/// Quadrature rules shared by the geometries: Gauss–Legendre on [0, 1] and the collapsed
/// (Duffy) Gauss rule on the reference triangle {s, t ≥ 0, s + t ≤ 1}.

#include <vector>

namespace sdot {

/// A node of a rule on [0, 1]: ∫₀¹ f ≈ Σ weight·f(x).
struct QuadratureNode1 {
  double x;       ///< in [0, 1]
  double weight;  ///< weights sum to 1
};

/// A node of a rule on the reference triangle: ∫ f ≈ Σ weight·f(s, t); for a triangle abc, the
/// point is a + s(b − a) + t(c − a) and the weights scale by twice its area.
struct QuadratureNode2 {
  ///@{
  /// Coordinates in the reference triangle (s, t ≥ 0, s + t ≤ 1): point = a + s(b − a) + t(c − a).
  double s, t;
  ///@}
  double weight;  ///< weights sum to 1/2, the reference triangle's area
};

/// Gauss–Legendre rule with `order` points on [0, 1] (exact for degree 2·order − 1).
/// Cached per order; thread-safe. Throws InputError for order < 1 or > 64.
const std::vector<QuadratureNode1>& gauss_legendre(int order);

/// Collapsed Gauss rule with order² points on the reference triangle
/// (exact for polynomials of degree 2·order − 2).
/// Cached per order; thread-safe. Throws InputError for order < 1 or > 64.
const std::vector<QuadratureNode2>& triangle_rule(int order);

}  // namespace sdot
