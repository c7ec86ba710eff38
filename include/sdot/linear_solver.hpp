#pragma once
/// \file linear_solver.hpp
/// Linear solvers for the Newton system, through Eigen's own `compute / info / solve`
/// interface: anything that has those plugs in (SimplicialLDLT, ConjugateGradient,
/// CholmodSupernodalLLT, …) with no adapter.

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <concepts>
#ifdef SDOT_HAVE_CHOLMOD
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
  ldlt,                ///< Eigen::SimplicialLDLT (sparse Cholesky), the default
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
#endif

}  // namespace sdot
