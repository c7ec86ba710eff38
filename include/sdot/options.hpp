#pragma once
/// \file options.hpp
/// Options of the damped-Newton solver and its outcome (`Summary`).

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "sdot/linear_solver.hpp"

namespace sdot {

/// What the solver reports after each Newton iteration (and once for the start).
struct IterationRecord {
  int iteration = 0;              ///< 0 for the start
  double max_relative_error = 0;  ///< max_i |μ(W_i) − ν_i| / ν_i
  double rms_relative_error = 0;  ///< sqrt(mean_i ((μ(W_i) − ν_i) / ν_i)²)
  double step = 0;                ///< accepted step length 2^−ℓ (0 at the start)
  double elapsed_s = 0;           ///< wall time since the solver started, in seconds
};

/// Settings of sdot::solve. The defaults suit most problems; validate() (called by solve) rejects
/// invalid values with an InputError naming the field.
struct Options {
  /// Stop when the maximum relative mass error max_i |μ(W_i) − ν_i|/ν_i ≤ tolerance (> 0).
  double tolerance = 1e-9;
  /// Newton iterations at most (≥ 0); reaching it is Status::iteration_limit, not an error.
  int max_iterations = 100;
  /// Step halvings per line search at most (1…60); running out is Status::line_search_failure.
  int max_step_halvings = 40;
  /// The solver of the Newton systems (linear_solver_from_name() reads its name); `cholmod` is
  /// invalid in a build without CHOLMOD.
  LinearSolverKind linear_solver = LinearSolverKind::automatic;
  /// Relative residual of the conjugate-gradient solve (> 0; only for conjugate_gradient).
  double cg_tolerance = 1e-12;
  /// When the target masses do not sum to the source mass: rescale them to it (true, the
  /// factor is reported in Summary::mass_scale) or reject them with an InputError (false)
  /// when they differ by more than `mass_sum_tolerance` relatively.
  bool rescale_masses = true;
  /// With `rescale_masses` false: the largest accepted relative difference (≥ 0) between the
  /// target masses' sum and the source mass. The masses are still rescaled by the small factor.
  double mass_sum_tolerance = 1e-9;
  /// Below this max relative mass error, failing to make progress (no acceptable step down to
  /// 2⁻¹⁰, where the line search then stops, or three damped steps ≤ 1/16 in a row) means the
  /// problem's precision floor was reached: the solver stops with Status::precision_floor instead
  /// of a failure (≥ 0; 0 turns that off).
  double precision_floor_threshold = 1e-7;
  /// Integrate the transport cost on the final cells (`Result::transport_cost`). It is needed
  /// only there, and costs a pass of integrals over every cell (sphere, 134,000 cells: 0.051 s on
  /// one thread, against 0.019 s for their masses and moments alone); with false,
  /// `transport_cost` is NaN.
  bool compute_transport_cost = true;
  /// Partial transport (sdot/partial.hpp, docs/partial.md): cell i is its Laguerre cell cut by the
  /// ball {x : c(x, y_i) ≤ w_i}, and the masses must sum to less than the source mass (they are not
  /// rescaled). Needs a geometry with ball cuts (PartialGeometry) and the uniform density.
  bool partial = false;
  /// Called after each iteration (progress output); may be empty.
  std::function<void(const IterationRecord&)> callback;

  /// Empty when valid, else a message naming the field (`options.tolerance: must be > 0`).
  [[nodiscard]] std::string validation_error() const;
  /// Throws InputError when invalid.
  void validate() const;
};

/// The linear solver named "auto", "ldlt", "cg", "cholmod" or "multigrid" (the names of the
/// problem file, the command line and the Python package); InputError (field `linear_solver`)
/// for any other name.
LinearSolverKind linear_solver_from_name(std::string_view name);

/// How a solve ended (Summary::status). Only `converged` and `precision_floor` give a usable
/// result (Summary::usable()).
enum class Status {
  converged,             ///< the tolerance was reached
  iteration_limit,       ///< max_iterations were used up
  line_search_failure,   ///< no step length satisfied the KMT conditions, above
                         ///< `precision_floor_threshold`; or a cell is empty at the default start
  linear_solve_failure,  ///< the Newton system could not be solved
  precision_floor,       ///< stopped at the arithmetic's precision floor, above `tolerance` but
                         ///< below `precision_floor_threshold`: as accurate as this problem allows
};

/// The enumerator's name: "converged", "iteration_limit", "line_search_failure",
/// "linear_solve_failure" or "precision_floor".
std::string_view to_string(Status status);

/// Where a solve spent its time, in seconds of wall time.
struct Timings {
  double diagram_s = 0;       ///< building Laguerre diagrams
  double assembly_s = 0;      ///< integrating masses, moments, costs and Hessian entries
  double linear_solve_s = 0;  ///< factorising and solving the Newton systems
  double total_s = 0;         ///< the whole solve
};

/// The outcome of a solve (Result::summary).
struct Summary {
  Status status = Status::iteration_limit;  ///< how the solve ended
  std::string message;                      ///< the status in words: the final error, or what failed
  int iterations = 0;                       ///< Newton iterations done (all continuation stages)
  double max_relative_error = 0;            ///< max_i |μ(W_i) − ν_i| / ν_i at the returned weights
  double rms_relative_error = 0;            ///< sqrt(mean_i ((μ(W_i) − ν_i) / ν_i)²) there
  /// Factor applied to the target masses so that they sum to the source mass (1 if none).
  double mass_scale = 1;
  double source_mass = 0;  ///< μ of the whole source domain
  /// A record at the start and after each iteration (and at the start of each continuation stage,
  /// when the density vanishes on part of the domain).
  std::vector<IterationRecord> history;
  Timings timings;  ///< where the time went

  /// The tolerance was reached.
  [[nodiscard]] bool converged() const { return status == Status::converged; }
  /// Converged, or stopped at the precision floor: the result is usable.
  [[nodiscard]] bool usable() const { return status == Status::converged || status == Status::precision_floor; }
};

}  // namespace sdot
