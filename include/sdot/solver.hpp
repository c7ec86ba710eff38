#pragma once
/// \file solver.hpp
/// The damped-Newton driver shared by every geometry (Kitagawa–Mérigot–Thibert, math.md §3).
///
///     sdot::Plane plane;                                  // unit square, uniform density
///     auto result = sdot::solve(plane, sdot::UniformDensity{}, sites, masses);
///     if (!result.summary.converged()) std::cerr << result.summary.message;

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "sdot/density.hpp"
#include "sdot/diagram.hpp"
#include "sdot/error.hpp"
#include "sdot/geometry.hpp"
#include "sdot/linear_solver.hpp"
#include "sdot/options.hpp"
#include "sdot/partial.hpp"

/// Semi-discrete optimal transport on the plane, the sphere and the hyperbolic plane: sdot::solve
/// and what it is built from (geometries, densities, linear solvers, the cell builder).
namespace sdot {

/// The solution of a semi-discrete transport problem.
template <class Point>
struct Result {
  Eigen::VectorXd weights;        ///< w_i (mean zero); cells argmin_i c(x, y_i) − w_i
  Eigen::VectorXd masses;         ///< μ(W_i) at `weights`
  Eigen::VectorXd target_masses;  ///< ν_i after rescaling (see Summary::mass_scale)
  std::vector<Point> centroids;   ///< centroid of each cell (the site itself for an empty cell)
  double transport_cost = 0;      ///< Σ_i ∫_{W_i} c(x, y_i) dμ (NaN if Options::compute_transport_cost is false)
  Diagram<Point> diagram;         ///< the cells at `weights`
  /// Partial transport only (Options::partial): the radius c⁻¹(w_i) of each site's ball; else empty.
  Eigen::VectorXd ball_radii;
  Summary summary;  ///< how the solve ended, the final errors, history and timings

  /// Neighbour lists of the cells.
  [[nodiscard]] std::vector<std::vector<int>> adjacency() const { return sdot::adjacency(diagram); }
};

/// Cells, their integrals and the Hessian of E at one set of weights.
template <class Point>
struct Evaluation {
  Diagram<Point> diagram;                       ///< the cells at the weights
  std::vector<CellIntegrals<Point>> integrals;  ///< per cell (zero for an empty cell)
  Eigen::VectorXd masses;                       ///< μ(W_i), the integrals' masses
  /// Off-diagonal Hessian weights ∫_Γij ρ/|∇(c_i − c_j)| for i < j (summed per pair on assembly),
  /// by increasing i and, for one i, in the order of its cell's edges: the same at every call.
  /// Empty unless asked for (`with_hessian`).
  std::vector<Eigen::Triplet<double>> facet_weights;
  /// Partial transport with `with_hessian`: per cell, ∫ ρ / |∇c_i| over its ball arcs (the arcs'
  /// term of the Hessian's diagonal); else empty.
  Eigen::VectorXd arc_weights;
};

/// Builds the diagram and integrates every cell and (optionally) every facet; `with_cost` false
/// leaves the cells' transport costs at 0 (the Newton iterations do not need them);
/// `stop_at_empty_cell` (for line searches, which reject steps that empty a cell) lets a geometry
/// that supports it stop building at the first empty cell and leave other cells empty too;
/// `partial` cuts every cell by its site's ball (a PartialGeometry and ρ ≡ 1 only).
template <Geometry G, Density<G> D>
Evaluation<typename G::Point> evaluate(const G& geometry, const D& density, std::span<const typename G::Point> sites,
                                       const Eigen::VectorXd& weights, bool with_hessian, Timings* timings = nullptr,
                                       bool with_cost = true, bool stop_at_empty_cell = false, bool partial = false);

/// Solves the semi-discrete transport problem from `density` on the geometry's source domain
/// to the Diracs Σ ν_i δ_{y_i}: finds weights whose cells have masses ν.
/// Throws InputError for invalid input (NaN, duplicate sites, non-positive masses, bad options,
/// initial weights that leave a cell empty). Non-convergence is reported in Result::summary.
template <Geometry G, Density<G> D>
Result<typename G::Point> solve(const G& geometry, const D& density, std::span<const typename G::Point> sites,
                                const Eigen::VectorXd& target_masses, const Options& options = {},
                                std::optional<Eigen::VectorXd> initial_weights = std::nullopt);

/// Same, with a linear solver type of your choice (any model of LinearSolver).
template <LinearSolver S, Geometry G, Density<G> D>
Result<typename G::Point> solve_with(const G& geometry, const D& density, std::span<const typename G::Point> sites,
                                     const Eigen::VectorXd& target_masses, const Options& options = {},
                                     std::optional<Eigen::VectorXd> initial_weights = std::nullopt);

/// Equal masses summing to `total`.
inline Eigen::VectorXd equal_masses(std::size_t count, double total = 1) {
  return Eigen::VectorXd::Constant(static_cast<Eigen::Index>(count), total / static_cast<double>(count));
}

}  // namespace sdot

#include "sdot/detail/solver_impl.hpp"
