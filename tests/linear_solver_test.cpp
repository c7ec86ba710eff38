// The default linear solver: correct solutions through its LDLᵀ → CHOLMOD trial and pattern changes.
#include <gtest/gtest.h>

#include <random>

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

/// A grid Laplacian (k × k unknowns) plus `extra` random symmetric couplings and a positive
/// diagonal shift: symmetric positive definite, with a pattern that changes with `seed`.
sdot::SparseMatrix spd_matrix(int k, int extra, unsigned seed) {
  const int n = k * k;
  std::vector<Eigen::Triplet<double>> entries;
  auto couple = [&](int a, int b, double w) {
    entries.emplace_back(a, b, -w);
    entries.emplace_back(b, a, -w);
    entries.emplace_back(a, a, w);
    entries.emplace_back(b, b, w);
  };
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
  sdot::AutomaticLinearSolver solver;
  const int k = 160;  // 25 600 unknowns: above the trial size, so the second factorisation is a trial
  ASSERT_GE(k * k, sdot::AutomaticLinearSolver::trial_size);
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

}  // namespace

// The Newton matrix is assembled in compressed columns directly; it must equal the sum of the
// four triplets per facet weight (what setFromTriplets builds), for input in any order and with
// a pair repeated (two cells sharing two facets), plus the gauge entry at (0, 0).
TEST(NewtonMatrix, AssemblyEqualsTheTripletSum) {
  const int n = 300;
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> site(0, n - 1);
  std::uniform_real_distribution<double> weight(0.1, 2.0);
  std::vector<Eigen::Triplet<double>> facet_weights;
  for (int k = 0; k < 1500; ++k) {
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
  sdot::SparseMatrix expected(n, n);
  expected.setFromTriplets(entries.begin(), entries.end());

  const sdot::SparseMatrix assembled = sdot::detail::assemble_hessian(n, facet_weights);
  EXPECT_TRUE(assembled.isCompressed());
  EXPECT_EQ(assembled.nonZeros(), expected.nonZeros());
  EXPECT_LT((assembled - expected).norm(), 1e-13 * expected.norm());
  for (int c = 0; c < n; ++c)  // rows strictly increasing in each column, diagonal present
    for (int p = assembled.outerIndexPtr()[c]; p + 1 < assembled.outerIndexPtr()[c + 1]; ++p)
      EXPECT_LT(assembled.innerIndexPtr()[p], assembled.innerIndexPtr()[p + 1]);
  EXPECT_EQ(assembled.diagonal().size(), n);
  EXPECT_GT(assembled.diagonal().minCoeff(), 0);
  // The same weights in the same order give the same matrix, bit for bit.
  const sdot::SparseMatrix again = sdot::detail::assemble_hessian(n, facet_weights);
  EXPECT_TRUE(std::equal(again.valuePtr(), again.valuePtr() + again.nonZeros(), assembled.valuePtr()));
}
