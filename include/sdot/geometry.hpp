#pragma once
/// \file geometry.hpp
/// The `Geometry` concept: what a space must supply for the shared solver.
///
/// Conventions (math.md §0), the same in every geometry: the Laguerre cell of site i is
/// W_i(w) = {x : c(x, y_i) − w_i ≤ c(x, y_j) − w_j ∀j}; the solver minimises the convex
/// E(w) = −∫ min_i [c(x, y_i) − w_i] dμ − Σ ν_i w_i, whose gradient is μ(W_i) − ν_i and whose
/// Hessian is H_ij = −∫_{Γ_ij} ρ / |∇_x(c_i − c_j)| ds (i ≠ j), H_ii = −Σ_{j≠i} H_ij.

#include <Eigen/Core>
#include <concepts>
#include <span>
#include <string_view>

#include "sdot/density.hpp"
#include "sdot/diagram.hpp"

namespace sdot {

/// A geometry (a model of this concept) supplies:
/// - `Point`: an Eigen fixed-size vector type for sites, cell vertices and first moments
///   (R² for the plane; the embedding in R³ for the sphere and the hyperboloid);
/// - `name()`: its name in files and on the command line;
/// - `cost(x, y)`: the transport cost c(x, y);
/// - `validate_sites(sites)`: throws InputError naming the site for NaN, duplicates, …;
/// - `default_weights(sites)`: a start at which every cell is non-empty (KMT needs that);
/// - `build_diagram(sites, weights)`: the Laguerre diagram over the source domain; cells are
///   convex polygons whose edges name the neighbour site (or a domain boundary label);
/// - `integrate(cell, site, with_cost)`: exact mass, first moment and (when `with_cost`) the
///   transport cost of the cell for ρ ≡ 1;
/// - `integrate(cell, site, rho, order, with_cost)`: the same for a function ρ, by quadrature;
/// - `facet_weight(a, b, y_i, w_i, y_j, w_j)`: ∫_{[a,b]} 1 / |∇_x(c_i − c_j)| ds, exact;
/// - `facet_weight(a, b, y_i, w_i, y_j, w_j, rho, order)`: ∫ ρ / |∇_x(c_i − c_j)| ds;
/// - `centroid(integrals)`: the (intrinsic) centroid of a cell from its integrals.
template <class G>
concept Geometry = requires(const G& geometry, const typename G::Point& point, std::span<const typename G::Point> sites,
                            const Eigen::VectorXd& weights, const Cell<typename G::Point>& cell,
                            const ScalarField<typename G::Point>& rho, int order, double weight,
                            const CellIntegrals<typename G::Point>& integrals) {
  { G::name() } -> std::convertible_to<std::string_view>;
  { geometry.cost(point, point) } -> std::convertible_to<double>;
  geometry.validate_sites(sites);
  { geometry.default_weights(sites) } -> std::convertible_to<Eigen::VectorXd>;
  { geometry.build_diagram(sites, weights) } -> std::same_as<Diagram<typename G::Point>>;
  { geometry.integrate(cell, point, true) } -> std::same_as<CellIntegrals<typename G::Point>>;
  { geometry.integrate(cell, point, rho, order, true) } -> std::same_as<CellIntegrals<typename G::Point>>;
  { geometry.facet_weight(point, point, point, weight, point, weight) } -> std::convertible_to<double>;
  { geometry.facet_weight(point, point, point, weight, point, weight, rho, order) } -> std::convertible_to<double>;
  { geometry.centroid(integrals) } -> std::convertible_to<typename G::Point>;
};

}  // namespace sdot
