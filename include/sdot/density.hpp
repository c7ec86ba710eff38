#pragma once
/// \file density.hpp
/// Source densities. A density is integrated over a cell (mass, first moment, cost) and along a
/// cell edge (the Hessian weight ∫_Γ ρ / |∇_x(c(·,y_i) − c(·,y_j))| ds) using only the
/// geometry's integration primitives, so every geometry gets every density for free.
///
/// A density describes itself as pieces with a local function: it splits a cell (or an edge)
/// into pieces and hands each piece to the geometry with the local form of ρ — a constant
/// (integrated exactly) or a function (integrated by quadrature). Data-driven densities
/// (piecewise linear on a mesh, images) are further models of `Density`.

#include <concepts>
#include <cstddef>
#include <functional>

#include "sdot/diagram.hpp"

namespace sdot {

/// A scalar function on the points of a geometry.
template <class Point>
using ScalarField = std::function<double(const Point&)>;

/// ρ ≡ 1 with respect to the geometry's own area measure (intrinsic area on S² and H²).
/// Integrated exactly by every geometry.
struct UniformDensity {
  /// Mass, first moment and (unless `with_cost` is false) transport cost of the cell, from the
  /// geometry's exact integrals. `with_cost` false skips the cost (the solver needs it only at
  /// the end).
  template <class G>
  [[nodiscard]] CellIntegrals<typename G::Point> integrate_cell(const G& geometry, const Cell<typename G::Point>& cell,
                                                                const typename G::Point& site,
                                                                bool with_cost = true) const {
    return geometry.integrate(cell, site, with_cost);
  }
  /// The Hessian weight ∫_{[a,b]} 1 / |∇_x(c(·, y_i) − c(·, y_j))| ds of the cell edge from `a`
  /// to `b` between the cells of `site_i` and `site_j` (with their weights), exact.
  template <class G>
  [[nodiscard]] double facet_weight(const G& geometry, const typename G::Point& a, const typename G::Point& b,
                                    const typename G::Point& site_i, double weight_i, const typename G::Point& site_j,
                                    double weight_j) const {
    return geometry.facet_weight(a, b, site_i, weight_i, site_j, weight_j);
  }
};

/// ρ(x) given by a function (ρ ≥ 0, finite), integrated by quadrature: a collapsed Gauss rule
/// with `quadrature_order`² points per triangle of a fan of each cell, and Gauss–Legendre with
/// `quadrature_order` points along each edge. The function is called concurrently from
/// several threads.
template <class Point>
struct FunctionDensity {
  /// ρ at a point of the geometry (≥ 0 and finite on the source domain).
  ScalarField<Point> rho;
  /// The quadrature order n: n² points per fan triangle, n Gauss–Legendre points per edge; in
  /// 1…64 (the quadrature rules throw InputError otherwise).
  int quadrature_order = 8;

  /// Mass, first moment and (unless `with_cost` is false) transport cost of ρ over the cell,
  /// by quadrature.
  template <class G>
  [[nodiscard]] CellIntegrals<Point> integrate_cell(const G& geometry, const Cell<Point>& cell, const Point& site,
                                                    bool with_cost = true) const {
    return geometry.integrate(cell, site, rho, quadrature_order, with_cost);
  }
  /// The Hessian weight ∫_{[a,b]} ρ / |∇_x(c(·, y_i) − c(·, y_j))| ds of the cell edge from `a`
  /// to `b`, by Gauss–Legendre quadrature.
  template <class G>
  [[nodiscard]] double facet_weight(const G& geometry, const Point& a, const Point& b, const Point& site_i,
                                    double weight_i, const Point& site_j, double weight_j) const {
    return geometry.facet_weight(a, b, site_i, weight_i, site_j, weight_j, rho, quadrature_order);
  }
};

/// A source density for geometry G: it integrates a cell and an edge of a cell.
template <class D, class G>
concept Density = requires(const D& density, const G& geometry, const Cell<typename G::Point>& cell,
                           const typename G::Point& point, double weight) {
  { density.integrate_cell(geometry, cell, point, true) } -> std::same_as<CellIntegrals<typename G::Point>>;
  { density.facet_weight(geometry, point, point, point, weight, point, weight) } -> std::convertible_to<double>;
};

}  // namespace sdot
