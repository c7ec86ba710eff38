// The linear solvers: the automatic solver's multigrid path, its fallback, and its direct path
// (LDLᵀ → CHOLMOD trial) through pattern changes; the multigrid solver on its own.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <limits>
#include <random>
#include <thread>

#include "sdot/linear_solver.hpp"
#include "sdot/solver.hpp"

namespace {

template <class S>
bool solver_uses_cholmod(const S& solver) {
  if constexpr (requires { solver.uses_cholmod(); })
    return solver.uses_cholmod();
  else
    return false;
}

/// The four entries of an edge of weight w between unknowns a and b of a graph Laplacian.
void add_edge(std::vector<Eigen::Triplet<double>>& entries, int a, int b, double w) {
  entries.emplace_back(a, b, -w);
  entries.emplace_back(b, a, -w);
  entries.emplace_back(a, a, w);
  entries.emplace_back(b, b, w);
}

/// A grid Laplacian (k × k unknowns) plus `extra` random symmetric couplings and a positive
/// diagonal shift: symmetric positive definite, with a pattern that changes with `seed`.
sdot::SparseMatrix spd_matrix(int k, int extra, unsigned seed) {
  const int n = k * k;
  std::vector<Eigen::Triplet<double>> entries;
  auto couple = [&](int a, int b, double w) { add_edge(entries, a, b, w); };
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j) {
      if (i + 1 < k) couple(i * k + j, (i + 1) * k + j, 1);
      if (j + 1 < k) couple(i * k + j, i * k + j + 1, 1);
    }
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> node(0, n - 2);
  for (int e = 0; e < extra; ++e) {
    const int a = node(random);
    couple(a, a + 1 + static_cast<int>(random() % 3) * k % (n - a - 1), 0.5);
  }
  for (int i = 0; i < n; ++i) entries.emplace_back(i, i, 1e-3);
  sdot::SparseMatrix matrix(n, n);
  matrix.setFromTriplets(entries.begin(), entries.end());
  return matrix;
}

TEST(LinearSolver, AutomaticSolvesThroughTheTrialAndPatternChanges) {
  sdot::AutomaticLinearSolver solver(std::numeric_limits<Eigen::Index>::max());  // direct path only
  const int k = 160;  // 25 600 unknowns: above the trial size (20,000), so the 2nd factorisation is a trial
  EXPECT_FALSE(solver.used_multigrid());
  for (unsigned step = 0; step < 4; ++step) {
    const sdot::SparseMatrix matrix = spd_matrix(k, 500, step);
    const Eigen::VectorXd rhs = Eigen::VectorXd::LinSpaced(matrix.rows(), -1, 1);
    solver.analyzePattern(matrix);
    solver.factorize(matrix);
    ASSERT_EQ(solver.info(), Eigen::Success) << "step " << step;
    const Eigen::VectorXd x = solver.solve(rhs);
    EXPECT_LT((matrix * x - rhs).norm(), 1e-9 * rhs.norm()) << "step " << step;
  }
  std::printf("  the trial chose %s\n", sdot::has_cholmod() && solver_uses_cholmod(solver) ? "CHOLMOD" : "LDLT");
}

#ifdef SDOT_HAVE_CHOLMOD
/// The team size of a parallel region asking for `requested` threads, opened on this thread.
int team_size(int requested) {
  int size = 0;
#pragma omp parallel num_threads(requested)
  {
#pragma omp single
    size = omp_get_num_threads();
  }
  return size;
}

TEST(LinearSolver, SerialOpenMpRegionsSerialiseOnlyTheirOwnThreadWhileTheyLive) {
  ASSERT_EQ(team_size(3), 3);  // CHOLMOD's teams ask for a fixed count, whatever the machine
  int other_thread_team = 0;
  {
    const sdot::detail::SerialOpenMpRegions serial;
    EXPECT_EQ(team_size(3), 1);
    std::thread other([&] { other_thread_team = team_size(3); });
    other.join();
  }
  EXPECT_EQ(other_thread_team, 3);
  EXPECT_EQ(team_size(3), 3);  // restored
}
#endif

/// A Newton-like matrix: a k × k grid Laplacian whose edge weights span six orders of magnitude
/// (log-uniform), pinned at unknown 0 as the Newton driver pins its gauge.
sdot::SparseMatrix weighted_laplacian(int k, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> exponent(-3, 3);
  std::vector<Eigen::Triplet<double>> entries;
  auto couple = [&](int a, int b) { add_edge(entries, a, b, std::pow(10.0, exponent(random))); };
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j) {
      if (i + 1 < k) couple(i * k + j, (i + 1) * k + j);
      if (j + 1 < k) couple(i * k + j, i * k + j + 1);
      if (i + 1 < k && j + 1 < k) couple(i * k + j, (i + 1) * k + j + 1);  // triangles, as in a Laguerre graph
    }
  entries.emplace_back(0, 0, 1.0);
  sdot::SparseMatrix matrix(k * k, k * k);
  matrix.setFromTriplets(entries.begin(), entries.end());
  return matrix;
}

Eigen::VectorXd zero_sum_rhs(Eigen::Index n, unsigned seed) {
  std::mt19937 random(seed);
  std::normal_distribution<double> normal;
  Eigen::VectorXd rhs(n);
  for (Eigen::Index i = 0; i < n; ++i) rhs[i] = normal(random);
  rhs.array() -= rhs.mean();
  return rhs;
}

TEST(Multigrid, SolvesAWeightedLaplacianToTheTolerance) {
  const sdot::SparseMatrix matrix = weighted_laplacian(120, 1);
  const Eigen::VectorXd rhs = zero_sum_rhs(matrix.rows(), 2);
  sdot::MultigridSolver multigrid;
  multigrid.compute(matrix);
  ASSERT_EQ(multigrid.info(), Eigen::Success);
  EXPECT_EQ((multigrid.matrix() - matrix).norm(), 0.0);  // what the automatic solver's fallback factorises
  const auto sizes = multigrid.level_sizes();
  ASSERT_GE(sizes.size(), 3u);  // 14,400 unknowns coarsen to at most 200 in several levels
  for (std::size_t l = 1; l < sizes.size(); ++l) EXPECT_LT(sizes[l] * 3, sizes[l - 1]) << "level " << l;
  EXPECT_LE(sizes.back(), 200);
  multigrid.setTolerance(1e-10);
  const Eigen::VectorXd x = multigrid.solve(rhs);
  ASSERT_EQ(multigrid.info(), Eigen::Success);
  EXPECT_LE((rhs - matrix * x).norm(), 1e-10 * rhs.norm());
  EXPECT_NEAR(multigrid.error(), (rhs - matrix * x).norm() / rhs.norm(), 1e-12);
  std::printf("  levels %zu, %d iterations to 1e-10\n", sizes.size(), multigrid.iterations());
  EXPECT_LE(multigrid.iterations(), 60);  // Jacobi-CG needs thousands on this matrix
  Eigen::SimplicialLDLT<sdot::SparseMatrix> ldlt(matrix);
  const Eigen::VectorXd exact = ldlt.solve(rhs);
  EXPECT_LT((x - exact).norm(), 1e-4 * exact.norm());
}

TEST(Multigrid, ScaledToleranceBoundsEveryResidualEntry) {
  const sdot::SparseMatrix matrix = weighted_laplacian(80, 3);
  const Eigen::VectorXd rhs = zero_sum_rhs(matrix.rows(), 4);
  const Eigen::VectorXd scale = Eigen::VectorXd::LinSpaced(matrix.rows(), 1, 100);
  sdot::MultigridSolver multigrid;
  multigrid.compute(matrix);
  multigrid.setTolerance(1);  // the scaled criterion alone decides
  int previous_iterations = 0;
  for (double tolerance : {1e-1, 1e-4, 1e-8}) {
    multigrid.set_scaled_tolerance(scale, tolerance);
    const Eigen::VectorXd x = multigrid.solve(rhs);
    ASSERT_EQ(multigrid.info(), Eigen::Success) << tolerance;
    const double worst = (scale.array() * (rhs - matrix * x).array().abs()).maxCoeff();
    EXPECT_LE(worst, tolerance);
    EXPECT_NEAR(multigrid.scaled_error(), worst, 1e-6 * worst);  // of the true residual
    EXPECT_GT(multigrid.iterations(), previous_iterations) << "a tighter tolerance needs more iterations";
    previous_iterations = multigrid.iterations();
  }
}

TEST(Multigrid, ReportsBadMatricesAndTheIterationLimit) {
  sdot::MultigridSolver multigrid;
  sdot::SparseMatrix matrix = weighted_laplacian(30, 5);
  matrix.coeffRef(17, 17) = -1;  // not positive definite
  multigrid.compute(matrix);
  EXPECT_EQ(multigrid.info(), Eigen::NumericalIssue);
  const Eigen::VectorXd rhs = zero_sum_rhs(matrix.rows(), 6);
  (void)multigrid.solve(rhs);
  EXPECT_NE(multigrid.info(), Eigen::Success);

  multigrid.compute(weighted_laplacian(60, 7));
  ASSERT_EQ(multigrid.info(), Eigen::Success);
  multigrid.setTolerance(1e-15);
  multigrid.setMaxIterations(2);
  (void)multigrid.solve(zero_sum_rhs(3600, 8));
  EXPECT_EQ(multigrid.info(), Eigen::NoConvergence);
  EXPECT_EQ(multigrid.iterations(), 2);
  EXPECT_GT(multigrid.error(), 1e-15);

  const Eigen::VectorXd wrong_size = Eigen::VectorXd::Ones(5);
  (void)multigrid.solve(wrong_size);
  EXPECT_EQ(multigrid.info(), Eigen::InvalidInput);
}

/// Builds the hierarchy of `matrix` and solves with it to 1e-10 (so that the next compute() of a
/// matrix of its size reuses it).
void build_and_solve(sdot::MultigridSolver& multigrid, const sdot::SparseMatrix& matrix, const Eigen::VectorXd& rhs) {
  multigrid.setTolerance(1e-10);
  multigrid.compute(matrix);
  (void)multigrid.solve(rhs);
  ASSERT_EQ(multigrid.info(), Eigen::Success);
}

TEST(Multigrid, ABadMatrixAfterAGoodOneIsRejectedAndTheNextGoodOneSolved) {
  // The finest level of a built hierarchy is overwritten in place by the next matrix of its
  // size: a bad one must not leave a half-replaced hierarchy behind.
  const sdot::SparseMatrix good = weighted_laplacian(60, 11);
  const Eigen::VectorXd rhs = zero_sum_rhs(good.rows(), 12);
  sdot::MultigridSolver multigrid;
  ASSERT_NO_FATAL_FAILURE(build_and_solve(multigrid, good, rhs));
  sdot::SparseMatrix bad = good;
  bad.coeffRef(40, 40) = -1;
  multigrid.compute(bad);
  EXPECT_EQ(multigrid.info(), Eigen::NumericalIssue);
  (void)multigrid.solve(rhs);
  EXPECT_NE(multigrid.info(), Eigen::Success);
  const sdot::SparseMatrix next = weighted_laplacian(60, 13);
  multigrid.compute(next);
  ASSERT_EQ(multigrid.info(), Eigen::Success);
  EXPECT_EQ((multigrid.matrix() - next).norm(), 0.0);
  const Eigen::VectorXd x = multigrid.solve(rhs);
  ASSERT_EQ(multigrid.info(), Eigen::Success);
  EXPECT_LE((rhs - next * x).norm(), 1e-10 * rhs.norm());
}

TEST(Multigrid, MoreSmoothingSweepsTakeFewerIterationsAndZeroIsRejected) {
  const sdot::SparseMatrix matrix = weighted_laplacian(100, 9);
  const Eigen::VectorXd rhs = zero_sum_rhs(matrix.rows(), 10);
  int previous = std::numeric_limits<int>::max();
  Eigen::VectorXd first;
  for (int sweeps : {1, 2, 3}) {
    sdot::MultigridSolver::Settings settings;
    settings.smoothing_sweeps = sweeps;
    sdot::MultigridSolver multigrid(settings);
    multigrid.compute(matrix);
    ASSERT_EQ(multigrid.info(), Eigen::Success);
    multigrid.setTolerance(1e-10);
    const Eigen::VectorXd x = multigrid.solve(rhs);
    ASSERT_EQ(multigrid.info(), Eigen::Success);
    EXPECT_LE((rhs - matrix * x).norm(), 1e-10 * rhs.norm());
    std::printf("  %d sweeps: %d iterations\n", sweeps, multigrid.iterations());
    EXPECT_LT(multigrid.iterations(), previous) << sweeps << " sweeps";
    previous = multigrid.iterations();
  }
  sdot::MultigridSolver::Settings none;
  none.smoothing_sweeps = 0;
  sdot::MultigridSolver multigrid(none);
  multigrid.compute(matrix);
  EXPECT_EQ(multigrid.info(), Eigen::InvalidInput);
}

TEST(Multigrid, ReusesItsHierarchyForTheNextNewtonMatrix) {
  const sdot::SparseMatrix first = weighted_laplacian(120, 1);
  const Eigen::VectorXd rhs = zero_sum_rhs(first.rows(), 2);
  sdot::MultigridSolver multigrid;
  ASSERT_NO_FATAL_FAILURE(build_and_solve(multigrid, first, rhs));
  const int fresh_iterations = multigrid.iterations();
  // The next Newton matrix: the same graph, weights a few percent off. The coarse levels stay.
  sdot::SparseMatrix next = first;
  std::mt19937 random(3);
  std::uniform_real_distribution<double> factor(0.95, 1.05);
  for (int c = 0; c < next.outerSize(); ++c)
    for (sdot::SparseMatrix::InnerIterator it(next, c); it; ++it)
      if (it.row() < it.col()) {
        const double f = factor(random), w = -it.value();
        next.coeffRef(it.row(), it.col()) = next.coeffRef(it.col(), it.row()) = -f * w;
        next.coeffRef(it.row(), it.row()) += (f - 1) * w;
        next.coeffRef(it.col(), it.col()) += (f - 1) * w;
      }
  next.makeCompressed();
  multigrid.compute(next);
  Eigen::VectorXd x = multigrid.solve(rhs);
  ASSERT_EQ(multigrid.info(), Eigen::Success);
  EXPECT_EQ(multigrid.builds(), 1);
  EXPECT_LE((rhs - next * x).norm(), 1e-10 * rhs.norm());
  EXPECT_LE(multigrid.iterations(), fresh_iterations + 5);
  // A matrix of the same size but another graph and other weights: the old levels fail or
  // converge slowly, the hierarchy is rebuilt, and the answer is still right.
  const sdot::SparseMatrix other = weighted_laplacian(120, 99) + 10 * first;
  for (int round = 0; round < 3; ++round) {
    multigrid.compute(other);
    x = multigrid.solve(rhs);
    ASSERT_EQ(multigrid.info(), Eigen::Success) << round;
    EXPECT_LE((rhs - other * x).norm(), 1e-10 * rhs.norm()) << round;
  }
  // Without reuse every compute builds.
  sdot::MultigridSolver::Settings settings;
  settings.reuse_hierarchy = false;
  sdot::MultigridSolver fresh(settings);
  fresh.compute(first);
  fresh.compute(next);
  EXPECT_EQ(fresh.builds(), 2);
}

TEST(Multigrid, SameSolutionWhateverTheThreadCount) {
  // The smoother's blocks and the parallel products are fixed by the matrix, not by the threads.
  const sdot::SparseMatrix matrix = weighted_laplacian(120, 4);  // 14,400 rows: several blocks
  const Eigen::VectorXd rhs = zero_sum_rhs(matrix.rows(), 5);
  auto solve_with_threads = [&](int threads) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    sdot::MultigridSolver multigrid;
    multigrid.setTolerance(1e-10);
    multigrid.compute(matrix);
    Eigen::VectorXd x = multigrid.solve(rhs);
    EXPECT_EQ(multigrid.info(), Eigen::Success);
    omp_set_num_threads(saved);
    return x;
  };
  const Eigen::VectorXd one = solve_with_threads(1), two = solve_with_threads(2), three = solve_with_threads(3);
  EXPECT_EQ(one, two);
  EXPECT_EQ(one, three);
}

TEST(Multigrid, ParallelVectorOperationsGiveTheSameSolutionWhateverTheThreadCount) {
  // 270,400 rows: enough blocks for the conjugate gradients' vector operations and block sums to
  // run in parallel; their sums are added per block, in order, whatever the threads.
  const sdot::SparseMatrix matrix = weighted_laplacian(520, 4);
  const Eigen::VectorXd rhs = zero_sum_rhs(matrix.rows(), 5);
  sdot::MultigridSolver multigrid;
  multigrid.setTolerance(1e-12);
  multigrid.setMaxIterations(5);  // five iterations, converged or not, are enough to compare
  multigrid.compute(matrix);
  ASSERT_EQ(multigrid.info(), Eigen::Success);
  auto solve_with_threads = [&](int threads) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    Eigen::VectorXd x = multigrid.solve(rhs);
    EXPECT_EQ(multigrid.iterations(), 5);
    omp_set_num_threads(saved);
    return x;
  };
  const Eigen::VectorXd one = solve_with_threads(1), two = solve_with_threads(2), three = solve_with_threads(3);
  EXPECT_EQ(one, two);
  EXPECT_EQ(one, three);
  EXPECT_LT((rhs - matrix * one).norm(), 0.5 * rhs.norm());  // and they did solve something
}

TEST(LinearSolver, AutomaticUsesMultigridAndFallsBackWhenItFails) {
  const sdot::SparseMatrix matrix = weighted_laplacian(130, 9);  // 16,900 unknowns: multigrid by default
  ASSERT_GE(matrix.rows(), sdot::AutomaticLinearSolver::default_multigrid_size);
  const Eigen::VectorXd rhs = zero_sum_rhs(matrix.rows(), 10);
  sdot::AutomaticLinearSolver solver;
  solver.compute(matrix);
  Eigen::VectorXd x = solver.solve(rhs);
  ASSERT_EQ(solver.info(), Eigen::Success);
  EXPECT_TRUE(solver.used_multigrid());
  EXPECT_LE((rhs - matrix * x).norm(), 1e-11 * rhs.norm());

  // An iteration that cannot reach its tolerance: the same system is then factorised instead,
  // and later systems skip the multigrid path.
  solver.multigrid().setMaxIterations(1);
  solver.setTolerance(1e-14);
  solver.compute(matrix);
  x = solver.solve(rhs);
  ASSERT_EQ(solver.info(), Eigen::Success);
  EXPECT_FALSE(solver.used_multigrid());
  EXPECT_TRUE(solver.multigrid_failed());
  EXPECT_LE((rhs - matrix * x).norm(), 1e-9 * rhs.norm());
  solver.compute(matrix);
  EXPECT_FALSE(solver.used_multigrid());
  EXPECT_LE((rhs - matrix * solver.solve(rhs)).norm(), 1e-9 * rhs.norm());

  // A matrix the hierarchy cannot take (a non-positive diagonal) goes to the direct path at once.
  sdot::AutomaticLinearSolver other;
  sdot::SparseMatrix indefinite = matrix;
  indefinite.coeffRef(5, 5) = 0;
  other.compute(indefinite);
  EXPECT_FALSE(other.used_multigrid());
  EXPECT_TRUE(other.multigrid_failed());
}

}  // namespace

// The Newton matrix is assembled in compressed columns directly; it must equal the sum of the
// four triplets per facet weight (what setFromTriplets builds), for input in any order and with
// a pair repeated (two cells sharing two facets), plus the gauge entry at (0, 0).
// Below 2¹⁶ facets the assembly runs on one thread, from there on one column range per thread.
TEST(NewtonMatrix, AssemblyEqualsTheTripletSum) {
  for (const auto& [n, pairs] : {std::pair{300, 1500}, std::pair{40000, 100000}}) {
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> site(0, n - 1);
    std::uniform_real_distribution<double> weight(0.1, 2.0);
    std::vector<Eigen::Triplet<double>> facet_weights;
    for (int k = 0; k < pairs; ++k) {
      int i = site(rng), j = site(rng);
      if (i == j) continue;
      if (i > j) std::swap(i, j);
      facet_weights.emplace_back(i, j, weight(rng));
      if (k % 50 == 0) facet_weights.emplace_back(i, j, weight(rng));  // a repeated pair
    }
    std::shuffle(facet_weights.begin(), facet_weights.end(), rng);
    std::vector<Eigen::Triplet<double>> entries;
    double largest = 0;
    for (const auto& t : facet_weights) {
      entries.emplace_back(t.row(), t.col(), -t.value());
      entries.emplace_back(t.col(), t.row(), -t.value());
      entries.emplace_back(t.row(), t.row(), t.value());
      entries.emplace_back(t.col(), t.col(), t.value());
      largest = std::max(largest, t.value());
    }
    entries.emplace_back(0, 0, largest);
    for (int c = 0; c < n; ++c) entries.emplace_back(c, c, 0.0);  // every diagonal entry is stored
    sdot::SparseMatrix expected(n, n);
    expected.setFromTriplets(entries.begin(), entries.end());

    const sdot::SparseMatrix assembled = sdot::detail::assemble_hessian(n, facet_weights);
    EXPECT_TRUE(assembled.isCompressed());
    EXPECT_EQ(assembled.nonZeros(), expected.nonZeros()) << n;
    EXPECT_LT((assembled - expected).norm(), 1e-13 * expected.norm()) << n;
    for (int c = 0; c < n; ++c)  // rows strictly increasing in each column, diagonal present
      for (int p = assembled.outerIndexPtr()[c]; p + 1 < assembled.outerIndexPtr()[c + 1]; ++p)
        ASSERT_LT(assembled.innerIndexPtr()[p], assembled.innerIndexPtr()[p + 1]) << n;
    EXPECT_EQ(assembled.diagonal().size(), n);
    EXPECT_GE(assembled.diagonal().minCoeff(), 0);
    // The same weights in the same order give the same matrix, bit for bit, on any number of threads.
    const int threads = omp_get_max_threads();
    for (int count : {1, 2, 3}) {
      omp_set_num_threads(count);
      const sdot::SparseMatrix again = sdot::detail::assemble_hessian(n, facet_weights);
      omp_set_num_threads(threads);
      ASSERT_EQ(again.nonZeros(), assembled.nonZeros());
      EXPECT_TRUE(std::equal(again.valuePtr(), again.valuePtr() + again.nonZeros(), assembled.valuePtr()))
          << n << " sites, " << count << " threads";
      EXPECT_TRUE(
          std::equal(again.innerIndexPtr(), again.innerIndexPtr() + again.nonZeros(), assembled.innerIndexPtr()));
      EXPECT_TRUE(std::equal(again.outerIndexPtr(), again.outerIndexPtr() + n + 1, assembled.outerIndexPtr()));
    }
  }
}

// Targets above 4× a cell's mass come down to 4×, the others scale up to keep the sum; nothing
// moves when that would take more than a quarter of the error away, or near the solution.
TEST(NewtonGrowth, LimitedToFourTimesTheMassWhileTheStepStillDescends) {
  using sdot::detail::limit_newton_growth;
  const Eigen::VectorXd masses = Eigen::VectorXd::Constant(400, 1.0);
  Eigen::VectorXd rhs = Eigen::VectorXd::Constant(400, -0.1);
  rhs[0] = 5.0;                  // a cell asked to grow 6×: to 4×
  rhs.segment(1, 10).fill(2.9);  // within the limit
  rhs[11] = -0.9;                // shrinking is not limited
  rhs.array() -= rhs.mean();
  const Eigen::VectorXd limited = limit_newton_growth(rhs, masses, false);
  ASSERT_NE(limited, rhs);
  EXPECT_NEAR(limited.sum(), 0, 1e-12);
  const Eigen::VectorXd targets = masses + rhs, limited_targets = masses + limited;
  const double scale = limited_targets[12] / targets[12];  // every target but the limited one
  EXPECT_GT(scale, 1);
  EXPECT_NEAR(limited_targets[0], 4.0 * scale, 1e-12);
  EXPECT_NEAR(limited_targets[1], targets[1] * scale, 1e-12);
  EXPECT_NEAR(limited_targets[11], targets[11] * scale, 1e-12);
  EXPECT_NEAR(limited_targets.sum(), masses.sum(), 1e-9);
  // Partial transport keeps its total moving: only the limited target changes.
  const Eigen::VectorXd kept = limit_newton_growth(rhs, masses, true);
  EXPECT_DOUBLE_EQ(kept[0], 3.0);
  EXPECT_TRUE(kept.tail(399) == rhs.tail(399));
  // One cell holding most of the error: limiting it would leave more than a quarter; unchanged.
  Eigen::VectorXd dominant = Eigen::VectorXd::Constant(400, -0.02);
  dominant[0] = 9.0;
  dominant.array() -= dominant.mean();
  EXPECT_EQ(limit_newton_growth(dominant, masses, false), dominant);
  // Within the limit (growth to 4× included): unchanged.
  const Eigen::VectorXd near = Eigen::VectorXd::LinSpaced(400, -0.99, 3.0);
  EXPECT_EQ(limit_newton_growth(near, masses, true), near);
}

// The line search's floor: ε₀ for a cell at 2ε₀ or more; half the current mass for a cell below
// that, never below ε₀/8; a NaN mass never passes.
TEST(LineSearchFloor, CellsNearEpsilonZeroMayHalveDownToAnEighthOfIt) {
  using sdot::detail::above_mass_floor;
  const double epsilon0 = 1.0;
  const Eigen::VectorXd current = (Eigen::VectorXd(4) << 10.0, 2.0, 1.03, 0.2).finished();
  Eigen::VectorXd trial = (Eigen::VectorXd(4) << 1.0, 1.0, 0.6, 0.125).finished();
  EXPECT_TRUE(above_mass_floor(trial, current, epsilon0));
  // KMT's rule alone (every cell ≥ ε₀) rejects this trial: the third cell is at 0.6ε₀.
  EXPECT_LT(trial.minCoeff(), epsilon0);
  trial[0] = 0.99;  // a cell at 10ε₀ must stay above ε₀
  EXPECT_FALSE(above_mass_floor(trial, current, epsilon0));
  trial[0] = 1.0, trial[2] = 0.5;  // below half of 1.03
  EXPECT_FALSE(above_mass_floor(trial, current, epsilon0));
  trial[2] = 0.6, trial[3] = 0.1;  // below ε₀/8, although half of 0.2 would allow it
  EXPECT_FALSE(above_mass_floor(trial, current, epsilon0));
  trial[3] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(above_mass_floor(trial, current, epsilon0));
}
