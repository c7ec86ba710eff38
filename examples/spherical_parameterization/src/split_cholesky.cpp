#include "split_cholesky.hpp"

#include "mesh.hpp"  // u

#ifdef SDOT_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#include <algorithm>
#include <exception>
#include <future>
#include <sdot/linear_solver.hpp>
#include <stdexcept>
#include <string>

namespace sphparam {
namespace {

/// A split pays when its estimated cost, the larger half plus the dense separator work, is below
/// this share of the whole factorisation's.
constexpr double worthwhile_share = 0.8;
/// Separators of more columns are not tried: their dense Schur complement costs more than a half.
constexpr std::size_t max_separator = 3000;

}  // namespace

SplitCholesky::~SplitCholesky() {
  for (auto& half : halves_) {
    if (half.factor) cholmod_free_factor(&half.factor, &half.common);
    if (half.started) cholmod_finish(&half.common);
  }
}

void SplitCholesky::on_both_halves(const std::function<void(int)>& work) {
  auto second = std::async(std::launch::async, [&work] {
    const sdot::detail::SerialOpenMpRegions serial;  // CHOLMOD's own OpenMP teams: see there
    work(0);
  });
  std::exception_ptr error;
  try {
    const sdot::detail::SerialOpenMpRegions serial;
    work(1);
  } catch (...) {
    error = std::current_exception();
  }
  second.get();
  if (error) std::rethrow_exception(error);
}

bool SplitCholesky::plan(const cholmod_factor& analysis) {
  if (!analysis.is_super || analysis.itype != CHOLMOD_INT) return false;
  const std::size_t n = analysis.n, supernodes = analysis.nsuper;
  const int* super = static_cast<const int*>(analysis.super);
  const int* patterns = static_cast<const int*>(analysis.pi);
  const int* rows = static_cast<const int*>(analysis.s);
  // The supernodal elimination tree and the flops of each subtree (a supernode of nscol columns
  // and nsrow rows: the sum of (nsrow - c)² over its columns c).
  std::vector<int> supernode_of(n);
  for (std::size_t s = 0; s < supernodes; ++s)
    for (int j = super[s]; j < super[s + 1]; ++j) supernode_of[u(j)] = static_cast<int>(s);
  std::vector<int> parent(supernodes, -1);
  std::vector<std::vector<int>> children(supernodes);
  std::vector<double> subtree(supernodes, 0.0);
  std::vector<int> frontier;  // the roots, then the subtrees right below the separator
  for (std::size_t s = 0; s < supernodes; ++s) {
    const int columns = super[s + 1] - super[s], height = patterns[s + 1] - patterns[s];
    for (int c = 0; c < columns; ++c) subtree[s] += static_cast<double>(height - c) * (height - c);
    if (height > columns) {
      parent[s] = supernode_of[u(rows[patterns[s] + columns])];
      if (u(parent[s]) <= s) return false;  // not postordered
      children[u(parent[s])].push_back(static_cast<int>(s));
    } else {
      frontier.push_back(static_cast<int>(s));
    }
  }
  for (std::size_t s = 0; s < supernodes; ++s)
    if (parent[s] >= 0) subtree[u(parent[s])] += subtree[s];
  double total = 0;
  for (int root : frontier) total += subtree[u(root)];

  // The separator: the top of the tree, grown one supernode at a time (the heaviest subtree
  // below it) while that makes the split cheaper; the subtrees below it go to the halves, the
  // heaviest first to the lighter half.
  std::vector<int> top, best_top, best_frontier;
  std::vector<int> best_bins;
  double best_cost = total;
  std::size_t separator_columns = 0;
  while (!frontier.empty() && separator_columns <= max_separator) {
    std::sort(frontier.begin(), frontier.end(), [&](int a, int b) { return subtree[u(a)] > subtree[u(b)]; });
    std::array<double, 2> load{0, 0};
    std::vector<int> bins(frontier.size());
    for (std::size_t k = 0; k < frontier.size(); ++k) {
      bins[k] = load[1] < load[0] ? 1 : 0;
      load[u(bins[k])] += subtree[u(frontier[k])];
    }
    // The dense work: each half's separator block and its product L_SS,i L_SS,iᵀ (the halves at
    // once), then the Schur complement's factorisation, about m³/3 flops each.
    const auto m = static_cast<double>(separator_columns);
    const double cost = std::max(load[0], load[1]) + m * m * m;
    if (load[0] > 0 && load[1] > 0 && cost < best_cost)
      best_cost = cost, best_top = top, best_frontier = frontier, best_bins = bins;
    const int heaviest = frontier.front();
    frontier.erase(frontier.begin());
    top.push_back(heaviest);
    separator_columns += u(super[u(heaviest) + 1] - super[u(heaviest)]);
    frontier.insert(frontier.end(), children[u(heaviest)].begin(), children[u(heaviest)].end());
  }
  if (best_top.empty() || best_cost > worthwhile_share * total) return false;

  // Each column's part: 0 or 1 (a half) or 2 (the separator), parents before children.
  std::vector<int> part_of_supernode(supernodes, -1);
  for (int s : best_top) part_of_supernode[u(s)] = 2;
  for (std::size_t k = 0; k < best_frontier.size(); ++k) part_of_supernode[u(best_frontier[k])] = best_bins[k];
  for (std::size_t s = supernodes; s-- > 0;)
    if (part_of_supernode[s] < 0) part_of_supernode[s] = part_of_supernode[u(parent[s])];
  part_.resize(n);
  for (std::size_t j = 0; j < n; ++j) part_[j] = part_of_supernode[u(supernode_of[j])];
  return true;
}

bool SplitCholesky::prepare(const Eigen::SparseMatrix<double>& lower, const StartCommon& start) {
  const std::size_t n = part_.size();
  if (n == 0 || static_cast<std::size_t>(lower.rows()) != n) return false;
  const std::vector<int>& part = part_;
  std::vector<int> position(n);
  for (std::size_t j = 0; j < n; ++j) {
    auto& list = part[j] == 2 ? separator_ : halves_[u(part[j])].columns;
    position[j] = static_cast<int>(list.size());
    list.push_back(static_cast<int>(j));
  }

  // S_i: the separator's columns that half i touches.
  const int* outer = lower.outerIndexPtr();
  const int* inner = lower.innerIndexPtr();
  std::array<std::vector<int>, 2> local_in_separator;  // separator position -> M_i's S_i index, or -1
  for (auto& local : local_in_separator) local.assign(separator_.size(), -1);
  for (std::size_t c = 0; c < n; ++c)
    for (int k = outer[c]; k < outer[c + 1]; ++k) {
      const int r = inner[k], pr = part[u(r)], pc = part[c];
      if (pr != 2 && pc != 2 && pr != pc) return false;  // the halves would be coupled
      if ((pr == 2) != (pc == 2)) local_in_separator[u(pr == 2 ? pc : pr)][u(position[pr == 2 ? u(r) : c])] = 0;
    }
  for (std::size_t i = 0; i < 2; ++i) {
    int next = static_cast<int>(halves_[i].columns.size());
    for (std::size_t p = 0; p < separator_.size(); ++p)
      if (local_in_separator[i][p] == 0) {
        local_in_separator[i][p] = next++;
        halves_[i].separator_slots.push_back(static_cast<int>(p));
      }
  }

  // M_i's lower triangles; each value remembers the value of K it comes from (its id, exact in a
  // double, is summed with nothing since K's entries are distinct).
  std::array<std::vector<Eigen::Triplet<double>>, 2> entries;
  std::array<std::vector<int>, 2> diagonals;  // per half, how many S_i diagonal entries it got
  std::array<std::vector<int>, 2> sources;
  std::array<std::vector<double>, 2> scales;
  for (std::size_t i = 0; i < 2; ++i) diagonals[i].assign(halves_[i].separator_slots.size(), 0);
  const auto add = [&](std::size_t i, int row, int column, int source, double scale) {
    entries[i].emplace_back(std::max(row, column), std::min(row, column), static_cast<double>(entries[i].size()));
    sources[i].push_back(source);
    scales[i].push_back(scale);
  };
  for (std::size_t c = 0; c < n; ++c)
    for (int k = outer[c]; k < outer[c + 1]; ++k) {
      const int r = inner[k], pr = part[u(r)], pc = part[c];
      if (pr != 2 && pc != 2) {
        add(u(pr), position[u(r)], position[c], k, 1.0);
      } else if (pr != 2 || pc != 2) {
        const std::size_t i = u(pr == 2 ? pc : pr);
        const int s = pr == 2 ? r : static_cast<int>(c), j = pr == 2 ? static_cast<int>(c) : r;
        add(i, local_in_separator[i][u(position[u(s)])], position[u(j)], k, 1.0);
      } else {
        separator_entries_.push_back({k, position[u(r)], position[c]});
        if (r != static_cast<int>(c)) continue;
        for (std::size_t i = 0; i < 2; ++i) {
          const int local = local_in_separator[i][u(position[c])];
          if (local < 0) continue;
          add(i, local, local, k, 2.0);
          ++diagonals[i][u(local) - halves_[i].columns.size()];
        }
      }
    }
  for (const auto& counts : diagonals)
    if (std::find(counts.begin(), counts.end(), 0) != counts.end()) return false;  // no diagonal entry

  std::array<bool, 2> analysed{false, false};
  on_both_halves([&](int which) {
    Half& half = halves_[u(which)];
    const auto size = static_cast<Eigen::Index>(half.columns.size() + half.separator_slots.size());
    half.matrix.resize(size, size);
    half.matrix.setFromTriplets(entries[u(which)].begin(), entries[u(which)].end());
    half.matrix.makeCompressed();
    half.value_source.resize(static_cast<std::size_t>(half.matrix.nonZeros()));
    half.value_scale.resize(half.value_source.size());
    for (std::size_t v = 0; v < half.value_source.size(); ++v) {
      const auto id = static_cast<std::size_t>(half.matrix.valuePtr()[v]);
      half.value_source[v] = sources[u(which)][id];
      half.value_scale[v] = scales[u(which)][id];
    }
    start(half.common);
    half.started = true;
    // M_i in its given order (K's, the separator last), which is already fill-reducing.
    half.common.nmethods = 1;
    half.common.method[0].ordering = CHOLMOD_NATURAL;
    half.common.postorder = 0;
    cholmod_sparse view = Eigen::viewAsCholmod(half.matrix);
    view.stype = -1;
    half.factor = cholmod_analyze(&view, &half.common);
    analysed[u(which)] = half.factor && half.factor->is_super && half.factor->ordering == CHOLMOD_NATURAL;
  });
  return analysed[0] && analysed[1];
}

void SplitCholesky::factorize_half(Half& half, const double* values) {
  double* own = half.matrix.valuePtr();
  for (std::size_t v = 0; v < half.value_source.size(); ++v)
    own[v] = half.value_scale[v] * values[half.value_source[v]];
  cholmod_sparse view = Eigen::viewAsCholmod(half.matrix);
  view.stype = -1;
  if (!cholmod_factorize(&view, half.factor, &half.common) || half.common.status != CHOLMOD_OK)
    throw std::runtime_error("the Tutte system could not be factorised (CHOLMOD status " +
                             std::to_string(half.common.status) + ")");
  // L_SS,i: the columns from m_i on, whichever supernodes hold them.
  const auto m = static_cast<int>(half.columns.size());
  const auto size = static_cast<Eigen::Index>(half.separator_slots.size());
  half.corner.setZero(size, size);
  const int* super = static_cast<const int*>(half.factor->super);
  const int* patterns = static_cast<const int*>(half.factor->pi);
  const int* starts = static_cast<const int*>(half.factor->px);
  const int* rows = static_cast<const int*>(half.factor->s);
  const auto* x = static_cast<const double*>(half.factor->x);
  for (std::size_t s = 0; s < half.factor->nsuper; ++s) {
    if (super[s + 1] <= m) continue;
    const int height = patterns[s + 1] - patterns[s];
    for (int c = std::max(super[s], m) - super[s]; c < super[s + 1] - super[s]; ++c)
      for (int r = c; r < height; ++r)
        half.corner(rows[patterns[s] + r] - m, super[s] + c - m) = x[starts[s] + r + c * height];
  }
  // L_SS,i L_SS,iᵀ's lower triangle by column blocks, each a product of the rows below and the
  // block's columns of L_SS,i up to its last: about m³/3 flops, where a rank update of the whole
  // triangle (Eigen's) takes m³.
  constexpr Eigen::Index block = 64;
  half.update.setZero(size, size);
  for (Eigen::Index first = 0; first < size; first += block) {
    const Eigen::Index width = std::min(block, size - first), depth = first + width;
    half.update.block(first, first, size - first, width).noalias() =
        half.corner.block(first, 0, size - first, depth) * half.corner.block(first, 0, width, depth).transpose();
  }
}

void SplitCholesky::factorize(const Eigen::SparseMatrix<double>& lower) {
  const double* values = lower.valuePtr();
  on_both_halves([&](int which) { factorize_half(halves_[u(which)], values); });
  // K_SS − Σ (C_i − L_SS,i L_SS,iᵀ), lower triangle.
  const auto size = static_cast<Eigen::Index>(separator_.size());
  Eigen::MatrixXd schur = Eigen::MatrixXd::Zero(size, size);
  for (const auto& [value, row, column] : separator_entries_) schur(row, column) += values[value];
  const Eigen::VectorXd diagonal = schur.diagonal();
  for (auto& half : halves_) {
    const auto local = static_cast<Eigen::Index>(half.separator_slots.size());
    for (Eigen::Index b = 0; b < local; ++b) {
      const int column = half.separator_slots[u(b)];
      schur(column, column) -= 2 * diagonal(column);
      for (Eigen::Index a = b; a < local; ++a) schur(half.separator_slots[u(a)], column) += half.update(a, b);
    }
  }
  schur_.compute(schur);
  if (schur_.info() != Eigen::Success)
    throw std::runtime_error("the Tutte system could not be factorised (its separator's Schur complement)");
}

void SplitCholesky::forward_half(Half& half, const Eigen::MatrixXd& rhs) {
  const auto m = static_cast<Eigen::Index>(half.columns.size());
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(m + static_cast<Eigen::Index>(half.separator_slots.size()), rhs.cols());
  for (Eigen::Index j = 0; j < m; ++j) b.row(j) = rhs.row(half.columns[u(j)]);
  cholmod_dense view = Eigen::viewAsCholmod(b);
  cholmod_dense* y = cholmod_solve(CHOLMOD_L, half.factor, &view, &half.common);
  if (!y) throw std::runtime_error("the Tutte system could not be solved (CHOLMOD)");
  half.forward = Eigen::Map<const Eigen::MatrixXd>(static_cast<const double*>(y->x), b.rows(), b.cols());
  cholmod_free_dense(&y, &half.common);
}

void SplitCholesky::backward_half(Half& half, const Eigen::MatrixXd& separator_solution, Eigen::MatrixXd& out) {
  const auto m = static_cast<Eigen::Index>(half.columns.size());
  const auto local = static_cast<Eigen::Index>(half.separator_slots.size());
  Eigen::MatrixXd on_separator(local, separator_solution.cols());
  for (Eigen::Index a = 0; a < local; ++a) on_separator.row(a) = separator_solution.row(half.separator_slots[u(a)]);
  half.forward.bottomRows(local) = half.corner.triangularView<Eigen::Lower>().transpose() * on_separator;
  cholmod_dense view = Eigen::viewAsCholmod(half.forward);
  cholmod_dense* w = cholmod_solve(CHOLMOD_Lt, half.factor, &view, &half.common);
  if (!w) throw std::runtime_error("the Tutte system could not be solved (CHOLMOD)");
  const Eigen::Map<const Eigen::MatrixXd> solution(static_cast<const double*>(w->x), half.forward.rows(),
                                                   half.forward.cols());
  for (Eigen::Index j = 0; j < m; ++j) out.row(half.columns[u(j)]) = solution.row(j);
  cholmod_free_dense(&w, &half.common);
}

Eigen::MatrixXd SplitCholesky::solve(const Eigen::MatrixXd& rhs) {
  // Forward: L_i [y_i; t_i] = [b_i; 0] gives B_iᵀ A_i⁻¹ b_i = −L_SS,i t_i.
  on_both_halves([&](int which) { forward_half(halves_[u(which)], rhs); });
  Eigen::MatrixXd separator_rhs(static_cast<Eigen::Index>(separator_.size()), rhs.cols());
  for (std::size_t p = 0; p < separator_.size(); ++p)
    separator_rhs.row(static_cast<Eigen::Index>(p)) = rhs.row(separator_[p]);
  for (auto& half : halves_) {
    const auto local = static_cast<Eigen::Index>(half.separator_slots.size());
    const Eigen::MatrixXd pushed = half.corner.triangularView<Eigen::Lower>() * half.forward.bottomRows(local);
    for (Eigen::Index a = 0; a < local; ++a) separator_rhs.row(half.separator_slots[u(a)]) += pushed.row(a);
  }
  const Eigen::MatrixXd separator_solution = schur_.solve(separator_rhs);
  // Backward: L_iᵀ [x_i; x_S] = [y_i; L_SS,iᵀ x_S] gives x_i = A_i⁻¹ (b_i − B_i x_S).
  Eigen::MatrixXd out(rhs.rows(), rhs.cols());
  on_both_halves([&](int which) { backward_half(halves_[u(which)], separator_solution, out); });
  for (std::size_t p = 0; p < separator_.size(); ++p)
    out.row(separator_[p]) = separator_solution.row(static_cast<Eigen::Index>(p));
  return out;
}

}  // namespace sphparam
#endif
