#pragma once
// A supernodal Cholesky factorisation split in two halves that run on two threads.
#ifdef SDOT_HAVE_CHOLMOD
#include <cholmod.h>

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <array>
#include <functional>
#include <vector>

namespace sphparam {

/// The Cholesky factorisation of a sparse symmetric positive-definite matrix K (its lower
/// triangle, in a fill-reducing order) as two independent halves and a dense separator.
/// CHOLMOD's numeric factorisation runs on one thread; the two subtrees below the top of K's
/// elimination tree do not touch each other, so each is factorised, with the separator S that
/// couples them, by CHOLMOD on a thread of its own:
///   M_i = [A_i  B_i; B_iᵀ  C_i] = L_i L_iᵀ,  C_i = 2 diag(K_SS) (any C_i keeping M_i definite),
/// whose last block gives B_iᵀ A_i⁻¹ B_i = C_i − L_SS,i L_SS,iᵀ; the Schur complement
/// K_SS − Σ B_iᵀ A_i⁻¹ B_i is factorised densely. Solves go forward in both halves at once, through
/// the separator, and back in both halves at once.
/// The result is the same bit for bit whatever the number of threads. A split pays when the
/// separator is small against the halves: a tube cut across (capsule40_120k: 388 columns against
/// halves of 60,000), not a sphere-like surface cut in two (igea_134k: 1,114).
class SplitCholesky {
 public:
  /// Sets up cholmod_common for the halves (CHOLMOD's start and the caller's settings).
  using StartCommon = std::function<void(cholmod_common&)>;

  SplitCholesky() = default;
  SplitCholesky(const SplitCholesky&) = delete;
  SplitCholesky& operator=(const SplitCholesky&) = delete;
  ~SplitCholesky();

  /// Chooses the separator from `analysis`, a supernodal symbolic factor of K in its own
  /// (natural, postordered) order. False when no split is expected to pay (small systems, an
  /// elimination tree without two balanced subtrees below a small separator): then this object
  /// is unusable and the caller factorises K as a whole.
  bool plan(const cholmod_factor& analysis);
  /// After plan: the halves' matrices from the pattern of `lower` (K's lower triangle, in the
  /// analysis's order) and their symbolic analyses. False when K's pattern does not split as
  /// planned (unusable as after a failed plan).
  bool prepare(const Eigen::SparseMatrix<double>& lower, const StartCommon& start);
  /// Factorises the matrix of `lower` (the pattern given to plan, new values). Throws
  /// std::runtime_error when K is not numerically positive definite.
  void factorize(const Eigen::SparseMatrix<double>& lower);
  /// K⁻¹ rhs for the last factorised K, every column.
  [[nodiscard]] Eigen::MatrixXd solve(const Eigen::MatrixXd& rhs);

  /// The separator's size (0 before a successful prepare).
  [[nodiscard]] std::size_t separator_size() const { return separator_.size(); }
  /// True when K's column `column` is in the separator (false before a successful plan).
  [[nodiscard]] bool is_separator(int column) const {
    return column >= 0 && static_cast<std::size_t>(column) < part_.size() &&
           part_[static_cast<std::size_t>(column)] == 2;
  }

 private:
  struct Half {
    cholmod_common common{};
    bool started = false;
    cholmod_factor* factor = nullptr;
    std::vector<int> columns;            // K's columns of this half's subtrees, in K's order
    std::vector<int> separator_slots;    // S_i: positions in separator_ of the S columns it touches
    Eigen::SparseMatrix<double> matrix;  // lower triangle of M_i: the columns, then S_i
    std::vector<int> value_source;       // per value of matrix: the value of K's lower triangle
    std::vector<double> value_scale;     // 1, or 2 on S_i's diagonal (C_i)
    Eigen::MatrixXd corner;              // L_SS,i (lower triangle)
    Eigen::MatrixXd update;              // L_SS,i L_SS,iᵀ (lower triangle)
    Eigen::MatrixXd forward;             // L_i⁻¹ [b_i; 0] of the current solve
  };
  void factorize_half(Half& half, const double* values);
  void forward_half(Half& half, const Eigen::MatrixXd& rhs);
  void backward_half(Half& half, const Eigen::MatrixXd& separator_solution, Eigen::MatrixXd& out);
  /// Runs work(0) on a second thread and work(1) on this one; rethrows the first exception.
  static void on_both_halves(const std::function<void(int)>& work);

  std::vector<int> part_;  // per column of K: its half (0, 1) or the separator (2); plan
  std::array<Half, 2> halves_;
  std::vector<int> separator_;  // K's columns of S, in K's order
  // K_SS's lower triangle: (value of K's lower triangle, row, column) in separator_ positions
  std::vector<std::array<int, 3>> separator_entries_;
  Eigen::LLT<Eigen::MatrixXd> schur_;
};

}  // namespace sphparam
#endif
