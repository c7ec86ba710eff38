// SplitCholesky: the Tutte systems' factorisation in two halves on two threads.
#include <gtest/gtest.h>

#ifdef SDOT_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#include <Eigen/SparseCholesky>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "split_cholesky.hpp"

namespace sphparam {
namespace {

/// A weighted graph Laplacian of a width × length grid with diagonal neighbours, weights
/// spread over e^±`spread`, plus a diagonal of 1e-3 on the grid's first row (as the Tutte
/// systems' fixed vertices do): symmetric positive definite, both triangles.
Eigen::SparseMatrix<double> grid_laplacian(int width, int length, double spread, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> exponent(-spread, spread);
  const int n = width * length;
  std::vector<Eigen::Triplet<double>> entries;
  std::vector<double> diagonal(static_cast<std::size_t>(n), 0.0);
  const auto link = [&](int a, int b) {
    const double w = std::exp(exponent(random));
    entries.emplace_back(a, b, -w), entries.emplace_back(b, a, -w);
    diagonal[static_cast<std::size_t>(a)] += w, diagonal[static_cast<std::size_t>(b)] += w;
  };
  for (int j = 0; j < length; ++j)
    for (int i = 0; i < width; ++i) {
      const int v = j * width + i;
      if (i + 1 < width) link(v, v + 1);
      if (j + 1 < length) link(v, v + width);
      if (i + 1 < width && j + 1 < length) link(v, v + width + 1);
    }
  for (int i = 0; i < width; ++i) diagonal[static_cast<std::size_t>(i)] += 1e-3;
  for (int v = 0; v < n; ++v) entries.emplace_back(v, v, diagonal[static_cast<std::size_t>(v)]);
  Eigen::SparseMatrix<double> matrix(n, n);
  matrix.setFromTriplets(entries.begin(), entries.end());
  return matrix;
}

/// A matrix in a nested-dissection order (METIS's, postordered by CHOLMOD), with the symbolic
/// supernodal analysis of that order as SplitCholesky::plan takes it.
class Ordered {
 public:
  explicit Ordered(const Eigen::SparseMatrix<double>& matrix) : permutation_(matrix.rows()) {
    start(common_);
    common_.nmethods = 1;
    common_.method[0].ordering = CHOLMOD_METIS;  // nested dissection, as the Tutte systems' orders
    Eigen::SparseMatrix<double> lower = matrix.triangularView<Eigen::Lower>();
    cholmod_sparse view = Eigen::viewAsCholmod(lower);
    view.stype = -1;
    cholmod_factor* ordering = cholmod_analyze(&view, &common_);
    if (!ordering) throw std::runtime_error("cholmod_analyze failed");
    for (Eigen::Index k = 0; k < matrix.rows(); ++k)
      permutation_.indices()[static_cast<const int*>(ordering->Perm)[k]] = static_cast<int>(k);
    cholmod_free_factor(&ordering, &common_);
    permuted_.resize(matrix.rows(), matrix.cols());
    permuted_.selfadjointView<Eigen::Lower>() = matrix.selfadjointView<Eigen::Lower>().twistedBy(permutation_);
    permuted_ = Eigen::SparseMatrix<double>(permuted_.transpose()).transpose();  // sorted columns
    permuted_.makeCompressed();
    common_.nmethods = 1;
    common_.method[0].ordering = CHOLMOD_NATURAL;
    common_.postorder = 0;
    cholmod_sparse natural = Eigen::viewAsCholmod(permuted_);
    natural.stype = -1;
    analysis_ = cholmod_analyze(&natural, &common_);
    if (!analysis_) throw std::runtime_error("cholmod_analyze failed");
  }
  Ordered(const Ordered&) = delete;
  Ordered& operator=(const Ordered&) = delete;
  ~Ordered() {
    cholmod_free_factor(&analysis_, &common_);
    cholmod_finish(&common_);
  }
  static void start(cholmod_common& common) {
    cholmod_start(&common);
    common.supernodal = CHOLMOD_SUPERNODAL;
    common.print = 0;  // the indefinite systems below are meant to fail
  }
  /// The lower triangle of P A Pᵀ.
  [[nodiscard]] const Eigen::SparseMatrix<double>& lower() const { return permuted_; }
  [[nodiscard]] const cholmod_factor& analysis() const { return *analysis_; }
  /// P A Pᵀ for another matrix of the same pattern as the one given at construction.
  [[nodiscard]] Eigen::SparseMatrix<double> lower_of(const Eigen::SparseMatrix<double>& matrix) const {
    Eigen::SparseMatrix<double> out(matrix.rows(), matrix.cols());
    out.selfadjointView<Eigen::Lower>() = matrix.selfadjointView<Eigen::Lower>().twistedBy(permutation_);
    out = Eigen::SparseMatrix<double>(out.transpose()).transpose();
    out.makeCompressed();
    return out;
  }

 private:
  cholmod_common common_{};
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> permutation_;
  Eigen::SparseMatrix<double> permuted_;
  cholmod_factor* analysis_ = nullptr;
};

/// max over the columns of ‖K x − b‖ / ‖b‖, K given by its lower triangle.
double relative_residual(const Eigen::SparseMatrix<double>& lower, const Eigen::MatrixXd& x, const Eigen::MatrixXd& b) {
  const Eigen::MatrixXd product = lower.selfadjointView<Eigen::Lower>() * x;
  double worst = 0;
  for (Eigen::Index c = 0; c < b.cols(); ++c)
    worst = std::max(worst, (product.col(c) - b.col(c)).norm() / b.col(c).norm());
  return worst;
}

/// Plans and prepares `split` for `ordered`'s matrix, which must split.
void plan_and_prepare(SplitCholesky& split, const Ordered& ordered) {
  ASSERT_TRUE(split.plan(ordered.analysis()));
  ASSERT_TRUE(split.prepare(ordered.lower(), Ordered::start));
}

TEST(SplitCholesky, SolvesALongGridInTwoHalvesAsOneFactorisationDoes) {
  // A grid 16 wide and 2,000 long, like a tube: its top separator is a few dozen columns
  // across, below it two halves of about 16,000 unknowns each.
  const Eigen::SparseMatrix<double> first = grid_laplacian(16, 2000, 6.0, 1);
  const Ordered ordered(first);
  SplitCholesky split;
  ASSERT_NO_FATAL_FAILURE(plan_and_prepare(split, ordered));
  EXPECT_GT(split.separator_size(), 0u);
  EXPECT_LT(split.separator_size(), 200u);
  std::mt19937 random(7);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd rhs(first.rows(), 2);
  for (Eigen::Index k = 0; k < rhs.size(); ++k) rhs.data()[k] = normal(random);
  // Twice, with other values in the same pattern the second time (a reweighting).
  for (unsigned seed : {1u, 2u}) {
    const Eigen::SparseMatrix<double> lower =
        seed == 1 ? ordered.lower() : ordered.lower_of(grid_laplacian(16, 2000, 6.0, seed));
    split.factorize(lower);
    const Eigen::MatrixXd x = split.solve(rhs);
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> whole(lower);
    ASSERT_EQ(whole.info(), Eigen::Success);
    const Eigen::MatrixXd reference = whole.solve(rhs);
    const double split_residual = relative_residual(lower, x, rhs);
    const double whole_residual = relative_residual(lower, reference, rhs);
    EXPECT_LT(split_residual, std::max(1e-10, 10 * whole_residual)) << "seed " << seed;
    EXPECT_LT((x - reference).norm() / reference.norm(), 1e-6) << "seed " << seed;
  }
}

TEST(SplitCholesky, DeclinesAMatrixWithoutTwoSubtrees) {
  // A small dense matrix is one supernode: nothing to split.
  Eigen::MatrixXd dense = Eigen::MatrixXd::Random(60, 60);
  dense = dense * dense.transpose() + 60 * Eigen::MatrixXd::Identity(60, 60);
  const Eigen::SparseMatrix<double> matrix = dense.sparseView();
  const Ordered ordered(matrix);
  SplitCholesky split;
  EXPECT_FALSE(split.plan(ordered.analysis()));
  EXPECT_FALSE(split.prepare(ordered.lower(), Ordered::start));  // nothing planned
}

TEST(SplitCholesky, SaysSoWhenTheMatrixIsNotPositiveDefinite) {
  const Eigen::SparseMatrix<double> matrix = grid_laplacian(16, 2000, 2.0, 3);
  const Ordered ordered(matrix);
  SplitCholesky split;
  ASSERT_NO_FATAL_FAILURE(plan_and_prepare(split, ordered));
  // −K in a half: a half's factorisation fails.
  const Eigen::SparseMatrix<double> negative = -ordered.lower();
  EXPECT_THROW(split.factorize(negative), std::runtime_error);
  // K with its separator's diagonal halved: indefinite (the constant vector's energy is negative),
  // but the halves, whose separator diagonal C_i is twice K's, are still definite: the Schur
  // complement is not.
  Eigen::SparseMatrix<double> shifted = ordered.lower();
  split.factorize(shifted);  // fine as it is
  const Eigen::MatrixXd ones = Eigen::MatrixXd::Ones(matrix.rows(), 1);
  EXPECT_LT(relative_residual(shifted, split.solve(ones), ones), 1e-8);
  for (Eigen::Index c = 0; c < shifted.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(shifted, c); it; ++it)
      if (it.row() == it.col() && split.is_separator(static_cast<int>(c))) it.valueRef() *= 0.5;
  EXPECT_THROW(split.factorize(shifted), std::runtime_error);
}

}  // namespace
}  // namespace sphparam
#endif
