// Smoothed-aggregation algebraic multigrid (Vaněk, Mandel, Brezina 1996) as the preconditioner of
// conjugate gradients. Matrices are kept in compressed rows of their own (the input is symmetric,
// so its compressed columns are its rows); the smoother is Gauss–Seidel, Settings::smoothing_sweeps
// forward sweeps before the coarse correction and as many backward after it, so that the V-cycle
// is a symmetric preconditioner.
#include "sdot/multigrid.hpp"

#include <omp.h>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

namespace sdot {
namespace {

/// Compressed sparse rows. The index arrays are the matrix's own, or borrowed from another
/// matrix of the same pattern (`shared_start`, `shared_column`): the finest level's
/// single-precision copy borrows those of the double-precision matrix, 32 MB at 10⁶ rows. A
/// borrowing matrix has empty `start` and `column`: read its pattern through starts(), columns(),
/// row_begin() and row_end().
template <class Real>
struct Rows {
  int rows = 0, cols = 0;
  std::vector<int> start{0}, column;
  std::vector<Real> value;
  const int* shared_start = nullptr;
  const int* shared_column = nullptr;

  [[nodiscard]] const int* starts() const { return shared_start ? shared_start : start.data(); }
  [[nodiscard]] const int* columns() const { return shared_column ? shared_column : column.data(); }
  [[nodiscard]] std::size_t row_begin(int i) const { return static_cast<std::size_t>(starts()[i]); }
  [[nodiscard]] std::size_t row_end(int i) const { return static_cast<std::size_t>(starts()[i + 1]); }
};

/// The hierarchy is built in double precision; the V-cycle (smoothing, restriction and
/// prolongation) runs on single-precision copies of its matrices. Those loops are limited by
/// memory bandwidth, and the preconditioner needs no more than single precision: the conjugate
/// gradients, the only place where the residual's accuracy matters, use the double-precision
/// finest matrix.
using RowMatrix = Rows<double>;
using SingleRows = Rows<float>;

/// `s` = single-precision values of `a`, borrowing `a`'s index arrays (valid while `a`'s arrays
/// live); `s`'s value array keeps its capacity.
void share_as_single(const RowMatrix& a, SingleRows& s) {
  s.rows = a.rows, s.cols = a.cols;
  s.start.clear(), s.column.clear();
  s.shared_start = a.start.data(), s.shared_column = a.column.data();
  s.value.assign(a.value.begin(), a.value.end());
}

/// Single-precision copy that takes over `a`'s index arrays (`a` is left empty).
SingleRows to_single(RowMatrix&& a) {
  SingleRows s;
  s.rows = a.rows, s.cols = a.cols;
  s.value.assign(a.value.begin(), a.value.end());
  s.start = std::move(a.start), s.column = std::move(a.column);
  a = RowMatrix{};
  return s;
}

inline std::size_t at(int i) {
  return static_cast<std::size_t>(i);
}

/// Rows per block of the parallel loops; a fixed size (not one block per thread) keeps every
/// result independent of the number of threads.
constexpr int block_rows = 4096;

/// From how many blocks the vector operations run in parallel: below it (10⁵ unknowns, 25 blocks)
/// waking the second thread for each operation cost more than it saved (sphere, 10⁵ sites: linear
/// solves 0.58 → 0.61 s).
constexpr int parallel_vector_blocks = 64;

/// The conjugate gradients' vector operations, block by block of `block_rows` entries, on both
/// cores for long vectors (at 10⁶ unknowns they were a tenth of an iteration on one). Sums add the
/// blocks' partial sums in order, so they do not depend on the number of threads.
template <class Body>
void for_each_block(Eigen::Index n, Body&& body) {
  const auto blocks = static_cast<int>((n + block_rows - 1) / block_rows);
#pragma omp parallel for schedule(static) if (blocks >= parallel_vector_blocks)
  for (int block = 0; block < blocks; ++block)
    body(Eigen::Index(block) * block_rows, std::min<Eigen::Index>(n, Eigen::Index(block + 1) * block_rows));
}

/// term(0) ⊕ … ⊕ term(n − 1) for ⊕ = `combine` from `identity`, per block as above, the blocks'
/// results combined in order.
template <class Term, class Combine>
double block_reduce(Eigen::Index n, double identity, Term&& term, Combine&& combine) {
  const auto blocks = static_cast<int>((n + block_rows - 1) / block_rows);
  std::vector<double> partial(static_cast<std::size_t>(blocks), identity);
  for_each_block(n, [&](Eigen::Index first, Eigen::Index last) {
    double value = identity;
    for (Eigen::Index i = first; i < last; ++i) value = combine(value, term(i));
    partial[static_cast<std::size_t>(first / block_rows)] = value;
  });
  double total = identity;
  for (double value : partial) total = combine(total, value);
  return total;
}

double dot(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return block_reduce(
      a.size(), 0.0, [&](Eigen::Index i) { return a[i] * b[i]; }, std::plus<>());
}

/// to = from
void copy(const Eigen::VectorXd& from, Eigen::VectorXd& to) {
  to.resize(from.size());
  for_each_block(from.size(), [&](Eigen::Index first, Eigen::Index last) {
    std::copy(from.data() + first, from.data() + last, to.data() + first);
  });
}

/// y = A·x (in double precision whatever A's)
template <class Real>
void multiply(const Rows<Real>& a, const Eigen::VectorXd& x, Eigen::VectorXd& y) {
  const int* start = a.starts();
  const int* column = a.columns();
  const Real* value = a.value.data();
#pragma omp parallel for schedule(static) if (a.rows >= 2 * block_rows)
  for (int i = 0; i < a.rows; ++i) {
    double sum = 0;
    for (int k = start[i]; k < start[i + 1]; ++k) sum += double(value[k]) * x[column[k]];
    y[i] = sum;
  }
}

/// The transpose of `a` (for the restriction Pᵀ).
RowMatrix transpose(const RowMatrix& a) {
  RowMatrix t;
  t.rows = a.cols, t.cols = a.rows;
  t.start.assign(at(a.cols) + 1, 0);
  for (int c : a.column) ++t.start[at(c) + 1];
  for (std::size_t c = 0; c < at(a.cols); ++c) t.start[c + 1] += t.start[c];
  t.column.resize(a.column.size());
  t.value.resize(a.value.size());
  std::vector<int> cursor(t.start.begin(), t.start.end() - 1);
  for (int i = 0; i < a.rows; ++i)
    for (std::size_t k = a.row_begin(i); k < a.row_end(i); ++k) {
      const auto slot = at(cursor[at(a.column[k])]++);
      t.column[slot] = i, t.value[slot] = a.value[k];
    }
  return t;
}

/// a·b by rows (Gustavson), with a dense accumulator over b's columns; the rows are split in one
/// contiguous range per thread and joined in order. Columns within a row are left unsorted
/// (nothing here needs them sorted).
RowMatrix product(const RowMatrix& a, const RowMatrix& b) {
  RowMatrix c;
  c.rows = a.rows, c.cols = b.cols;
  c.start.assign(at(a.rows) + 1, 0);
  std::vector<RowMatrix> parts;
#pragma omp parallel
  {
#pragma omp single
    parts.resize(static_cast<std::size_t>(omp_get_num_threads()));
    const int thread = omp_get_thread_num(), threads = omp_get_num_threads();
    const int first = static_cast<int>(static_cast<long>(a.rows) * thread / threads);
    const int last = static_cast<int>(static_cast<long>(a.rows) * (thread + 1) / threads);
    RowMatrix& part = parts[static_cast<std::size_t>(thread)];
    std::vector<int> slot(at(b.cols), -1);  // position in `part` of the current row's column, or -1
    part.column.reserve(at(last - first) * 16);
    part.value.reserve(at(last - first) * 16);
    for (int i = first; i < last; ++i) {
      const std::size_t row_start = part.column.size();
      for (std::size_t k = a.row_begin(i); k < a.row_end(i); ++k) {
        const double aij = a.value[k];
        const int j = a.column[k];
        for (std::size_t l = b.row_begin(j); l < b.row_end(j); ++l) {
          int& position = slot[at(b.column[l])];
          if (position < 0) {
            position = static_cast<int>(part.column.size());
            part.column.push_back(b.column[l]), part.value.push_back(0.0);
          }
          part.value[at(position)] += aij * b.value[l];
        }
      }
      for (std::size_t k = row_start; k < part.column.size(); ++k) slot[at(part.column[k])] = -1;
      c.start[at(i) + 1] = static_cast<int>(part.column.size() - row_start);
    }
  }
  for (std::size_t i = 0; i < at(a.rows); ++i) c.start[i + 1] += c.start[i];
  c.column.reserve(at(c.start.back()));
  c.value.reserve(at(c.start.back()));
  for (const auto& part : parts) {
    c.column.insert(c.column.end(), part.column.begin(), part.column.end());
    c.value.insert(c.value.end(), part.value.begin(), part.value.end());
  }
  return c;
}

struct Level {
  RowMatrix matrix;                           // A (symmetric); kept on the finest level only, once built
  SingleRows single;                          // A in single precision, for the V-cycle
  Eigen::VectorXd diagonal;                   // a_ii
  Eigen::VectorXd smoother_inverse;           // 1 / the divisors of smoother_diagonal()
  std::vector<unsigned char> crosses_blocks;  // 1 for rows with entries in other smoother blocks
  SingleRows prolongation;                    // P: this level's unknowns from the next level's
  SingleRows restriction;                     // Pᵀ
  mutable Eigen::VectorXd rhs, x, residual, previous;
};

/// Aggregates of strongly connected unknowns (the three passes of Vaněk et al.): returns the
/// aggregate of each unknown and the number of aggregates.
std::vector<int> aggregate(const RowMatrix& a, const Eigen::VectorXd& diagonal, double theta, int& count) {
  const int n = a.rows;
  std::vector<int> owner(at(n), -1);
  auto strong = [&](int i, std::size_t k) {
    const int j = a.column[k];
    return j != i && std::abs(a.value[k]) >= theta * std::sqrt(diagonal[i] * diagonal[j]);
  };
  count = 0;
  // 1. an unknown whose strong neighbours are all free starts an aggregate with them
  for (int i = 0; i < n; ++i) {
    if (owner[at(i)] >= 0) continue;
    bool free = true, any = false;
    for (std::size_t k = a.row_begin(i); k < a.row_end(i) && free; ++k)
      if (strong(i, k)) any = true, free = owner[at(a.column[k])] < 0;
    if (!free || !any) continue;
    owner[at(i)] = count;
    for (std::size_t k = a.row_begin(i); k < a.row_end(i); ++k)
      if (strong(i, k)) owner[at(a.column[k])] = count;
    ++count;
  }
  // 2. the rest join the aggregate of their strongest aggregated neighbour (pass-1 owners only)
  std::vector<int> joined(at(n), -1);
  for (int i = 0; i < n; ++i) {
    if (owner[at(i)] >= 0) continue;
    double best = 0;
    for (std::size_t k = a.row_begin(i); k < a.row_end(i); ++k) {
      const int j = a.column[k];
      if (strong(i, k) && owner[at(j)] >= 0 && std::abs(a.value[k]) > best)
        best = std::abs(a.value[k]), joined[at(i)] = owner[at(j)];
    }
  }
  for (int i = 0; i < n; ++i)
    if (joined[at(i)] >= 0) owner[at(i)] = joined[at(i)];
  // 3. what is left forms aggregates with its free neighbours; an unknown without strong
  //    connections stays out (its row of P₀ is zero, and the smoothing of P interpolates it
  //    from its neighbours' aggregates): as a singleton it would stall the coarsening
  for (int i = 0; i < n; ++i) {
    if (owner[at(i)] >= 0) continue;
    bool any = false;
    double best = 0;
    int nearest = -1;
    for (std::size_t k = a.row_begin(i); k < a.row_end(i); ++k) {
      if (!strong(i, k)) continue;
      int& other = owner[at(a.column[k])];
      if (other < 0)
        other = count, any = true;
      else if (other != count && std::abs(a.value[k]) > best)
        best = std::abs(a.value[k]), nearest = other;
    }
    if (any)
      owner[at(i)] = count++;
    else if (nearest >= 0)
      owner[at(i)] = nearest;  // its free neighbours were taken earlier in this pass
  }
  return owner;
}

/// P = (I − ω D⁻¹A)·P₀, P₀ the aggregates' indicator columns; ω = 4/(3ρ), ρ bounded by
/// Gershgorin's max_i Σ_j |a_ij| / a_ii.
RowMatrix smoothed_prolongation(const RowMatrix& a, const Eigen::VectorXd& diagonal, const std::vector<int>& owner,
                                int count) {
  const double rho = block_reduce(
      a.rows, 0.0,
      [&](Eigen::Index i) {
        double sum = 0;
        for (std::size_t k = a.row_begin(int(i)); k < a.row_end(int(i)); ++k) sum += std::abs(a.value[k]);
        return sum / diagonal[i];
      },
      [](double x, double y) { return std::max(x, y); });
  const double omega = 4.0 / (3.0 * rho);
  // Rows in blocks of `block_rows`, each block into arrays of its own, joined in block order:
  // the same matrix whatever the number of threads.
  const int blocks = (a.rows + block_rows - 1) / block_rows;
  std::vector<RowMatrix> parts(at(blocks));
#pragma omp parallel for schedule(dynamic, 1) if (blocks > 1)
  for (int block = 0; block < blocks; ++block) {
    const int first_row = block * block_rows, last_row = std::min(a.rows, first_row + block_rows);
    RowMatrix& part = parts[at(block)];
    part.start.clear();
    part.column.reserve(a.row_end(last_row - 1) - a.row_begin(first_row));
    part.value.reserve(part.column.capacity());
    for (int i = first_row; i < last_row; ++i) {
      const std::size_t first = part.column.size();
      auto add = [&](int c, double v) {
        for (std::size_t k = first; k < part.column.size(); ++k)
          if (part.column[k] == c) {
            part.value[k] += v;
            return;
          }
        part.column.push_back(c), part.value.push_back(v);
      };
      if (owner[at(i)] >= 0) add(owner[at(i)], 1.0);
      for (std::size_t k = a.row_begin(i); k < a.row_end(i); ++k)
        if (owner[at(a.column[k])] >= 0) add(owner[at(a.column[k])], -omega * a.value[k] / diagonal[i]);
      part.start.push_back(static_cast<int>(part.column.size() - first));
    }
  }
  RowMatrix p;
  p.rows = a.rows, p.cols = count;
  p.start.assign(at(a.rows) + 1, 0);
  std::size_t entries = 0;
  for (const auto& part : parts) entries += part.column.size();
  p.column.reserve(entries);
  p.value.reserve(entries);
  int row = 0;
  for (auto& part : parts) {
    for (int length : part.start) p.start[at(row) + 1] = p.start[at(row)] + length, ++row;
    p.column.insert(p.column.end(), part.column.begin(), part.column.end());
    p.value.insert(p.value.end(), part.value.begin(), part.value.end());
    part = RowMatrix{};
  }
  return p;
}

Eigen::VectorXd diagonal_of(const RowMatrix& a, bool& positive) {
  Eigen::VectorXd d = Eigen::VectorXd::Zero(a.rows);
  for_each_block(a.rows, [&](Eigen::Index first, Eigen::Index last) {
    for (auto i = int(first); i < int(last); ++i)
      for (std::size_t k = a.row_begin(i); k < a.row_end(i); ++k)
        if (a.column[k] == i) d[i] += a.value[k];
  });
  positive = (d.array() > 0).all() && d.allFinite();
  return d;
}

/// One Gauss–Seidel sweep on A x = b, forward or backward, in blocks of `block_rows` rows that run
/// in parallel (hybrid Gauss–Seidel): within a block the sweep uses the block's new values, across
/// blocks the values from before the sweep (`level.previous`). The solver orders the sites along a
/// space-filling curve, so most of a row's entries lie in its own block. `from_zero`: x = 0
/// before the sweep (the pre-smoothing), so no copy is needed.
void gauss_seidel(const Level& level, bool forward, bool from_zero) {
  const SingleRows& a = level.single;
  const int n = a.rows;
  const int* start = a.starts();
  const int* column = a.columns();
  const float* value = a.value.data();
  const unsigned char* crosses = level.crosses_blocks.data();
  const int blocks = (n + block_rows - 1) / block_rows;
  if (blocks > 1) {
    if (from_zero)
      level.previous.setZero(n);
    else
      copy(level.x, level.previous);
  }
#pragma omp parallel for schedule(static) if (blocks > 1)
  for (int block = 0; block < blocks; ++block) {
    const int first = block * block_rows, last = std::min(n, first + block_rows);
    for (int step = first; step < last; ++step) {
      const int i = forward ? step : first + last - 1 - step;
      // x_i += r_i / d_i: with d_i = a_ii this is x_i = (b_i − Σ_{j≠i} a_ij x_j) / a_ii.
      double residual = level.rhs[i];
      if (!crosses[i]) {  // most rows: no test per entry
        for (int k = start[i]; k < start[i + 1]; ++k) residual -= double(value[k]) * level.x[column[k]];
      } else {
        for (int k = start[i]; k < start[i + 1]; ++k) {
          const int j = column[k];
          residual -= double(value[k]) * (j >= first && j < last ? level.x[j] : level.previous[j]);
        }
      }
      // A product, not a division: the next row waits for this x_i.
      level.x[i] += residual * level.smoother_inverse[i];
    }
  }
}

/// The divisors of the hybrid Gauss–Seidel sweep: a_ii plus Σ |a_ij| over the row's entries in
/// other blocks (the "ℓ1" smoother of Baker, Falgout, Kolev and Yang, 2011). Plain a_ii would
/// treat those entries like undamped Jacobi, which diverges where they dominate a row; with the
/// ℓ1 term every sweep reduces the error in the energy norm. With a single block, a_ii.
/// `crosses_blocks` gets 1 for the rows with such entries (none with a single block).
Eigen::VectorXd smoother_diagonal(const RowMatrix& a, const Eigen::VectorXd& diagonal,
                                  std::vector<unsigned char>& crosses_blocks) {
  Eigen::VectorXd result = diagonal;
  crosses_blocks.assign(at(a.rows), 0);
  if (a.rows <= block_rows) return result;
  for_each_block(a.rows, [&](Eigen::Index first_row, Eigen::Index last_row) {
    for (auto i = int(first_row); i < int(last_row); ++i) {
      const int first = i / block_rows * block_rows, last = first + block_rows;
      for (std::size_t k = a.row_begin(i); k < a.row_end(i); ++k)
        if (a.column[k] < first || a.column[k] >= last) result[i] += std::abs(a.value[k]), crosses_blocks[at(i)] = 1;
    }
  });
  return result;
}

}  // namespace

struct MultigridSolver::Hierarchy {
  std::vector<Level> levels;
  bool reused = false;     // the coarse levels come from an earlier matrix
  bool rebuild = false;    // the next compute() builds every level afresh
  double fresh_rate = -1;  // convergence factor per iteration of the first solve after a build
  int fresh_iterations = 0;
  int builds = 0;
  void build(RowMatrix finest_matrix, const Settings& settings);
  /// Conjugate gradients preconditioned by one V-cycle, from x = 0.
  Eigen::VectorXd conjugate_gradients(const Eigen::VectorXd& rhs) const;
  Eigen::SimplicialLDLT<SparseMatrix> coarse;
  Eigen::ComputationInfo info = Eigen::Success;
  double tolerance = 1e-12;     // on ‖r‖₂ / ‖rhs‖₂
  Eigen::VectorXd scale;        // empty: no scaled criterion
  double scaled_tolerance = 0;  // on max_i scale_i·|r_i|
  int max_iterations = 200;
  mutable Eigen::ComputationInfo solve_info = Eigen::Success;
  mutable int last_iterations = 0;
  mutable double last_error = 0, last_scaled_error = 0;
  int smoothing_sweeps = 2;

  /// x ≈ A⁻¹ b on `levels[l]` (b in levels[l].rhs, result in levels[l].x)
  void cycle(std::size_t l) const {
    const Level& level = levels[l];
    if (l + 1 == levels.size()) {
      level.x = coarse.solve(level.rhs);
      return;
    }
    level.x.setZero();
    gauss_seidel(level, true, true);
    for (int sweep = 1; sweep < smoothing_sweeps; ++sweep) gauss_seidel(level, true, false);
    multiply(level.single, level.x, level.residual);
    for_each_block(level.residual.size(), [&](Eigen::Index first, Eigen::Index last) {
      for (Eigen::Index i = first; i < last; ++i) level.residual[i] = level.rhs[i] - level.residual[i];
    });
    multiply(level.restriction, level.residual, levels[l + 1].rhs);
    cycle(l + 1);
    const Eigen::VectorXd& coarse_x = levels[l + 1].x;
    const SingleRows& p = level.prolongation;
#pragma omp parallel for schedule(static) if (p.rows >= 2 * block_rows)
    for (int i = 0; i < p.rows; ++i) {
      double sum = 0;
      for (std::size_t k = p.row_begin(i); k < p.row_end(i); ++k) sum += double(p.value[k]) * coarse_x[p.column[k]];
      level.x[i] += sum;
    }
    for (int sweep = 0; sweep < smoothing_sweeps; ++sweep) gauss_seidel(level, false, false);
  }
};

MultigridSolver::MultigridSolver() : MultigridSolver(Settings{}) {}
MultigridSolver::MultigridSolver(const Settings& settings)
    : settings_(settings), hierarchy_(std::make_unique<Hierarchy>()) {}
MultigridSolver::MultigridSolver(MultigridSolver&&) noexcept = default;
MultigridSolver& MultigridSolver::operator=(MultigridSolver&&) noexcept = default;
MultigridSolver::~MultigridSolver() = default;

void MultigridSolver::compute(const SparseMatrix& matrix) {
  Hierarchy& h = *hierarchy_;
  const bool previous_built = h.info == Eigen::Success && h.levels.size() > 1;
  h.info = Eigen::Success;
  h.solve_info = Eigen::Success;
  if (matrix.rows() != matrix.cols() || !matrix.isCompressed() || settings_.smoothing_sweeps < 1) {
    h.levels.clear();
    h.info = Eigen::InvalidInput;
    return;
  }
  // Copies the input into `a`, whose arrays keep their capacity: the finest level of the last
  // hierarchy is overwritten in place rather than freed and allocated again (at 10⁶ unknowns
  // 100 MB of fresh pages per Newton step, which the kernel must zero).
  auto copy_into = [&matrix](RowMatrix& a) {
    a.rows = a.cols = static_cast<int>(matrix.rows());
    a.start.assign(matrix.outerIndexPtr(), matrix.outerIndexPtr() + matrix.outerSize() + 1);
    a.column.assign(matrix.innerIndexPtr(), matrix.innerIndexPtr() + matrix.nonZeros());
    a.value.assign(matrix.valuePtr(), matrix.valuePtr() + matrix.nonZeros());
  };
  // A matrix of the size of the last one (the next Newton step's Hessian) keeps the coarse levels
  // while they precondition well: only the finest level, where the smoother and the conjugate
  // gradients run, takes the new matrix.
  if (settings_.reuse_hierarchy && !h.rebuild && previous_built && h.levels.front().matrix.rows == matrix.rows()) {
    Level& finest = h.levels.front();
    copy_into(finest.matrix);
    bool positive = false;
    finest.diagonal = diagonal_of(finest.matrix, positive);
    if (!positive) {
      h.levels.clear();
      h.info = Eigen::NumericalIssue;
      return;
    }
    finest.smoother_inverse = smoother_diagonal(finest.matrix, finest.diagonal, finest.crosses_blocks).cwiseInverse();
    share_as_single(finest.matrix, finest.single);
    h.reused = true;
    return;
  }
  RowMatrix a;
  copy_into(a);
  h.build(std::move(a), settings_);
}

void MultigridSolver::Hierarchy::build(RowMatrix finest_matrix, const Settings& settings) {
  ++builds;
  smoothing_sweeps = settings.smoothing_sweeps;
  levels.clear();
  info = Eigen::Success;
  reused = false;
  rebuild = false;
  fresh_rate = -1;
  Level finest;
  finest.matrix = std::move(finest_matrix);
  levels.push_back(std::move(finest));
  for (;;) {
    Level& level = levels.back();
    bool positive = false;
    level.diagonal = diagonal_of(level.matrix, positive);
    if (!positive) {
      info = Eigen::NumericalIssue;
      return;
    }
    level.smoother_inverse = smoother_diagonal(level.matrix, level.diagonal, level.crosses_blocks).cwiseInverse();
    const int n = level.matrix.rows;
    level.rhs.resize(n), level.x.resize(n), level.residual.resize(n);
    if (n <= settings.coarse_size || static_cast<int>(levels.size()) >= settings.max_levels) break;
    int count = 0;
    const auto owner = aggregate(level.matrix, level.diagonal, settings.strength_threshold, count);
    if (4 * count > 3 * n || count == 0) break;  // the coarsening stalls: solve this level directly
    RowMatrix prolongation = smoothed_prolongation(level.matrix, level.diagonal, owner, count);
    RowMatrix restriction = transpose(prolongation);
    Level next;
    next.matrix = product(restriction, product(level.matrix, prolongation));
    level.prolongation = to_single(std::move(prolongation));
    level.restriction = to_single(std::move(restriction));
    levels.push_back(std::move(next));
  }
  // The coarsest level by a sparse LDLᵀ: small when the coarsening went well, and still exact
  // (if slower) when it stalled.
  const RowMatrix& coarsest = levels.back().matrix;
  SparseMatrix coarse_matrix(coarsest.rows, coarsest.rows);
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(coarsest.column.size());
  for (int i = 0; i < coarsest.rows; ++i)
    for (std::size_t k = coarsest.row_begin(i); k < coarsest.row_end(i); ++k)
      entries.emplace_back(coarsest.column[k], i, coarsest.value[k]);
  coarse_matrix.setFromTriplets(entries.begin(), entries.end());
  coarse.compute(coarse_matrix);
  // Only the conjugate gradients need a double-precision matrix, the finest.
  for (std::size_t l = 0; l < levels.size(); ++l)
    if (l == 0)
      share_as_single(levels[l].matrix, levels[l].single);
    else
      levels[l].single = to_single(std::move(levels[l].matrix));
  if (coarse.info() != Eigen::Success || !(coarse.vectorD().array() > 0).all()) info = Eigen::NumericalIssue;
}

Eigen::ComputationInfo MultigridSolver::info() const {
  return hierarchy_->info != Eigen::Success ? hierarchy_->info : hierarchy_->solve_info;
}

void MultigridSolver::setTolerance(double tolerance) {
  hierarchy_->tolerance = tolerance;
}

void MultigridSolver::set_scaled_tolerance(const Eigen::VectorXd& scale, double tolerance) {
  hierarchy_->scaled_tolerance = tolerance;
  hierarchy_->scale = scale;
}

void MultigridSolver::setMaxIterations(int iterations) {
  hierarchy_->max_iterations = iterations;
}

int MultigridSolver::iterations() const {
  return hierarchy_->last_iterations;
}

double MultigridSolver::error() const {
  return hierarchy_->last_error;
}

double MultigridSolver::scaled_error() const {
  return hierarchy_->last_scaled_error;
}

int MultigridSolver::builds() const {
  return hierarchy_->builds;
}

std::vector<Eigen::Index> MultigridSolver::level_sizes() const {
  std::vector<Eigen::Index> sizes;
  for (const auto& level : hierarchy_->levels) sizes.push_back(level.single.rows);
  return sizes;
}

SparseMatrix MultigridSolver::matrix() const {
  if (hierarchy_->levels.empty()) return {};
  // the input was symmetric, so its compressed columns, kept as rows, are the matrix itself
  const RowMatrix& a = hierarchy_->levels.front().matrix;
  return Eigen::Map<const SparseMatrix>(a.rows, a.cols, static_cast<Eigen::Index>(a.column.size()), a.start.data(),
                                        a.column.data(), a.value.data());
}

Eigen::VectorXd MultigridSolver::solve(const Eigen::VectorXd& rhs) const {
  Hierarchy& h = *hierarchy_;
  const int limit = h.max_iterations;
  // Reused coarse levels that need far more iterations than fresh ones are not worth keeping.
  if (h.reused && h.fresh_iterations > 0) h.max_iterations = std::min(limit, 3 * h.fresh_iterations + 10);
  Eigen::VectorXd x = h.conjugate_gradients(rhs);
  h.max_iterations = limit;
  if (h.reused && h.solve_info != Eigen::Success && h.info == Eigen::Success) {
    // The earlier coarse levels no longer fit this matrix: build them from it and solve again.
    const int spent = h.last_iterations;
    h.build(std::move(h.levels.front().matrix), settings_);
    if (h.info != Eigen::Success) {
      h.solve_info = h.info;
      return x;
    }
    x = h.conjugate_gradients(rhs);
    h.last_iterations += spent;
  } else if (h.solve_info == Eigen::Success && h.last_iterations > 0) {
    // Convergence factor per iteration; the coarse levels are rebuilt at the next compute() once
    // reusing them has halved the digits gained per iteration.
    const double rate = std::pow(std::max(h.last_error, 1e-300), 1.0 / h.last_iterations);
    if (!h.reused) {
      h.fresh_rate = rate, h.fresh_iterations = h.last_iterations;
    } else if (h.fresh_rate > 0 && rate > std::sqrt(h.fresh_rate)) {
      h.rebuild = true;
    }
  }
  return x;
}

Eigen::VectorXd MultigridSolver::Hierarchy::conjugate_gradients(const Eigen::VectorXd& rhs) const {
  const Hierarchy& h = *this;
  h.last_iterations = 0;
  const auto n = static_cast<Eigen::Index>(h.levels.empty() ? 0 : h.levels.front().matrix.rows);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  if (h.info != Eigen::Success || rhs.size() != n) {
    h.solve_info = Eigen::InvalidInput;
    return x;
  }
  const bool scaled = h.scale.size() == n;
  const double rhs_norm = std::sqrt(dot(rhs, rhs));
  auto converged = [&](const Eigen::VectorXd& r) {  // records both measures
    const double r_norm = std::sqrt(dot(r, r));
    h.last_error = rhs_norm > 0 ? r_norm / rhs_norm : r_norm;
    h.last_scaled_error = scaled ? block_reduce(
                                       n, 0.0, [&](Eigen::Index i) { return h.scale[i] * std::abs(r[i]); },
                                       [](double a, double b) { return std::max(a, b); })
                                 : 0.0;
    return h.last_error <= h.tolerance && h.last_scaled_error <= h.scaled_tolerance;
  };
  Eigen::VectorXd r = rhs, z(n), p(n), q(n);
  if (converged(r)) {
    h.solve_info = Eigen::Success;
    return x;
  }
  const Level& finest = h.levels.front();
  auto precondition = [&](const Eigen::VectorXd& residual, Eigen::VectorXd& out) {
    copy(residual, finest.rhs);
    h.cycle(0);
    out.swap(finest.x);  // the next cycle overwrites finest.x anyway
  };
  precondition(r, z);
  copy(z, p);
  double rz = dot(r, z);
  h.solve_info = Eigen::NoConvergence;
  while (h.last_iterations < h.max_iterations) {
    multiply(finest.matrix, p, q);
    const double pq = dot(p, q);
    if (!(pq > 0) || !std::isfinite(pq)) {
      h.solve_info = Eigen::NumericalIssue;
      break;
    }
    const double alpha = rz / pq;
    for_each_block(n, [&](Eigen::Index first, Eigen::Index last) {
      for (Eigen::Index i = first; i < last; ++i) x[i] += alpha * p[i], r[i] -= alpha * q[i];
    });
    ++h.last_iterations;
    bool restart = false;
    if (converged(r)) {
      // The updated residual drifts from b − A·x by round-off: decide on the true one, and
      // restart from it when they disagree.
      multiply(finest.matrix, x, q);
      r = rhs - q;
      if (converged(r)) {
        h.solve_info = Eigen::Success;
        break;
      }
      restart = true;
    }
    precondition(r, z);
    const double rz_next = dot(r, z), beta = restart ? 0.0 : rz_next / rz;
    for_each_block(n, [&](Eigen::Index first, Eigen::Index last) {
      for (Eigen::Index i = first; i < last; ++i) p[i] = z[i] + beta * p[i];
    });
    rz = rz_next;
  }
  return x;
}

}  // namespace sdot
