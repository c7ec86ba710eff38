#pragma once
/// \file multigrid.hpp
/// Conjugate gradients preconditioned by a smoothed-aggregation algebraic multigrid V-cycle, for
/// the Newton systems (weighted graph Laplacians with a pinned site). It has Eigen's
/// `compute / info / solve` interface, so it is a `LinearSolver`.
///
/// Where it pays: a sparse Cholesky factorisation of a Laguerre Hessian grows like n^1.5 and fills
/// in; one V-cycle costs a few sweeps over the matrix. The Newton driver asks only for the accuracy
/// each step needs (`set_scaled_tolerance`: relative to each target mass), so early steps take
/// a few cycles. Convergence is not guaranteed for every symmetric matrix: when the iteration does
/// not reach the tolerance, `info()` is `Eigen::NoConvergence` and the caller falls back to a
/// factorisation (the automatic solver does).

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <memory>
#include <vector>

namespace sdot {

/// The Newton systems' matrix type (column-major, double).
using SparseMatrix = Eigen::SparseMatrix<double>;

/// Conjugate gradients preconditioned by one smoothed-aggregation algebraic multigrid V-cycle
/// (LinearSolverKind::multigrid, and the large-system path of AutomaticLinearSolver). A model
/// of `LinearSolver` for symmetric matrices with a positive diagonal, such as the Newton
/// Hessians with a pinned site. Movable, not copyable.
class MultigridSolver {
 public:
  /// How the hierarchy is built.
  struct Settings {
    /// Connections with |a_ij| ≥ θ·sqrt(a_ii·a_jj) join aggregates (Vaněk–Mandel–Brezina).
    double strength_threshold = 0.08;
    /// At most this many unknowns: the level is the coarsest, solved by a sparse LDLᵀ.
    Eigen::Index coarse_size = 200;
    /// At most this many levels, the finest included: the last is solved directly, whatever its size.
    int max_levels = 12;
    /// `compute` on a matrix of the same size as the last keeps the coarse levels and replaces
    /// only the finest (the Newton Hessians of one solve differ little from step to step). They
    /// are rebuilt at the next `compute` once a solve with them converges at less than half the
    /// digits per iteration of the first solve after a build, and at once when a solve with them
    /// does not converge.
    bool reuse_hierarchy = true;
    /// Symmetric Gauss–Seidel sweeps before and after each coarse correction (at least 1). Two
    /// cost less in all than one: sphere, 10⁶ sites, 62 → 40 conjugate-gradient iterations in
    /// the 6 Newton solves, 7.1–7.3 → 6.8–6.9 s of linear solves.
    int smoothing_sweeps = 2;
  };

  /// A solver with the default Settings.
  MultigridSolver();
  /// A solver whose hierarchies are built with `settings`.
  explicit MultigridSolver(const Settings& settings);
  /// Not copyable (the hierarchy is owned).
  MultigridSolver(const MultigridSolver&) = delete;
  /// Not copyable (the hierarchy is owned).
  MultigridSolver& operator=(const MultigridSolver&) = delete;
  /// Takes over the other solver's hierarchy and settings.
  MultigridSolver(MultigridSolver&&) noexcept;
  /// Takes over the other solver's hierarchy and settings.
  MultigridSolver& operator=(MultigridSolver&&) noexcept;
  /// Releases the hierarchy.
  ~MultigridSolver();

  /// Builds the hierarchy of `matrix`: symmetric, both triangles stored, positive diagonal.
  void compute(const SparseMatrix& matrix);
  /// `Eigen::Success` after a successful compute and solve; `InvalidInput` when the matrix is not
  /// square or not compressed, or `Settings::smoothing_sweeps` is below 1; `NumericalIssue` when the matrix has a
  /// non-positive diagonal entry or a level cannot be factorised; `NoConvergence` when the last solve stopped at the
  /// iteration limit above the tolerance.
  [[nodiscard]] Eigen::ComputationInfo info() const;
  /// Solves matrix·x = rhs from x = 0.
  [[nodiscard]] Eigen::VectorXd solve(const Eigen::VectorXd& rhs) const;

  /// The iteration stops when ‖r‖₂ ≤ tolerance·‖rhs‖₂ (Eigen's convention; default 1e-12) and,
  /// if a scaled tolerance is set, max_i scale_i·|r_i| ≤ scaled tolerance as well. The Newton
  /// driver sets both: scale_i = 1/ν_i, so that each cell's predicted mass is within a relative
  /// tolerance of its target, and the 2-norm, so that the step is a descent direction.
  void setTolerance(double tolerance);
  /// An empty `scale` removes the scaled criterion.
  void set_scaled_tolerance(const Eigen::VectorXd& scale, double tolerance);
  /// At most this many conjugate-gradient iterations per solve (default 200); reaching it above
  /// the tolerance is `Eigen::NoConvergence`.
  void setMaxIterations(int iterations);

  /// Conjugate-gradient iterations of the last solve.
  [[nodiscard]] int iterations() const;
  /// ‖r‖₂ / ‖rhs‖₂ after the last solve (of the true residual rhs − A·x when it succeeded).
  [[nodiscard]] double error() const;
  /// max_i scale_i·|r_i| after the last solve (0 without a scaled tolerance).
  [[nodiscard]] double scaled_error() const;
  /// How many times the whole hierarchy was built (the rest of the `compute` calls reused its
  /// coarse levels; see Settings::reuse_hierarchy).
  [[nodiscard]] int builds() const;
  /// Unknowns per level, finest first (visible in tests and benchmarks).
  [[nodiscard]] std::vector<Eigen::Index> level_sizes() const;
  /// The matrix of the last `compute` (the hierarchy keeps it as its finest level), for a caller
  /// that falls back to a factorisation without keeping a copy of its own; empty before any.
  [[nodiscard]] SparseMatrix matrix() const;

 private:
  struct Hierarchy;
  Settings settings_;
  std::unique_ptr<Hierarchy> hierarchy_;
};

}  // namespace sdot
