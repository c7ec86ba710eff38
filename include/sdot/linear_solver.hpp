#pragma once
/// \file linear_solver.hpp
/// Linear solvers for the Newton system, through Eigen's own `compute / info / solve`
/// interface: anything that has those plugs in (SimplicialLDLT, ConjugateGradient,
/// CholmodSupernodalLLT, …) with no adapter.

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <chrono>
#include <concepts>

#include "sdot/multigrid.hpp"
#ifdef SDOT_HAVE_CHOLMOD
#include <dlfcn.h>
#include <omp.h>

#include <Eigen/CholmodSupport>
#endif

namespace sdot {

/// The Newton systems' matrix type (column-major, double).
using SparseMatrix = Eigen::SparseMatrix<double>;

/// A sparse symmetric positive-definite solver with Eigen's interface.
template <class S>
concept LinearSolver = requires(S solver, const SparseMatrix& matrix, const Eigen::VectorXd& rhs) {
  solver.compute(matrix);
  { solver.info() } -> std::same_as<Eigen::ComputationInfo>;
  {solver.solve(rhs)};
};

/// A solver that can split symbolic and numeric factorisation; the Newton driver then reuses
/// the symbolic step while the Hessian's sparsity pattern is unchanged.
template <class S>
concept FactorizingLinearSolver = LinearSolver<S> && requires(S solver, const SparseMatrix& matrix) {
  solver.analyzePattern(matrix);
  solver.factorize(matrix);
};

/// The built-in choices (`Options::linear_solver`).
enum class LinearSolverKind {
  automatic,           ///< the default: AutomaticLinearSolver (multigrid for large systems, else LDLᵀ)
  ldlt,                ///< Eigen::SimplicialLDLT (sparse Cholesky)
  conjugate_gradient,  ///< Eigen::ConjugateGradient with a Jacobi preconditioner
  cholmod,             ///< CHOLMOD's supernodal Cholesky (when built with SuiteSparse)
  multigrid,           ///< MultigridSolver: conjugate gradients with an algebraic multigrid V-cycle
};

/// True when this build offers LinearSolverKind::cholmod.
constexpr bool has_cholmod() {
#ifdef SDOT_HAVE_CHOLMOD
  return true;
#else
  return false;
#endif
}

/// Sparse LDLᵀ of the lower triangle (LinearSolverKind::ldlt).
using DefaultLinearSolver = Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower>;
/// Conjugate gradients with Eigen's default (Jacobi) preconditioner on the whole matrix
/// (LinearSolverKind::conjugate_gradient; Options::cg_tolerance).
using ConjugateGradientSolver = Eigen::ConjugateGradient<SparseMatrix, Eigen::Lower | Eigen::Upper>;
#ifdef SDOT_HAVE_CHOLMOD
/// CHOLMOD's supernodal Cholesky of the lower triangle (LinearSolverKind::cholmod); only in builds
/// with CHOLMOD (has_cholmod()).
using CholmodSolver = Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower>;

namespace detail {
/// Sets OpenBLAS's thread count when the BLAS in use is OpenBLAS (looked up at run time, no link
/// dependency); does nothing otherwise.
inline void set_blas_threads(int threads) {
  using SetThreads = void (*)(int);
  if (auto set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) set(threads);
}
/// CHOLMOD's dense kernels run in the BLAS. A multithreaded OpenBLAS keeps its threads spinning
/// after each call, which slowed sdot's own OpenMP loops by ~10 % (sphere diagrams at 10⁵ sites,
/// 2.5 → 2.8 s); one BLAS thread was faster overall. Applied once, only when the BLAS in use is
/// OpenBLAS (looked up at run time, no link dependency).
inline void use_single_threaded_blas() {
  static const bool done = [] {
    set_blas_threads(1);
    return true;
  }();
  (void)done;
}

/// While alive, the OpenMP parallel regions the constructing thread opens run on that thread
/// alone (max-active-levels is a per-thread setting; other threads are not affected).
/// For CHOLMOD's numeric factorisation: SuiteSparse 5 runs its supernodal assembly loops in a team
/// of a fixed 4 threads (CHOLMOD_OMP_NUM_THREADS) for every supernode of more than 64 rows, and
/// on a 2-core machine, beside OpenBLAS's threads, forking and joining those teams cost more than
/// the loops (capsule40_120k's Tutte systems, 16 factorisations: 3.1 s -> 2.2 s).
class SerialOpenMpRegions {
 public:
  SerialOpenMpRegions() : levels_(omp_get_max_active_levels()) { omp_set_max_active_levels(0); }
  SerialOpenMpRegions(const SerialOpenMpRegions&) = delete;
  SerialOpenMpRegions& operator=(const SerialOpenMpRegions&) = delete;
  ~SerialOpenMpRegions() { omp_set_max_active_levels(levels_); }

 private:
  int levels_;
};
}  // namespace detail

namespace detail {
/// The direct path of AutomaticLinearSolver: Eigen's SimplicialLDLT, and for systems of at least
/// `trial_size` unknowns one timed trial of CHOLMOD's supernodal Cholesky at the second
/// factorisation; the faster of the two is kept for the rest of the solve. Which wins depends on
/// the Hessian's fill and on the BLAS (measured at 10⁵ sites with OpenBLAS: on the sphere CHOLMOD
/// 1.6 s against LDLᵀ 2.0–2.3 s per solve, on the plane 1.44 s against 1.29 s; see
/// docs/benchmarks.md). Every new pattern gets its own ordering: one ordering (AMD or METIS) kept
/// across Newton iterations multiplied the fill by up to 6 at the next pattern.
class DirectLinearSolver {
 public:
  static constexpr Eigen::Index trial_size = 20000;

  void analyzePattern(const SparseMatrix&) { ++pattern_; }  // deferred to factorize
  void factorize(const SparseMatrix& matrix) {
    if (pattern_ == 0) ++pattern_;
    const bool trial = choice_ == Choice::undecided && factorizations_ == 1 && matrix.rows() >= trial_size;
    const bool cholmod = choice_ == Choice::cholmod || trial;
    const auto start = std::chrono::steady_clock::now();
    if (cholmod) {
      use_single_threaded_blas();
      const SerialOpenMpRegions serial;
      if (cholmod_pattern_ != pattern_) cholmod_.analyzePattern(matrix), cholmod_pattern_ = pattern_;
      cholmod_.factorize(matrix);
    } else {
      if (ldlt_pattern_ != pattern_) ldlt_.analyzePattern(matrix), ldlt_pattern_ = pattern_;
      ldlt_.factorize(matrix);
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    last_was_cholmod_ = cholmod;
    if (factorizations_ == 0) ldlt_seconds_ = seconds;
    if (trial) choice_ = cholmod_.info() == Eigen::Success && seconds < ldlt_seconds_ ? Choice::cholmod : Choice::ldlt;
    if (trial && choice_ == Choice::ldlt && cholmod_.info() != Eigen::Success) factorize_ldlt_again(matrix);
    ++factorizations_;
  }
  [[nodiscard]] Eigen::ComputationInfo info() const { return last_was_cholmod_ ? cholmod_.info() : ldlt_.info(); }
  [[nodiscard]] Eigen::VectorXd solve(const Eigen::VectorXd& rhs) const {
    return last_was_cholmod_ ? Eigen::VectorXd(cholmod_.solve(rhs)) : Eigen::VectorXd(ldlt_.solve(rhs));
  }
  [[nodiscard]] bool uses_cholmod() const { return choice_ == Choice::cholmod; }

 private:
  enum class Choice { undecided, ldlt, cholmod };
  void factorize_ldlt_again(const SparseMatrix& matrix) {
    if (ldlt_pattern_ != pattern_) ldlt_.analyzePattern(matrix), ldlt_pattern_ = pattern_;
    ldlt_.factorize(matrix);
    last_was_cholmod_ = false;
  }
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower> ldlt_;
  CholmodSolver cholmod_;
  Choice choice_ = Choice::undecided;
  int factorizations_ = 0;
  long pattern_ = 0, ldlt_pattern_ = -1, cholmod_pattern_ = -1;
  double ldlt_seconds_ = 0;
  bool last_was_cholmod_ = false;
};
}  // namespace detail
#else
namespace detail {
/// Without CHOLMOD the direct path is the sparse LDLᵀ.
using DirectLinearSolver = DefaultLinearSolver;
}  // namespace detail
#endif

/// The default solver. From `multigrid_size` unknowns: MultigridSolver (conjugate gradients with an
/// algebraic multigrid V-cycle), to the accuracy the Newton driver asks for; sphere, 10⁵ sites:
/// 0.79–0.82 s of linear solves per Newton solve against 1.70–1.71 s by the direct path
/// (docs/benchmarks.md, "Session 7"). Below
/// that size, or once the multigrid iteration has failed on a system (it then stays off), the
/// direct path: LDLᵀ, with a timed trial of CHOLMOD from 20,000 unknowns when available.
/// The multigrid path is deterministic. The CHOLMOD trial depends on timing: two runs of the same
/// large problem that fall back may use different direct solvers and differ in the last bits.
class AutomaticLinearSolver {
 public:
  /// From how many unknowns the default-constructed solver tries the multigrid path first.
  static constexpr Eigen::Index default_multigrid_size = 12000;

  /// Multigrid from default_multigrid_size unknowns.
  AutomaticLinearSolver() = default;
  /// `multigrid_size`: from how many unknowns the multigrid path is tried first.
  explicit AutomaticLinearSolver(Eigen::Index multigrid_size) : multigrid_size_(multigrid_size) {}

  /// The direct path's symbolic analysis of a new sparsity pattern (the multigrid path needs none).
  void analyzePattern(const SparseMatrix& matrix) { direct_.analyzePattern(matrix); }
  /// Prepares `matrix` (symmetric, both triangles stored): builds the multigrid hierarchy when the
  /// system is large enough and the multigrid path has not failed, else (or when that build fails)
  /// factorises it by the direct path. info() tells whether it succeeded.
  void factorize(const SparseMatrix& matrix) {
    last_was_multigrid_ = false;
    if (matrix.rows() >= multigrid_size_ && !multigrid_failed_) {
      multigrid_.compute(matrix);
      if (multigrid_.info() == Eigen::Success) {
        last_was_multigrid_ = true;
        return;
      }
      multigrid_failed_ = true;
    }
    direct_.factorize(matrix);
  }
  /// analyzePattern() then factorize().
  void compute(const SparseMatrix& matrix) {
    analyzePattern(matrix);
    factorize(matrix);
  }
  /// `Eigen::Success`, or the failure of the path that handled the last factorize() or solve().
  [[nodiscard]] Eigen::ComputationInfo info() const { return last_was_multigrid_ ? multigrid_.info() : direct_.info(); }
  /// The solution x of matrix·x = `rhs` for the last factorised matrix.
  /// Not const, unlike Eigen's solvers: a failed multigrid iteration falls back to a factorisation.
  [[nodiscard]] Eigen::VectorXd solve(const Eigen::VectorXd& rhs) {
    if (last_was_multigrid_) {
      Eigen::VectorXd x = multigrid_.solve(rhs);
      if (multigrid_.info() == Eigen::Success) return x;
      multigrid_failed_ = true, last_was_multigrid_ = false;
      const SparseMatrix matrix = multigrid_.matrix();  // the hierarchy's copy: none kept here
      direct_.analyzePattern(matrix);
      direct_.factorize(matrix);
    }
    return direct_.solve(rhs);
  }
  /// Forwarded to the multigrid path (the direct path is exact anyway).
  void setTolerance(double tolerance) { multigrid_.setTolerance(tolerance); }
  /// Forwarded to the multigrid path: see MultigridSolver::set_scaled_tolerance.
  void set_scaled_tolerance(const Eigen::VectorXd& scale, double tolerance) {
    multigrid_.set_scaled_tolerance(scale, tolerance);
  }
  /// True when the last system was solved by the multigrid path (visible in tests).
  [[nodiscard]] bool used_multigrid() const { return last_was_multigrid_; }
  /// True once the multigrid path has failed and was switched off.
  [[nodiscard]] bool multigrid_failed() const { return multigrid_failed_; }
  /// True once the direct path's trial chose CHOLMOD (visible in tests).
  [[nodiscard]] bool uses_cholmod() const { return direct_uses_cholmod(direct_); }
  /// The multigrid path's solver (its iteration limit can be set; tests use it).
  [[nodiscard]] MultigridSolver& multigrid() { return multigrid_; }

 private:
  // A template, so that the requires-expression is a test rather than a hard error when the
  // direct solver of a build without CHOLMOD has no uses_cholmod().
  template <class Direct>
  static bool direct_uses_cholmod(const Direct& direct) {
    if constexpr (requires { direct.uses_cholmod(); })
      return direct.uses_cholmod();
    else
      return false;
  }

  Eigen::Index multigrid_size_ = default_multigrid_size;
  MultigridSolver multigrid_;
  detail::DirectLinearSolver direct_;
  bool last_was_multigrid_ = false, multigrid_failed_ = false;
};

}  // namespace sdot
