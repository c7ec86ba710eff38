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
#ifdef SDOT_HAVE_CHOLMOD
#include <dlfcn.h>

#include <Eigen/CholmodSupport>
#endif

namespace sdot {

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
  automatic,           ///< the default: AutomaticLinearSolver (LDLᵀ, or CHOLMOD when it is faster)
  ldlt,                ///< Eigen::SimplicialLDLT (sparse Cholesky)
  conjugate_gradient,  ///< Eigen::ConjugateGradient with a Jacobi preconditioner
  cholmod,             ///< CHOLMOD's supernodal Cholesky (when built with SuiteSparse)
};

/// True when this build offers LinearSolverKind::cholmod.
constexpr bool has_cholmod() {
#ifdef SDOT_HAVE_CHOLMOD
  return true;
#else
  return false;
#endif
}

using DefaultLinearSolver = Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower>;
using ConjugateGradientSolver = Eigen::ConjugateGradient<SparseMatrix, Eigen::Lower | Eigen::Upper>;
#ifdef SDOT_HAVE_CHOLMOD
using CholmodSolver = Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower>;

namespace detail {
/// CHOLMOD's dense kernels run in the BLAS. A multithreaded OpenBLAS keeps its threads spinning
/// after each call, which slowed sdot's own OpenMP loops by ~10 % (sphere diagrams at 10⁵ sites,
/// 2.5 → 2.8 s); one BLAS thread was faster overall. Applied once, only when the BLAS in use is
/// OpenBLAS (looked up at run time, no link dependency).
inline void use_single_threaded_blas() {
  static const bool done = [] {
    using SetThreads = void (*)(int);
    if (auto set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) set(1);
    return true;
  }();
  (void)done;
}
}  // namespace detail

/// The default solver: Eigen's SimplicialLDLT, and for systems of at least `trial_size` unknowns
/// one timed trial of CHOLMOD's supernodal Cholesky at the second factorisation; the faster of
/// the two is kept for the rest of the solve. Which wins depends on the Hessian's fill and on
/// the BLAS (measured at 10⁵ sites with OpenBLAS: on the sphere CHOLMOD 1.6 s against LDLᵀ
/// 2.0–2.3 s per solve, on the plane 1.44 s against 1.29 s; see docs/benchmarks.md).
/// The choice depends on timing: two runs of the same large problem may use different solvers
/// and differ in the last bits. Choose `ldlt` or `cholmod` explicitly for bitwise-reproducible
/// results. Every new pattern gets its own ordering: one ordering (AMD or METIS) kept across
/// Newton iterations multiplied the fill by up to 6 at the next pattern (docs/benchmarks.md).
class AutomaticLinearSolver {
 public:
  static constexpr Eigen::Index trial_size = 20000;

  void analyzePattern(const SparseMatrix&) { ++pattern_; }  // deferred to factorize
  void factorize(const SparseMatrix& matrix) {
    if (pattern_ == 0) ++pattern_;
    const bool trial = choice_ == Choice::undecided && factorizations_ == 1 && matrix.rows() >= trial_size;
    const bool cholmod = choice_ == Choice::cholmod || trial;
    const auto start = std::chrono::steady_clock::now();
    if (cholmod) {
      detail::use_single_threaded_blas();
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
  void compute(const SparseMatrix& matrix) {
    analyzePattern(matrix);
    factorize(matrix);
  }
  [[nodiscard]] Eigen::ComputationInfo info() const { return last_was_cholmod_ ? cholmod_.info() : ldlt_.info(); }
  [[nodiscard]] Eigen::VectorXd solve(const Eigen::VectorXd& rhs) const {
    return last_was_cholmod_ ? Eigen::VectorXd(cholmod_.solve(rhs)) : Eigen::VectorXd(ldlt_.solve(rhs));
  }
  /// True once the trial chose CHOLMOD (visible in tests).
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
#else
/// Without CHOLMOD the default solver is the sparse LDLᵀ.
using AutomaticLinearSolver = DefaultLinearSolver;
#endif

}  // namespace sdot
