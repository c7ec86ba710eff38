// Initial map, Möbius balancing, untangling, area optimization, subdivision.
#include "param.hpp"
#include "lane_math.hpp"
#include "split_cholesky.hpp"

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <future>
#include <iterator>
#include <limits>
#include <memory>
#include <numeric>
#include <sdot/linear_solver.hpp>
#include <stdexcept>
#include <unordered_map>

namespace sphparam {
namespace {

double cot_angle(const Vec3& p, const Vec3& q, const Vec3& r) {  // cot of the angle at p
  const Vec3 a = q - p, b = r - p;
  const double s = a.cross(b).norm();
  return a.dot(b) / std::max(s, 1e-300);
}

#ifdef SDOT_HAVE_CHOLMOD
/// P with (P A Pᵀ) in the pivot order of a METIS nested dissection of the lower triangle of A
/// (through CHOLMOD, which links METIS); empty when that fails.
Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> nested_dissection(
    const Eigen::SparseMatrix<double>& matrix) {
  Eigen::SparseMatrix<double> lower = matrix.triangularView<Eigen::Lower>();
  lower.makeCompressed();
  cholmod_sparse view = Eigen::viewAsCholmod(lower);
  view.stype = -1;  // the lower triangle of a symmetric matrix
  std::vector<int> pivots(static_cast<std::size_t>(matrix.rows()));
  cholmod_common common;
  cholmod_start(&common);
  const int ok = cholmod_metis(&view, nullptr, 0, 1, pivots.data(), &common);
  cholmod_finish(&common);
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> order;
  if (!ok) return order;
  order.resize(matrix.rows());
  for (int k = 0; k < static_cast<int>(pivots.size()); ++k) order.indices()[pivots[static_cast<std::size_t>(k)]] = k;
  return order;
}
#endif

/// The nested-dissection driver of both orders below. A node is a range of `ids` (mesh
/// vertices); `split(node, first, last, part, labels)` marks each vertex of the node with part 0,
/// part 1 or 2 (the separator), which are ordered in that order: the separator takes the node's
/// last positions, each part becomes a node, down to 8 vertices. `label` holds the node of each
/// unknown (−1: a fixed or ordered vertex); `split` may take fresh labels (`labels++`) for
/// marks of its own, and returns false for a node it cannot split, which is ordered as it is.
/// `index` numbers the unknowns (−1: a fixed vertex); the result lists them in pivot order.
template <class Split>
std::vector<int> dissect(const std::vector<int>& index, int unknowns, std::vector<int>& label, Split split) {
  constexpr int leaf = 8;
  std::vector<int> ids;  // mesh vertices, regrouped node by node
  ids.reserve(u(unknowns));
  for (std::size_t v = 0; v < index.size(); ++v)
    if (index[v] >= 0) ids.push_back(static_cast<int>(v));
  label.assign(index.size(), -1);
  for (int v : ids) label[u(v)] = 0;
  int labels = 1;
  std::vector<int> order(u(unknowns));
  std::vector<int> scratch(u(unknowns));
  std::vector<char> part(index.size(), 0);
  struct Node {
    int begin, end, last;  // ids[begin, end) take the order positions [last - size, last)
  };
  std::vector<Node> stack{{0, unknowns, unknowns}};
  while (!stack.empty()) {
    const Node node = stack.back();
    stack.pop_back();
    const int size = node.end - node.begin;
    const auto first = ids.begin() + node.begin, last = ids.begin() + node.end;
    if (size <= leaf || !split(label[u(*first)], first, last, part, labels)) {
      for (int k = 0; k < size; ++k) {
        label[u(ids[u(node.begin + k)])] = -1;
        order[u(node.last - size + k)] = index[u(ids[u(node.begin + k)])];
      }
      continue;
    }
    int counts[3] = {0, 0, 0};
    for (auto it = first; it != last; ++it) ++counts[static_cast<int>(part[u(*it)])];
    int fill[3] = {0, counts[0], counts[0] + counts[1]};
    for (auto it = first; it != last; ++it) scratch[u(fill[static_cast<int>(part[u(*it)])]++)] = *it;
    std::copy(scratch.begin(), scratch.begin() + size, first);
    for (int k = counts[0] + counts[1]; k < size; ++k) {
      const int v = ids[u(node.begin + k)];
      label[u(v)] = -1;
      order[u(node.last - size + k)] = index[u(v)];
    }
    const int left = labels++, right = labels++;
    for (int k = 0; k < counts[0]; ++k) label[u(ids[u(node.begin + k)])] = left;
    for (int k = counts[0]; k < counts[0] + counts[1]; ++k) label[u(ids[u(node.begin + k)])] = right;
    const int left_end = node.begin + counts[0], right_end = left_end + counts[1];
    const int right_last = node.last - (size - counts[0] - counts[1]);
    stack.push_back({node.begin, left_end, right_last - counts[1]});
    stack.push_back({left_end, right_end, right_last});
  }
  return order;
}

using IdIterator = std::vector<int>::iterator;

}  // namespace

/// An elimination order of the Tutte systems from the mesh's geometry: nested dissection by
/// planes. A node's vertices are split at the median of their widest coordinate; the vertices of
/// the smaller side that have a neighbour on the other side form the separator. O(n log n):
/// 0.8 s at 2.1 M unknowns, where CHOLMOD's default analysis (AMD, then METIS) took 13 s for a
/// factor 1.3 times smaller (Loop-subdivided igea_134k: 1.6e8 against 1.2e8 entries,
/// factorisation 5.8 s against 4.2 s).
std::vector<int> plane_nested_dissection(const Topology& topo, const std::vector<Vec3>& points,
                                         const std::vector<int>& index, int unknowns) {
  std::vector<int> label;
  auto touches = [&](int v, int other) {
    for (int k = topo.nbr_offsets[u(v)]; k < topo.nbr_offsets[u(v) + 1]; ++k)
      if (label[u(topo.nbrs[u(k)])] == other) return true;
    return false;
  };
  auto split = [&](int, IdIterator first, IdIterator last, std::vector<char>& part, int& labels) {
    Vec3 low = points[u(*first)], high = low;
    for (auto it = first; it != last; ++it) low = low.cwiseMin(points[u(*it)]), high = high.cwiseMax(points[u(*it)]);
    int axis = 0;
    (high - low).maxCoeff(&axis);
    const auto middle = first + (last - first) / 2;
    std::nth_element(first, middle, last, [&](int a, int b) { return points[u(a)][axis] < points[u(b)][axis]; });
    const int left = labels++, right = labels++;
    for (auto it = first; it != middle; ++it) label[u(*it)] = left;
    for (auto it = middle; it != last; ++it) label[u(*it)] = right;
    int left_boundary = 0, right_boundary = 0;
    for (auto it = first; it != middle; ++it) left_boundary += touches(*it, right);
    for (auto it = middle; it != last; ++it) right_boundary += touches(*it, left);
    const int cut = left_boundary <= right_boundary ? left : right, other = cut == left ? right : left;
    for (auto it = first; it != last; ++it) {
      const int v = *it;
      part[u(v)] = label[u(v)] == cut && touches(v, other) ? 2 : (label[u(v)] == left ? 0 : 1);
    }
    return true;
  };
  return dissect(index, unknowns, label, split);
}

/// Another elimination order of the Tutte systems, from the mesh graph alone: nested dissection
/// by breadth-first level structures (George and Liu). A node's vertices are layered by their
/// graph distance to a pseudo-peripheral vertex of the node; the layer where the count passes
/// half the node is the separator (only its vertices that touch the next layer); a node that is
/// not connected splits into the part reached and the rest, with no separator. O(n log n).
/// The layers of a surface are rings around the start, so a thin part (a spike, a finger) is cut
/// across, where a plane may cut it lengthwise: spiky_120k (scripts/hard_meshes.py), 1.8e9 flops
/// a factorisation against 4.5e9 in the plane order; capsule40_120k, a straight tube, 1.0e9
/// against 7.7e8; igea_134k Loop-subdivided twice, 1.9e11 against 1.4e11 (CHOLMOD's
/// symbolic analysis). About 2.5 times the plane order's time (2.1 M unknowns: 1.8 s).
std::vector<int> graph_nested_dissection(const Topology& topo, const std::vector<int>& index, int unknowns) {
  std::vector<int> label;
  // the last search that reached a vertex, and its distance there
  std::vector<std::pair<int, int>> reached(index.size(), {-1, 0});
  int searches = 0;
  std::vector<int> queue;
  queue.reserve(u(unknowns));
  std::vector<int> layer_sizes;
  // Breadth-first search from `root` over the vertices labelled `node`: `queue` lists them by
  // distance.
  auto search = [&](int root, int node) {
    const int id = searches++;
    queue.clear();
    queue.push_back(root);
    reached[u(root)] = {id, 0};
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const int v = queue[head], next = reached[u(v)].second + 1;
      for (int k = topo.nbr_offsets[u(v)]; k < topo.nbr_offsets[u(v) + 1]; ++k) {
        const int w = topo.nbrs[u(k)];
        if (label[u(w)] == node && reached[u(w)].first != id) reached[u(w)] = {id, next}, queue.push_back(w);
      }
    }
    return id;
  };
  auto split = [&](int me, IdIterator first, IdIterator last, std::vector<char>& part, int&) {
    const auto size = static_cast<std::size_t>(last - first);
    // a pseudo-peripheral vertex: the last one reached from the node's first vertex
    int id = search(*first, me);
    if (queue.size() == size) id = search(queue.back(), me);
    const int depth = reached[u(queue.back())].second;
    if (queue.size() == size && depth < 2) return false;  // a clique-like node: nothing to dissect
    if (queue.size() < size) {                            // not connected: the part reached and the rest
      for (auto it = first; it != last; ++it) part[u(*it)] = reached[u(*it)].first == id ? 0 : 1;
      return true;
    }
    layer_sizes.assign(u(depth) + 1, 0);
    for (int v : queue) ++layer_sizes[u(reached[u(v)].second)];
    int middle = 1;
    std::size_t below = u(layer_sizes[0]);
    while (middle < depth - 1 && below + u(layer_sizes[u(middle)]) < size / 2) below += u(layer_sizes[u(middle++)]);
    for (int v : queue) {
      const int d = reached[u(v)].second;
      char p = d < middle ? 0 : 1;
      if (d == middle) {
        p = 0;  // joins the first part unless it touches the next layer
        for (int k = topo.nbr_offsets[u(v)]; k < topo.nbr_offsets[u(v) + 1]; ++k) {
          const int w = topo.nbrs[u(k)];
          if (label[u(w)] == me && reached[u(w)].first == id && reached[u(w)].second == middle + 1) {
            p = 2;
            break;
          }
        }
      }
      part[u(v)] = p;
    }
    return true;
  };
  return dissect(index, unknowns, label, split);
}

namespace {

/// The Tutte systems (same pattern for every reweighting): Eigen's LDLᵀ in the order of one
/// METIS nested dissection (bunny_35k, 8 factorisations: 0.037 s each against 0.064 s with AMD,
/// for one ordering of 0.1 s), or CHOLMOD's supernodal Cholesky from `cholmod_from_unknowns`,
/// analysed once, in the order (set_order_makers: the plane, then the graph nested dissection)
/// its symbolic analysis finds the fewest flops for.
/// On CHOLMOD's path, from the second system on, a split that the first system's analysis
/// planned (SplitCholesky: a small separator between two halves, as across a tube) factorises
/// and solves the halves on two threads (capsule40_120k, 14 systems: the initial map 2.77-2.81 s
/// -> 1.99-2.02 s).
/// The METIS ordering runs on the second core while the first system is factorised with AMD;
/// the reweightings (if any) use it. The matrix comes as triplets, in the same order at every
/// reweighting: from the second, their values go straight to their places in the permuted lower
/// triangle, instead of through setFromTriplets and a symmetric permutation each time.
class LaplacianSolver {
 public:
  using Triplets = std::vector<Eigen::Triplet<double>>;
  explicit LaplacianSolver(Eigen::Index unknowns)
      : use_cholmod_(sdot::has_cholmod() && unknowns >= cholmod_from_unknowns) {}
  LaplacianSolver(const LaplacianSolver&) = delete;
  LaplacianSolver& operator=(const LaplacianSolver&) = delete;
  ~LaplacianSolver() {
#ifdef SDOT_HAVE_CHOLMOD
    if (factor_) cholmod_free_factor(&factor_, &common_);
    if (common_started_) cholmod_finish(&common_);
#endif
  }
  /// True when only the lower triangle's triplets (row >= column) are read.
  [[nodiscard]] bool lower_only() const {
    return use_cholmod_;
  }
  /// Makers of elimination orders for the CHOLMOD path (each order lists the unknowns in pivot
  /// order). The first factorisation makes and analyses them at once, each on a thread of its
  /// own, and keeps the one with the fewest flops, a later one only with 20 % fewer than an
  /// earlier one (brain_48k: 7.2e8 flops in the graph order against 8.8e8 in the plane order,
  /// but the initial map 0.22 s against 0.20 s; the plane order's separators are larger and
  /// fewer, its supernodes larger). None: AMD.
  void set_order_makers(std::vector<std::function<std::vector<int>()>> makers) {
    // started now, while the caller assembles the first system (2 M unknowns: about 0.5 s)
    for (auto& make : makers) pending_orders_.push_back(std::async(std::launch::async, std::move(make)));
  }
  /// Factorises the matrix of `triplets` (duplicates summed), which it may release.
  void factorize(Eigen::Index n, Triplets&& triplets) {
#ifdef SDOT_HAVE_CHOLMOD
    if (use_cholmod_) {
      // One BLAS thread for the supernodes, whatever the machine: OpenBLAS splits its work by
      // thread count, so a fixed count keeps the map the same bit for bit everywhere. Two threads
      // hand every supernode's kernels to a second thread and back, a futex wake and a
      // sched_yield wait each, and their waiting thread then polls beside sdot's OpenMP loops;
      // with the coarser supernodes below, one thread was as fast or faster (capsule40_120k, 16
      // factorisations: 2.19-2.41 s against 2.49-3.20 s with two).
      sdot::detail::set_blas_threads(1);
      // The first system in the chosen order, as CHOLMOD permutes it; from the second, the
      // permuted lower triangle in place (write_in_place).
      Eigen::SparseMatrix<double> first_system;
      if (!factor_ && !split_) {
        first_system.resize(n, n);
        first_system.setFromTriplets(triplets.begin(), triplets.end());
        first_system.makeCompressed();
        analyse(first_system);
      } else {
        write_in_place(n, triplets);
        if (planned_split_) start_split();
      }
      Triplets().swap(triplets);  // released before the factorisation (2 M unknowns: 240 MB)
      if (split_) {
        split_->factorize(permuted_);
        return;
      }
      cholmod_sparse view = Eigen::viewAsCholmod(in_place_ ? permuted_ : first_system);
      view.stype = -1;
      bool factorised = false;
      {
        const sdot::detail::SerialOpenMpRegions serial;  // CHOLMOD's own teams: see there
        factorised = factor_ && cholmod_factorize(&view, factor_, &common_) && common_.status == CHOLMOD_OK;
      }
      if (!factorised)
        throw std::runtime_error("the Tutte system could not be factorised (CHOLMOD status " +
                                 std::to_string(common_.status) + ")");
      return;
    }
    if (!use_cholmod_ && pivots_.size() == n && slots_.size() == triplets.size()) {
      write_values(triplets);
      ordered_ldlt_.factorize(permuted_);
      return;
    }
#endif
    Eigen::SparseMatrix<double> matrix(n, n);
    matrix.setFromTriplets(triplets.begin(), triplets.end());
#ifdef SDOT_HAVE_CHOLMOD
    if (!analysed_ && !pending_order_.valid())
      pending_order_ = std::async(std::launch::async, [copy = matrix] { return nested_dissection(copy); });
    else if (pending_order_.valid())
      pivots_ = pending_order_.get();
    if (pivots_.size() == n) {
      place_in_pivot_order(n, triplets);
      ordered_ldlt_.analyzePattern(permuted_);
      ordered_ldlt_.factorize(permuted_);
      return;
    }
#endif
    if (!analysed_) ldlt_.analyzePattern(matrix), analysed_ = true;
    ldlt_.factorize(matrix);
  }
  /// Solves for every column of `rhs` (the CHOLMOD path: both at once, one pass over the factor).
  [[nodiscard]] Eigen::MatrixXd solve(const Eigen::MatrixXd& rhs) {
#ifdef SDOT_HAVE_CHOLMOD
    if (split_) return pivots_.transpose() * split_->solve(pivots_ * rhs);
    if (use_cholmod_) {
      Eigen::MatrixXd b = in_place_ ? Eigen::MatrixXd(pivots_ * rhs) : rhs;  // in place: a factor of P A Pᵀ
      cholmod_dense view = Eigen::viewAsCholmod(b);
      cholmod_dense* x = cholmod_solve(CHOLMOD_A, factor_, &view, &common_);
      if (!x) throw std::runtime_error("the Tutte system could not be solved (CHOLMOD)");
      const Eigen::Map<const Eigen::MatrixXd> solution(static_cast<const double*>(x->x), rhs.rows(), rhs.cols());
      Eigen::MatrixXd out = in_place_ ? Eigen::MatrixXd(pivots_.transpose() * solution) : Eigen::MatrixXd(solution);
      cholmod_free_dense(&x, &common_);
      return out;
    }
#endif
    Eigen::MatrixXd out(rhs.rows(), rhs.cols());
    for (Eigen::Index column = 0; column < rhs.cols(); ++column) out.col(column) = solve_one(rhs.col(column));
    return out;
  }

 private:
  [[nodiscard]] Eigen::VectorXd solve_one(const Eigen::VectorXd& rhs) const {
#ifdef SDOT_HAVE_CHOLMOD
    if (pivots_.size() == rhs.size()) return pivots_.transpose() * Eigen::VectorXd(ordered_ldlt_.solve(pivots_ * rhs));
#endif
    return ldlt_.solve(rhs);
  }

#ifdef SDOT_HAVE_CHOLMOD
  /// The symbolic factorisation of the first system on CHOLMOD's path, in the order of the
  /// makers set_order_makers prefers (AMD without one). The analyses run at once, the first on
  /// this thread, each other one on a thread of its own with its own cholmod_common (CHOLMOD is
  /// thread-safe so); a factor keeps no pointer to the common that made it.
  void analyse(Eigen::SparseMatrix<double>& lower) {
    // Coarser supernodes than CHOLMOD's defaults (nrelax 4, 16, 48; zrelax 0.8, 0.1, 0.05) up to
    // coarse_supernodes_up_to unknowns: a few more explicit zeros, but a third of the supernodes,
    // each of which costs a BLAS call per update and, in SuiteSparse 5, an OpenMP region (a
    // futex wake even on one thread). capsule40_120k, 16 factorisations: 11,840 supernodes and
    // 4.0-4.2 s -> 4,398 and 2.2-2.4 s; spiky_120k's third factorisation 0.26 s -> 0.16 s. At
    // brain scale the supernodes are large anyway: brain_48k and igea_134k Loop-subdivided twice
    // (775k and 2.1M unknowns) took 24.6 and 42.2 s with them against 23.4 and 41.2 s without,
    // and peaked at 1,496 and 3,515 MB against 1,123 and 2,590 MB.
    const auto start = [coarse = lower.rows() <= coarse_supernodes_up_to](cholmod_common& common) {
      start_common(common, coarse);
      common.nmethods = 1;
      common.method[0].ordering = CHOLMOD_GIVEN;
    };
    start(common_);
    common_started_ = true;
    cholmod_sparse view = Eigen::viewAsCholmod(lower);
    view.stype = -1;
    struct Analysis {
      cholmod_factor* factor = nullptr;
      double flops = std::numeric_limits<double>::infinity();
    };
    const auto n = static_cast<std::size_t>(lower.rows());
    const auto run = [&view, n](std::future<std::vector<int>>& pending_order, cholmod_common* common) {
      std::vector<int> order = pending_order.get();
      Analysis a;
      if (order.size() == n) a.factor = cholmod_analyze_p(&view, order.data(), nullptr, 0, common);
      if (a.factor) a.flops = common->fl;
      return a;
    };
    std::vector<cholmod_common> others(pending_orders_.size() > 1 ? pending_orders_.size() - 1 : 0);
    std::vector<std::future<Analysis>> pending;
    for (std::size_t k = 0; k < others.size(); ++k) {
      start(others[k]);
      pending.push_back(std::async(std::launch::async, run, std::ref(pending_orders_[k + 1]), &others[k]));
    }
    Analysis best;
    if (!pending_orders_.empty()) best = run(pending_orders_[0], &common_);
    for (auto& p : pending) {
      Analysis a = p.get();
      if (a.factor && a.flops < 0.8 * best.flops) std::swap(a, best);
      if (a.factor) cholmod_free_factor(&a.factor, &common_);
    }
    for (auto& common : others) cholmod_finish(&common);
    pending_orders_.clear();
    factor_ = best.factor;
    if (!factor_) common_.method[0].ordering = CHOLMOD_AMD, factor_ = cholmod_analyze(&view, &common_);
    if (!factor_) return;
    // planned before the factor's values are allocated: the plan's scratch never adds to them
    planned_split_ = std::make_unique<SplitCholesky>();
    if (!planned_split_->plan(*factor_)) planned_split_.reset();
    fault_in_numeric_factor();
  }

  /// CHOLMOD's settings for the Tutte systems: coarse supernodes (see analyse) up to
  /// coarse_supernodes_up_to unknowns.
  static void start_common(cholmod_common& common, bool coarse) {
    cholmod_start(&common);
    common.supernodal = CHOLMOD_SUPERNODAL;
    if (coarse) {
      common.nrelax[0] = 16, common.nrelax[1] = 64, common.nrelax[2] = 256;
      common.zrelax[0] = 0.8, common.zrelax[1] = 0.2, common.zrelax[2] = 0.1;
    }
    common.final_asis = 1;
  }

  /// From the second system on (a single one would not repay the setup: the halves' matrices,
  /// their analyses and their values' first writes, brain_48k's initial map 0.21 s -> 0.33 s):
  /// the halves of the split that the first system's analysis planned.
  void start_split() {
    auto split = std::move(planned_split_);
    const bool coarse = permuted_.rows() <= coarse_supernodes_up_to;
    if (!split->prepare(permuted_, [coarse](cholmod_common& common) { start_common(common, coarse); })) return;
    split_ = std::move(split);
    cholmod_free_factor(&factor_, &common_);
  }

  /// Allocates the factor's values (as cholmod_super_numeric would at the first factorisation)
  /// and writes to each of their pages on every thread. A page's first write is a page fault,
  /// which on a virtual machine whose host has taken back the free memory costs about 2 ms per
  /// MB on one thread: spiky_120k's factor is 126 MB, and its first numeric factorisation took
  /// 0.45-0.47 s instead of 0.17-0.18 s for the next ones, 12 s after the previous run; with the
  /// pages written first on two threads, 0.13 s and then 0.19 s. Back to back with the previous
  /// run, 0.19-0.41 s against 0.007 s and 0.18 s. The factorisation overwrites every value.
  void fault_in_numeric_factor() {
    if (!cholmod_change_factor(CHOLMOD_REAL, 1, 1, 1, 1, factor_, &common_) || !factor_->x) return;
    auto* values = static_cast<double*>(factor_->x);
    const auto size = static_cast<std::ptrdiff_t>(factor_->xsize);
    constexpr std::ptrdiff_t page = 4096 / sizeof(double);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t k = 0; k < size; k += page) values[k] = 0;
  }

  /// From the second system on CHOLMOD's path: the lower triangle of P A Pᵀ (P: the first
  /// factor's pivot order, the order then the elimination tree's postorder) in its own natural
  /// order, its values written in place. cholmod_factorize then reads the matrix as it is, where
  /// with a permutation it transposes it twice (cholmod_factorize.c), and the triplets skip
  /// setFromTriplets (capsule40_120k, 16 systems: about 0.02 s a system of 0.19 s). The first
  /// system goes the plain way: a single one (most meshes) would not repay building the permuted
  /// copy and its slots.
  void write_in_place(Eigen::Index n, const Triplets& triplets) {
    if (in_place_) {
      write_values(triplets);
      return;
    }
    pivots_.resize(n);
    auto* pivot_order = static_cast<int*>(factor_->Perm);
    for (Eigen::Index k = 0; k < n; ++k) pivots_.indices()[pivot_order[k]] = static_cast<int>(k);
    place_in_pivot_order(n, triplets);
    // The factor's symbolic structure is that of P A Pᵀ already: with the identity as its order
    // it factorises permuted_ as it is. A second analysis in natural order gave the same
    // structure, but as a new factor, whose values (126 MB on spiky_120k) were faulted in and
    // zeroed again.
    for (Eigen::Index k = 0; k < n; ++k) pivot_order[k] = static_cast<int>(k);
    if (auto* inverse = static_cast<int*>(factor_->IPerm))
      for (Eigen::Index k = 0; k < n; ++k) inverse[k] = static_cast<int>(k);
    factor_->ordering = CHOLMOD_NATURAL;
    in_place_ = true;
  }

  /// permuted_: the lower triangle of P A Pᵀ, A given by its triplets (the lower ones are read);
  /// slots_: where each triplet's value goes in it (−1: an upper one, unused).
  void place_in_pivot_order(Eigen::Index n, const Triplets& triplets) {
    std::vector<Eigen::Triplet<double>> moved;
    moved.reserve(triplets.size());
    for (const auto& t : triplets) {
      if (t.row() < t.col()) continue;
      const int r = pivots_.indices()[t.row()], c = pivots_.indices()[t.col()];
      moved.emplace_back(std::max(r, c), std::min(r, c), t.value());
    }
    permuted_.resize(n, n);
    permuted_.setFromTriplets(moved.begin(), moved.end());
    permuted_.makeCompressed();
    slots_.assign(triplets.size(), -1);
    for (std::size_t t = 0, m = 0; t < triplets.size(); ++t) {
      if (triplets[t].row() < triplets[t].col()) continue;
      const auto& placed = moved[m++];
      const int* first = permuted_.innerIndexPtr() + permuted_.outerIndexPtr()[placed.col()];
      const int* last = permuted_.innerIndexPtr() + permuted_.outerIndexPtr()[placed.col() + 1];
      slots_[t] = static_cast<int>(std::find(first, last, placed.row()) - permuted_.innerIndexPtr());
    }
  }

  /// The values of a system of the same triplets as place_in_pivot_order's, in place.
  void write_values(const Triplets& triplets) {
    double* values = permuted_.valuePtr();
    std::fill(values, values + permuted_.nonZeros(), 0.0);
    for (std::size_t t = 0; t < triplets.size(); ++t)
      if (slots_[t] >= 0) values[slots_[t]] += triplets[t].value();
  }
#endif

  bool use_cholmod_ = false, analysed_ = false;
  std::vector<std::future<std::vector<int>>> pending_orders_;  // set_order_makers
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt_;    // AMD: the first system (and without METIS)
#ifdef SDOT_HAVE_CHOLMOD
  cholmod_common common_{};
  bool common_started_ = false;
  cholmod_factor* factor_ = nullptr;
  bool in_place_ = false;                         // write_in_place
  std::unique_ptr<SplitCholesky> planned_split_;  // analyse: a split of the second system on
  std::unique_ptr<SplitCholesky> split_;          // start_split
  std::future<Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>> pending_order_;
  // P, mapping an unknown to its pivot position: METIS's (Eigen's path) or CHOLMOD's (in place)
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> pivots_;
  Eigen::SparseMatrix<double> permuted_;  // lower triangle of P A Pᵀ
  std::vector<int> slots_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> ordered_ldlt_;
#endif
};

}  // namespace

Topology::Topology(const Mesh& mesh) {
  // Flat arrays only, no vector per vertex: the coarse-to-fine map builds one per level
  // (capsule_120k: 98 levels, 0.41 s with a vector per vertex).
  const std::size_t nv = mesh.vertices.size();
  face_offsets.assign(nv + 1, 0);
  for (const auto& f : mesh.faces)
    for (int v : f) ++face_offsets[u(v) + 1];
  for (std::size_t i = 0; i < nv; ++i) face_offsets[i + 1] += face_offsets[i];
  vfaces.resize(u(face_offsets[nv]));
  std::vector<int> fill(face_offsets.begin(), face_offsets.end() - 1);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (int v : mesh.faces[f]) vfaces[u(fill[u(v)]++)] = static_cast<int>(f);
  // each face gives its two other vertices to each of its vertices: 2 candidates per face, then
  // each vertex's candidates sorted and made unique in place
  std::vector<int> candidates(2 * vfaces.size());
  for (std::size_t i = 0; i < nv; ++i)
    for (int q = face_offsets[i]; q < face_offsets[i + 1]; ++q) {
      const auto& f = mesh.faces[u(vfaces[u(q)])];
      const int c = f[0] == static_cast<int>(i) ? 0 : (f[1] == static_cast<int>(i) ? 1 : 2);
      candidates[u(2 * q)] = f[u((c + 1) % 3)];
      candidates[u(2 * q + 1)] = f[u((c + 2) % 3)];
    }
  nbr_offsets.assign(nv + 1, 0);
  nbrs.clear();
  nbrs.reserve(vfaces.size());
  for (std::size_t i = 0; i < nv; ++i) {
    const auto first = candidates.begin() + 2 * face_offsets[i], last = candidates.begin() + 2 * face_offsets[i + 1];
    std::sort(first, last);
    nbrs.insert(nbrs.end(), first, std::unique(first, last));
    nbr_offsets[i + 1] = static_cast<int>(nbrs.size());
  }
}

std::vector<double> face_targets(const Mesh& mesh, const std::vector<double>& vertex_factors) {
  auto a = face_areas(mesh);
  double amax = 0;
  for (double x : a) amax = std::max(amax, x);
  const double floor = 1e-12 * amax;
  for (std::size_t f = 0; f < a.size(); ++f) {
    a[f] = std::max(a[f], floor);
    if (!vertex_factors.empty()) {
      const auto& t = mesh.faces[f];
      a[f] *= (vertex_factors[u(t[0])] + vertex_factors[u(t[1])] + vertex_factors[u(t[2])]) / 3.0;
    }
  }
  const double total = std::accumulate(a.begin(), a.end(), 0.0);
  for (double& x : a) x *= 4 * M_PI / total;
  return a;
}

std::vector<double> vertex_targets(const Mesh& mesh, const std::vector<double>& face_target) {
  std::vector<double> m(mesh.vertices.size(), 0.0);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (int v : mesh.faces[f]) m[u(v)] += face_target[f] / 3.0;
  return m;
}

std::vector<Vec3> tutte_sphere_map(const Mesh& mesh, const Topology& topo, const std::vector<double>& targets,
                                   int max_reweightings, int* reweightings, bool* crushed, bool uniform_weights,
                                   bool* crushed_below_rounding) {
  const std::size_t nv = mesh.vertices.size(), nf = mesh.faces.size();
  const auto areas = face_areas(mesh);
  const std::size_t outer = static_cast<std::size_t>(std::max_element(areas.begin(), areas.end()) - areas.begin());
  const Face ob = mesh.faces[outer];
  // Per-face half cotangents (clamped positive: Tutte needs positive weights).
  std::vector<std::array<double, 3>> fc(nf);
  double mean = 0;
  for (std::size_t f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const auto& t = mesh.faces[f];
      fc[f][u(k)] = 0.5 * cot_angle(mesh.vertices[u(t[u((k + 2) % 3)])], mesh.vertices[u(t[u(k)])],
                                    mesh.vertices[u(t[u((k + 1) % 3)])]);  // edge (k, k+1), opposite corner k+2
      mean += std::abs(fc[f][u(k)]);
    }
  mean /= static_cast<double>(3 * nf);
  for (auto& c : fc)
    for (double& x : c) x = uniform_weights ? 1.0 : std::max(x, 0.02 * mean);

  std::vector<int> index(nv, -1);
  const int b[3] = {ob[0], ob[1], ob[2]};
  Eigen::Vector2d bpos[3];
  for (int k = 0; k < 3; ++k) {
    // The outer face is traversed clockwise in the plane (the other faces are counter-clockwise).
    const double t = -2 * M_PI * k / 3.0;
    bpos[k] = Eigen::Vector2d(std::cos(t), std::sin(t));
  }
  int n = 0;
  for (std::size_t i = 0; i < nv; ++i)
    if (static_cast<int>(i) != b[0] && static_cast<int>(i) != b[1] && static_cast<int>(i) != b[2]) index[i] = n++;
  std::vector<double> sigma(nf, 1.0);  // stretch factors (image area / target) of the last map
  LaplacianSolver solver(n);
  if (solver.lower_only())
    solver.set_order_makers({[&] { return plane_nested_dissection(topo, mesh.vertices, index, n); },
                             [&] { return graph_nested_dissection(topo, index, n); }});
  const bool lower_only = solver.lower_only();
  std::vector<Vec3> s(nv);
  int done = 0;
  bool still_crushed = false, below_rounding = false, deeply_crushed = false;
  std::vector<double> quantiles;  // the 0.5 % quantile of the log stretch after each solve
  constexpr int window = 4;       // reweightings over which progress is judged
  // A deeply crushed map (below e^-20, see there) is reweighted by up to e^±10 a solve, until e^-6.
  constexpr double deep_clamp = 10.0, deep_enough = -6.0, deep_below = -20.0;
  for (int iteration = 0;; ++iteration) {
    std::vector<Eigen::Triplet<double>> trips;
    trips.reserve((lower_only ? 3 : 6) * nf + nv);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 2);
    std::vector<double> diag(nv, 0.0);
    for (std::size_t f = 0; f < nf; ++f) {
      const auto& t = mesh.faces[f];
      for (int k = 0; k < 3; ++k) {
        const int i = t[u(k)], j = t[u((k + 1) % 3)];
        const double w = fc[f][u(k)] * sigma[f];
        diag[u(i)] += w, diag[u(j)] += w;
        for (int pass = 0; pass < 2; ++pass) {
          const int r = pass ? j : i, c = pass ? i : j;
          if (index[u(r)] < 0) continue;
          if (index[u(c)] >= 0) {
            if (!lower_only || index[u(r)] > index[u(c)]) trips.emplace_back(index[u(r)], index[u(c)], -w);
          } else {
            for (int q = 0; q < 3; ++q)
              if (b[q] == c) rhs.row(index[u(r)]) += w * bpos[q].transpose();
          }
        }
      }
    }
    for (std::size_t i = 0; i < nv; ++i)
      if (index[i] >= 0) trips.emplace_back(index[i], index[i], diag[i]);
    solver.factorize(n, std::move(trips));
    const Eigen::MatrixXd z = solver.solve(rhs);
    std::vector<Eigen::Vector2d> planar(nv);
    for (std::size_t i = 0; i < nv; ++i) {
      if (index[i] >= 0) {
        planar[i] = z.row(index[i]).transpose();
      } else {
        for (int c = 0; c < 3; ++c)
          if (b[c] == static_cast<int>(i)) planar[i] = bpos[c];
      }
      const Eigen::Vector2d& p = planar[i];
      // Inverse stereographic projection from the north pole; the plane is mirrored (y -> -y)
      // so that counter-clockwise planar faces become outward-oriented spherical faces.
      const double x = p.x(), y = -p.y(), r2 = x * x + y * y;
      s[i] = Vec3(2 * x, 2 * y, r2 - 1) / (r2 + 1);
    }
    std::size_t sphere_flips = count_flips(mesh, s);
    if (sphere_flips > nf / 2) {
      for (auto& q : s) q.y() = -q.y();
      sphere_flips = count_flips(mesh, s);
    }
    if (targets.empty()) break;
    // Stretch-weighted Laplacian (SEM-like, but with positive weights, so every iterate is a
    // valid planar embedding): crushed regions get weaker springs and open up. The stretch is
    // measured in the plane (area × the stereographic factor 4/(1+r²)²): crushed faces are
    // 1e-12 across, accurate there but below the resolution of points on the unit sphere.
    std::vector<double> logs(nf, 0.0);
    std::size_t vanished = 0;  // faces whose vertices coincide in the plane (area 0 in doubles)
    for (std::size_t f = 0; f < nf; ++f) {
      if (f == outer) continue;
      const auto& t = mesh.faces[f];
      const Eigen::Vector2d e1 = planar[u(t[1])] - planar[u(t[0])], e2 = planar[u(t[2])] - planar[u(t[0])];
      const double area = 0.5 * std::abs(e1.x() * e2.y() - e1.y() * e2.x());
      const double r2 = ((planar[u(t[0])] + planar[u(t[1])] + planar[u(t[2])]) / 3).squaredNorm();
      const double stretched = area * 4 / ((1 + r2) * (1 + r2));
      vanished += !(stretched > 1e-300);
      logs[f] = std::log(std::max(stretched, 1e-300) / targets[f]);
    }
    {
      std::vector<double> sorted = logs;  // global scale is arbitrary before balancing: centre on the median
      std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(nf / 2), sorted.end());
      const double median = sorted[nf / 2];
      for (double& x : logs) x -= median;
    }
    std::vector<double> sorted = logs;
    const std::size_t q = sorted.size() / 200;  // 0.5% quantile of log stretch
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(q), sorted.end());
    // Still crushed below e^-20 after 4 reweightings: a tube-like part, which the clamped
    // reweighting opens by about e^1 per solve (a capsule 40 radii long, 100k vertices: from
    // e^-33 to e^-10 in 40 solves, 6.1 s, then an OT with 4 continuation stages, 4.2 s). From
    // there each face's factor may change by up to e^±10 per solve, and e^-6, which the OT
    // takes without continuation, is enough (that capsule: 14 solves, the whole run 10.2 s →
    // 3.5 s, final area mean|d| 0.053 → 0.040). Milder crushing keeps e^±4 and e^-4 (after 4
    // reweightings arm.off is at e^-13.8 and armadillo_43k at e^-10.6; the spiky spheres stop
    // after 2).
    // A first reweighting that gains less than e^1 below e^-20 tells the same at once: the maps
    // that e^±4 opens gain 2-3 per solve from the start (arm.off from e^-22.6, cow_igl from
    // e^-36.2), a tube nothing in its first four (capsule40_120k: e^-32.5, -33.2, -32.5, -31.9,
    // -31.5; 14 solves instead of 16, the initial map 2.84-3.06 s -> 2.62-2.70 s, the final
    // area mean|d| the same, 0.0368).
    if (sorted[q] < deep_below && (done == window || (done == 1 && sorted[q] - quantiles.front() < 1.0)))
      deeply_crushed = true;
    // The goal: a plain Tutte map above e^-4 needs no reweighting; a reweighted one stops above
    // e^-6, which the OT takes without continuation. Going on to e^-4 creeps by e^0.2-0.3 a solve
    // (cones_25k: e^-5.4, -5.0, -4.8, ... -4.1, 10 solves) and left the spiky shapes' OT more
    // folds that stuck: the cones case at seeds 2-8, 25k and 60k, area mean|d| lower on all 14
    // (0.1209 -> 0.0966 on average, 52 s -> 33 s in all); 32 test spheres with 4-8 spikes 12-16
    // radii long, lower on 24 of 32 (0.0907 -> 0.0721, 75 s -> 46 s). docs: Pipeline, step 1.
    const double enough = done == 0 ? -4.0 : deep_enough;
    still_crushed = sorted[q] <= enough;
    // Less than 0.25 gained over 4 reweightings: the crushed parts are tubes whose crushing
    // reweighting cannot undo (param.hpp, hierarchical_sphere_map); more solves only cost time.
    quantiles.push_back(sorted[q]);
    // Faces whose area is below 1e-28 (edges about 1e-14 long) are below the resolution of points
    // on the unit sphere: their vertices coincide there (tubes_25k: 0.5 % of the faces at e^-616
    // of their targets; cow_igl, the most crushed shared mesh, at e^-10.8).
    // The planar map is an embedding, so a face flipped on the sphere is one whose vertices the
    // projection rounded together: more than 1 % of them and the OT cannot separate the sites
    // either (a capsule 60 radii long, 25k vertices: 13 % at the stall, then through the OT 28 s,
    // 1,085 fallbacks and area mean|d| 0.44; at 5k vertices 57 faces left flipped. cow_igl, the
    // most crushed shared mesh: 0.14 %).
    below_rounding =
        sorted[q] + std::log(4 * M_PI / static_cast<double>(nf)) < std::log(1e-28) || sphere_flips * 100 > nf;
    // No region crushed by more than e^-4 (e^-6): good enough for OT. Out of reweightings, the
    // crushing of this last map is what the caller's fallbacks judge (with 0 reweightings allowed
    // a capsule 40 radii long went to the OT at e^-33: 220 s and 2,306 faces left flipped).
    if (!still_crushed || iteration >= max_reweightings) break;
    // Stalled, besides less than 0.25 gained over 4 reweightings (above):
    // - more than 0.5 % of the faces still of area 0 in the plane after a reweighting: their
    //   vertices coincide in doubles, and no reweighting can measure, let alone undo, a crushing
    //   below that (tubes_120k and capsule_120k: the 0.5 % quantile stays at the floor, e^-585
    //   to e^-617, through all 5 or 6 reweightings before the plain stall, about 1 s);
    // - a deeply crushed map whose pace over its first 4 reweightings by e^±10 would not reach
    //   e^-6 within the reweightings left (a capsule 60 radii long, 25k vertices: 0.2 a
    //   reweighting from e^-33, with 6 % of its faces rounded flat on the sphere: the
    //   coarse-to-fine map, 1.1 s and area mean|d| 0.098, against 40 reweightings, the OT,
    //   1.5 s and 0.113).
    const bool full_window = quantiles.size() > std::size_t{window};
    const double gain = full_window ? quantiles.back() - quantiles[quantiles.size() - 1 - std::size_t{window}] : 0.0;
    // - a map so crushed that the reweightings left could not reach e^-6 even at the deep clamp's
    //   e^10 each, the most any face's weight may change in one, and more than any reweighting
    //   ever gained (e^6.2 on cow_igl): the tubes and capsules, at e^-585 to e^-617, take one
    //   Tutte system fewer (capsule_120k's initial map 2.87-2.94 s -> 2.59-2.60 s).
    const bool stalled = (full_window && gain < 0.25) || (done >= 1 && vanished > q) ||
                         (deeply_crushed && done >= 2 * window &&
                          quantiles.back() + gain / window * (max_reweightings - done) < enough) ||
                         sorted[q] + deep_clamp * (max_reweightings - done) < deep_enough;
    if (stalled && (crushed || below_rounding)) break;
    // the full stretch (exponent 1) converges in half the reweightings of its square root
    // (bunny_35k: 7 against 14) to the same OT result
    // Between e^-20 and e^-6 the crushed side (weaker springs) takes up to e^-10 a solve and the
    // stretched side keeps e^4. A crushed face opens by a third to two thirds of its weight's
    // change (armadillo_43k at e^±4: e^-18.9, -16.1, -14.0, -12.1, -10.6, ... -3.0); larger steps
    // on the stretched side overshoot (a symmetric e^±5: bunny_35k's OT 6 -> 9 Newton
    // iterations, here 6). Against e^±4: reweightings armadillo_43k 10 -> 5, bunny_35k 7 -> 4,
    // blub 9 -> 5, elephant 3 -> 1; the final area mean|d| the same or lower on all 34 shared and
    // hard meshes (armadillo_43k 0.0219 -> 0.0196, spiky_25k 0.0549 -> 0.0492), at up to 2 more
    // OT Newton iterations (elephant 4 -> 6, spiky_25k 7 -> 9). A map that starts below e^-20
    // keeps e^±4 until it is judged deeply crushed (above, by the pace of those steps): arm.off,
    // from e^-22.6, took 8 reweightings instead of 13 in the band, but its OT 2 more Newton
    // iterations whose line searches built 11-15 diagrams each before a step of 2^-15 to 2^-6
    // emptied no cell (the whole map 0.53-0.56 s -> 0.56-0.60 s).
    const bool moderately_crushed =
        quantiles.front() >= deep_below && sorted[q] < deep_enough && sorted[q] >= deep_below;
    const double shrink = deeply_crushed || moderately_crushed ? deep_clamp : 4.0;
    const double grow = deeply_crushed ? deep_clamp : 4.0;
    for (std::size_t f = 0; f < nf; ++f) sigma[f] *= std::exp(std::clamp(logs[f], -shrink, grow));
    ++done;
  }
  if (reweightings) *reweightings = done;
  if (crushed) *crushed = still_crushed;
  if (crushed_below_rounding) *crushed_below_rounding = still_crushed && below_rounding;
  return s;
}

int mobius_balance(std::vector<Vec3>& points, const std::vector<double>& weights, double tol, int max_iterations) {
  const double total = std::accumulate(weights.begin(), weights.end(), 0.0);
  for (int it = 0; it < max_iterations; ++it) {
    Vec3 c = Vec3::Zero();
    for (std::size_t i = 0; i < points.size(); ++i) c += weights[i] * points[i];
    c /= total;
    const double r = c.norm();
    if (r <= tol) return it;
    // Ball automorphism φ_a(x) = (1 − |a|²)(x − a)/|x − a|² − a moves a to 0; step a = c/2
    // (damped: the weighted mean moves roughly twice as far as a).
    const Vec3 a = (r < 0.9 ? 0.5 : 0.45 / r) * c;
    const double a2 = a.squaredNorm();
    // each point on its own, in parallel: the same bits on any thread count (the mean above stays
    // serial, in point order; 2.1 M points, 17 iterations: 0.43 s -> 0.26 s)
    const auto count = static_cast<std::ptrdiff_t>(points.size());
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < count; ++i) {
      Vec3& x = points[u(i)];
      const Vec3 d = x - a;
      Vec3 y = (1 - a2) * d / d.squaredNorm() - a;
      x = y.normalized();
    }
  }
  return max_iterations;
}

std::size_t count_flips(const Mesh& mesh, const std::vector<Vec3>& s) {
  std::size_t flips = 0;
  for (const auto& f : mesh.faces)
    if (s[u(f[0])].dot(s[u(f[1])].cross(s[u(f[2])])) <= 0) ++flips;
  return flips;
}

std::size_t untangle(const Mesh& mesh, const Topology& topo, std::vector<Vec3>& s, int max_rounds, bool allow_free) {
  const std::size_t nv = s.size();
  auto det = [&](int f) {
    const auto& t = mesh.faces[u(f)];
    return s[u(t[0])].dot(s[u(t[1])].cross(s[u(t[2])]));
  };
  // flipped faces in the star of v, and the smallest det there
  auto star = [&](int v, int& bad, double& worst) {
    bad = 0;
    worst = 1e300;
    for (int k = topo.face_offsets[u(v)]; k < topo.face_offsets[u(v) + 1]; ++k) {
      const double d = det(topo.vfaces[u(k)]);
      if (d <= 0) ++bad;
      worst = std::min(worst, d);
    }
  };
  std::vector<char> active(nv, 0), next(nv, 0);
  std::size_t best = mesh.faces.size() + 1;
  int ring = 0, stagnant = 0;
  for (int round = 0; round < max_rounds; ++round) {
    std::fill(active.begin(), active.end(), 0);
    std::size_t flips = 0;
    for (std::size_t f = 0; f < mesh.faces.size(); ++f)
      if (det(static_cast<int>(f)) <= 0) {
        ++flips;
        for (int v : mesh.faces[f]) active[u(v)] = 1;
      }
    if (flips == 0) return 0;
    if (flips < best) {
      best = flips;
      stagnant = 0;
    } else if (++stagnant >= 2) {
      ring = std::min(ring + 1, 10);
      stagnant = 0;
    }
    for (int r = 0; r < ring; ++r) {
      next = active;
      for (std::size_t i = 0; i < nv; ++i)
        if (active[i])
          for (int k = topo.nbr_offsets[i]; k < topo.nbr_offsets[i + 1]; ++k) next[u(topo.nbrs[u(k)])] = 1;
      active.swap(next);
    }
    for (int sweep = 0; sweep < 3; ++sweep)
      for (std::size_t i = 0; i < nv; ++i) {
        if (!active[i]) continue;
        Vec3 m = Vec3::Zero();
        for (int k = topo.nbr_offsets[i]; k < topo.nbr_offsets[i + 1]; ++k) m += s[u(topo.nbrs[u(k)])];
        if (!(m.norm() > 1e-300)) continue;
        const Vec3 old = s[i];
        int bad0, bad1;
        double w0, w1;
        star(static_cast<int>(i), bad0, w0);
        s[i] = m.normalized();
        star(static_cast<int>(i), bad1, w1);
        // monotone: never create flips; around flips, move freely to make room
        // (after a few stuck rounds the ring grows and plain Laplacian smoothing takes over there)
        if ((ring < 3 || !allow_free) && (bad1 > bad0 || (bad1 == bad0 && bad0 > 0 && w1 < w0 && ring == 0)))
          s[i] = old;
      }
  }
  return count_flips(mesh, s);
}

std::vector<char> near_flipped_faces(const Mesh& mesh, const Topology& topo, const std::vector<Vec3>& s, int rings) {
  std::vector<char> near(s.size(), 0);
  std::vector<int> front;
  for (const auto& f : mesh.faces)
    if (s[u(f[0])].dot(s[u(f[1])].cross(s[u(f[2])])) <= 0)
      for (int v : f)
        if (!near[u(v)]) near[u(v)] = 1, front.push_back(v);
  for (int ring = 0; ring < rings; ++ring) {
    std::vector<int> next;
    for (int v : front)
      for (int k = topo.nbr_offsets[u(v)]; k < topo.nbr_offsets[u(v) + 1]; ++k)
        if (!near[u(topo.nbrs[u(k)])]) near[u(topo.nbrs[u(k)])] = 1, next.push_back(topo.nbrs[u(k)]);
    front.swap(next);
  }
  return near;
}

// ------------------------------------------------------------------------ patch re-embedding
// Garanzha et al.'s untangling energy (param.hpp); χ and the gradient are written out by hand.
double untangling_energy(const ChartPatch& patch, const Eigen::MatrixX2d& x, double eps, Eigen::VectorXd& gradient,
                         double& min_det) {
  constexpr double theta = 0.5;  // shape and area terms weighted equally
  gradient.setZero(2 * patch.free_count);
  min_det = std::numeric_limits<double>::infinity();
  double energy = 0;
  for (std::size_t f = 0; f < patch.faces.size(); ++f) {
    const auto& t = patch.faces[f];
    Eigen::Matrix2d edges;
    edges.col(0) = (x.row(t[1]) - x.row(t[0])).transpose();
    edges.col(1) = (x.row(t[2]) - x.row(t[0])).transpose();
    const Eigen::Matrix2d jacobian = edges * patch.reference_inverse[f];
    const double d = jacobian.determinant(), root = std::sqrt(eps * eps + d * d);
    // χ without cancellation when D < 0: (D + r)/2 = ε² / (2 (r - D))
    const double chi = d >= 0 ? 0.5 * (d + root) : eps * eps / (2 * (root - d));
    const double chi_prime = 0.5 * (1 + d / root), frobenius = jacobian.squaredNorm();
    min_det = std::min(min_det, d);
    energy += patch.reference_area[f] * ((1 - theta) * frobenius / chi + theta * (d * d + 1) / chi);
    Eigen::Matrix2d cofactor;  // ∂D/∂J
    cofactor << jacobian(1, 1), -jacobian(1, 0), -jacobian(0, 1), jacobian(0, 0);
    const double d_energy_d_det = -(1 - theta) * frobenius * chi_prime / (chi * chi) +
                                  theta * (2 * d / chi - (d * d + 1) * chi_prime / (chi * chi));
    const Eigen::Matrix2d d_energy_d_edges = patch.reference_area[f] *
                                             ((1 - theta) * 2 / chi * jacobian + d_energy_d_det * cofactor) *
                                             patch.reference_inverse[f].transpose();
    const Eigen::Vector2d per_corner[3] = {-d_energy_d_edges.col(0) - d_energy_d_edges.col(1), d_energy_d_edges.col(0),
                                           d_energy_d_edges.col(1)};
    for (int k = 0; k < 3; ++k)
      if (t[u(k)] < patch.free_count) gradient.segment<2>(2 * t[u(k)]) += per_corner[k];
  }
  return energy;
}

bool untangle_chart_patch(const ChartPatch& patch, Eigen::MatrixX2d& x, std::size_t* face_budget) {
  const Eigen::Index n = 2 * patch.free_count;
  Eigen::VectorXd gradient(n), trial_gradient(n), direction(n);
  double min_det = 0;
  untangling_energy(patch, x, 1.0, gradient, min_det);
  if (min_det > 0) return true;
  double eps = std::sqrt(1e-8 + 0.04 * min_det * min_det);
  auto place = [&](Eigen::MatrixX2d& target, const Eigen::VectorXd& free_values) {
    for (Eigen::Index i = 0; i < patch.free_count; ++i) target.row(i) = free_values.segment<2>(2 * i).transpose();
  };
  Eigen::VectorXd values(n);
  for (Eigen::Index i = 0; i < patch.free_count; ++i) values.segment<2>(2 * i) = x.row(i).transpose();
  Eigen::MatrixX2d trial = x;
  // a bound on the work (face evaluations): about 0.2 s, so a hopeless patch costs little
  std::size_t max_evaluations = std::max<std::size_t>(20'000'000 / std::max<std::size_t>(patch.faces.size(), 1), 100);
  if (face_budget)
    max_evaluations = std::min(max_evaluations, *face_budget / std::max<std::size_t>(patch.faces.size(), 1));
  std::size_t evaluations = 0;
  struct Charge {  // the face evaluations leave the budget whichever way the function returns
    std::size_t* budget;
    const std::size_t& used;
    std::size_t faces;
    ~Charge() {
      if (budget) *budget -= std::min(*budget, used * faces);
    }
  } charge{face_budget, evaluations, patch.faces.size()};
  // At most 8 ε steps: the patches it untangles did so by the fourth (arm.off, spiky_60k and
  // spiky_120k); a patch whose fixed ring leaves no room crawls through all of them with its
  // smallest det still far below 0 (spiky_120k: 6 such attempts before Floater's embedding on
  // 13 rings succeeded, 0.33 s with 30 steps).
  constexpr int max_epsilon_steps = 8;
  for (int outer = 0; outer < max_epsilon_steps && evaluations < max_evaluations; ++outer) {
    constexpr int history = 8;
    std::vector<Eigen::VectorXd> steps, gradient_changes;
    std::vector<double> rho;
    double energy = untangling_energy(patch, x, eps, gradient, min_det);
    const double start_energy = energy;
    for (int iteration = 0; iteration < 400 && evaluations < max_evaluations; ++iteration) {
      // two-loop recursion: direction = -H ∇E
      direction = -gradient;
      std::vector<double> alpha(steps.size());
      for (std::size_t k = steps.size(); k-- > 0;) {
        alpha[k] = rho[k] * steps[k].dot(direction);
        direction -= alpha[k] * gradient_changes[k];
      }
      if (!steps.empty())
        direction *= steps.back().dot(gradient_changes.back()) / gradient_changes.back().squaredNorm();
      for (std::size_t k = 0; k < steps.size(); ++k)
        direction += (alpha[k] - rho[k] * gradient_changes[k].dot(direction)) * steps[k];
      double slope = gradient.dot(direction);
      if (!(slope < 0))
        direction = -gradient, slope = -gradient.squaredNorm(), steps.clear(), gradient_changes.clear(), rho.clear();
      double step = 1, trial_energy = 0, trial_min_det = 0;
      bool accepted = false;
      for (int halving = 0; halving < 50 && !accepted; ++halving, step *= 0.5) {
        place(trial, values + step * direction);
        trial_energy = untangling_energy(patch, trial, eps, trial_gradient, trial_min_det);
        ++evaluations;
        accepted = std::isfinite(trial_energy) && trial_energy <= energy + 1e-4 * step * slope;
      }
      if (!accepted) break;
      step *= 2;  // undo the last halving of the loop
      const double decrease = energy - trial_energy;
      steps.push_back(step * direction);
      gradient_changes.push_back(trial_gradient - gradient);
      const double curvature = steps.back().dot(gradient_changes.back());
      if (curvature > 1e-300) {
        rho.push_back(1 / curvature);
      } else {
        steps.pop_back(), gradient_changes.pop_back();
      }
      if (static_cast<int>(steps.size()) > history)
        steps.erase(steps.begin()), gradient_changes.erase(gradient_changes.begin()), rho.erase(rho.begin());
      values += step * direction;
      x = trial, gradient = trial_gradient, energy = trial_energy, min_det = trial_min_det;
      if (decrease <= 1e-12 * std::abs(energy)) break;
    }
    if (min_det > 0) return true;
    // the paper's rule: ε shrinks faster when the energy decreased much at this ε (min_det <= 0)
    const double sigma = std::max(1 - energy / start_energy, 0.1);
    const double root = std::sqrt(eps * eps + min_det * min_det);
    const double mu = (1 - sigma) * (min_det >= 0 ? 0.5 * (min_det + root) : eps * eps / (2 * (root - min_det)));
    eps = std::max(2 * std::sqrt(mu * (mu - min_det)), 1e-12);
  }
  return false;
}

std::size_t repair_flips_by_patches(const Mesh& mesh, const Topology& topo, std::vector<Vec3>& s,
                                    const PatchRepairOptions& options, int* patches, int* chart_untangles) {
  const std::size_t nv = s.size();
  auto det = [&](std::size_t f) {
    const auto& t = mesh.faces[f];
    return s[u(t[0])].dot(s[u(t[1])].cross(s[u(t[2])]));
  };
  std::vector<int> depth(nv, -1), free_index(nv, -1);
  std::vector<char> tried_face(mesh.faces.size(), 0), in_patch(mesh.faces.size(), 0);
  // Work bounds that keep the repair linear in the mesh size however many faces are flipped:
  // the scan for the next flipped face moves forward (it starts again from 0 only after a pass
  // that repaired something), the BFS resets only what it touched, and the chart untangling of
  // all patches together gets at most `options.untangling_work_per_face` face evaluations per mesh face
  // (tubes_25k: 730 flipped faces took minutes at 2·10⁷ per patch, against the default
  // chart_untangling_work_per_face, 200).
  std::size_t untangle_budget = options.untangling_work_per_face * mesh.faces.size();
  std::size_t cursor = 0;
  bool repaired_in_pass = false;
  std::vector<int> touched;
  for (;;) {
    std::size_t seed = mesh.faces.size();
    for (; cursor < mesh.faces.size() && seed == mesh.faces.size(); ++cursor)
      if (!tried_face[cursor] && det(cursor) <= 0) seed = cursor;
    if (seed == mesh.faces.size()) {
      if (!repaired_in_pass) break;  // no flips left, or none we can still repair
      cursor = 0, repaired_in_pass = false;
      continue;
    }
    tried_face[seed] = 1;
    if (patches) ++*patches;
    bool repaired = false;
    for (int rings = 1; rings <= options.max_rings && !repaired; rings = rings < 4 ? rings + 1 : rings * 3 / 2) {
      // free vertices: within `rings` edges of the flipped face; fixed: the ring just outside
      std::vector<int> free_vertices(mesh.faces[seed].begin(), mesh.faces[seed].end()), fixed;
      for (int v : touched) depth[u(v)] = -1;
      touched.clear();
      for (int v : free_vertices) depth[u(v)] = 0, touched.push_back(v);
      for (std::size_t head = 0; head < free_vertices.size(); ++head) {
        const int v = free_vertices[head];
        for (int k = topo.nbr_offsets[u(v)]; k < topo.nbr_offsets[u(v) + 1]; ++k) {
          const int w = topo.nbrs[u(k)];
          if (depth[u(w)] >= 0) continue;
          depth[u(w)] = depth[u(v)] + 1;
          touched.push_back(w);
          (depth[u(w)] <= rings ? free_vertices : fixed).push_back(w);
        }
      }
      if (free_vertices.size() > nv / 4) break;  // not a small disk any more
      // gnomonic chart centred on the patch: great circles are lines, so orientation is kept
      Vec3 centre = Vec3::Zero();
      for (int v : free_vertices) centre += s[u(v)];
      for (int v : fixed) centre += s[u(v)];
      if (!(centre.norm() > 1e-12)) break;
      centre.normalize();
      bool in_hemisphere = true;
      for (int v : fixed) in_hemisphere = in_hemisphere && s[u(v)].dot(centre) > 0.2;
      for (int v : free_vertices) in_hemisphere = in_hemisphere && s[u(v)].dot(centre) > 0.2;
      if (!in_hemisphere) break;
      const Vec3 e1 = centre.unitOrthogonal(), e2 = centre.cross(e1);
      auto chart = [&](int v) -> Eigen::Vector2d {
        const Vec3& p = s[u(v)];
        return Eigen::Vector2d(p.dot(e1), p.dot(e2)) / p.dot(centre);
      };
      for (std::size_t i = 0; i < free_vertices.size(); ++i) free_index[u(free_vertices[i])] = static_cast<int>(i);
      // Floater's mean-value weights from the current chart positions: positive, so a convex
      // enough boundary gives an embedding (Tutte/Floater), and the unflipped part of the patch
      // is close to a fixed point, so the map changes little there.
      const auto m = static_cast<Eigen::Index>(free_vertices.size());
      std::vector<Eigen::Triplet<double>> triplets;
      Eigen::MatrixX2d rhs = Eigen::MatrixX2d::Zero(m, 2);
      Eigen::VectorXd diagonal = Eigen::VectorXd::Zero(m);
      for (std::size_t i = 0; i < free_vertices.size(); ++i) {
        const int v = free_vertices[i];
        const Eigen::Vector2d pv = chart(v);
        for (int k = topo.face_offsets[u(v)]; k < topo.face_offsets[u(v) + 1]; ++k) {
          const auto& f = mesh.faces[u(topo.vfaces[u(k)])];
          int a = 0;
          while (f[u(a)] != v) ++a;
          const int b = f[u((a + 1) % 3)], c = f[u((a + 2) % 3)];
          const Eigen::Vector2d db = chart(b) - pv, dc = chart(c) - pv;
          const double lb = std::max(db.norm(), 1e-14), lc = std::max(dc.norm(), 1e-14);
          const double angle = std::acos(std::clamp(db.dot(dc) / (lb * lc), -1.0, 1.0));
          const double half_tan = std::tan(std::clamp(angle, 1e-6, M_PI - 1e-3) / 2);
          for (auto [w, length] : {std::pair{b, lb}, std::pair{c, lc}}) {
            const double weight = half_tan / length;
            diagonal[static_cast<Eigen::Index>(i)] += weight;
            if (free_index[u(w)] >= 0)
              triplets.emplace_back(static_cast<Eigen::Index>(i), free_index[u(w)], -weight);
            else
              rhs.row(static_cast<Eigen::Index>(i)) += weight * chart(w).transpose();
          }
        }
      }
      for (Eigen::Index i = 0; i < m; ++i) triplets.emplace_back(i, i, diagonal[i]);
      Eigen::SparseMatrix<double> laplacian(m, m);
      laplacian.setFromTriplets(triplets.begin(), triplets.end());
      // Places the free vertices at chart positions; keeps them if no face around them is flipped.
      auto try_positions = [&](const Eigen::MatrixX2d& x) {
        std::vector<Vec3> saved(free_vertices.size());
        for (std::size_t i = 0; i < free_vertices.size(); ++i) {
          const int v = free_vertices[i];
          saved[i] = s[u(v)];
          const auto r = static_cast<Eigen::Index>(i);
          s[u(v)] = (centre + x(r, 0) * e1 + x(r, 1) * e2).normalized();
        }
        bool ok = true;
        for (std::size_t i = 0; i < free_vertices.size() && ok; ++i)
          for (int k = topo.face_offsets[u(free_vertices[i])]; k < topo.face_offsets[u(free_vertices[i]) + 1]; ++k)
            if (det(u(topo.vfaces[u(k)])) <= 0) ok = false;
        if (!ok)
          for (std::size_t i = 0; i < free_vertices.size(); ++i) s[u(free_vertices[i])] = saved[i];
        return ok;
      };
      Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(laplacian);
      if (lu.info() == Eigen::Success) {
        const Eigen::MatrixX2d x = lu.solve(rhs);
        repaired = lu.info() == Eigen::Success && x.allFinite() && try_positions(x);
        repaired_in_pass = repaired_in_pass || repaired;
      }
      if (!repaired && rings <= options.chart_untangling_max_rings) {
        // Floater's embedding folds when the fixed ring is far from convex (arm.off: at every
        // ring count); the untangling energy starts from the current, folded, positions instead
        // and keeps the mesh's triangle shapes as its reference.
        for (std::size_t j = 0; j < fixed.size(); ++j)
          free_index[u(fixed[j])] = static_cast<int>(free_vertices.size() + j);
        ChartPatch patch;
        patch.free_count = m;
        Eigen::MatrixX2d positions(m + static_cast<Eigen::Index>(fixed.size()), 2);
        for (int v : free_vertices) positions.row(free_index[u(v)]) = chart(v).transpose();
        for (int v : fixed) positions.row(free_index[u(v)]) = chart(v).transpose();
        double chart_area = 0, reference_area = 0;
        std::vector<std::size_t> patch_faces;
        for (int v : free_vertices)
          for (int k = topo.face_offsets[u(v)]; k < topo.face_offsets[u(v) + 1]; ++k) {
            const auto f = u(topo.vfaces[u(k)]);
            if (in_patch[f]) continue;
            in_patch[f] = 1;
            patch_faces.push_back(f);
            const auto& t = mesh.faces[f];
            patch.faces.push_back({free_index[u(t[0])], free_index[u(t[1])], free_index[u(t[2])]});
            const Eigen::Vector2d a = chart(t[0]), ab = chart(t[1]) - a, ac = chart(t[2]) - a;
            chart_area += 0.5 * std::abs(ab.x() * ac.y() - ab.y() * ac.x());
            // the mesh triangle in its own plane (a degenerate one gets an equilateral reference)
            const Vec3 along = mesh.vertices[u(t[1])] - mesh.vertices[u(t[0])];
            const Vec3 other = mesh.vertices[u(t[2])] - mesh.vertices[u(t[0])];
            const Vec3 normal = along.cross(other);
            Eigen::Matrix2d reference;
            if (normal.norm() > 1e-10 * (along.squaredNorm() + other.squaredNorm())) {
              const Vec3 x_axis = along.normalized(), y_axis = normal.cross(x_axis).normalized();
              reference << along.norm(), other.dot(x_axis), 0, other.dot(y_axis);
            } else {
              reference << 1, 0.5, 0, 0.5 * std::sqrt(3.0);
            }
            patch.reference_inverse.push_back(reference);  // inverted below, once scaled
            patch.reference_area.push_back(0.5 * reference.determinant());
            reference_area += patch.reference_area.back();
          }
        for (std::size_t f : patch_faces) in_patch[f] = 0;
        // reference triangles scaled to the patch's area in the chart: only their shapes and
        // relative sizes matter
        const double scale = std::sqrt(chart_area / reference_area);
        for (std::size_t f = 0; f < patch.faces.size(); ++f) {
          patch.reference_inverse[f] = (scale * patch.reference_inverse[f]).inverse().eval();
          patch.reference_area[f] *= scale * scale;
        }
        if (chart_untangles) ++*chart_untangles;
        if (scale > 0 && std::isfinite(scale) && untangle_budget > 0 &&
            untangle_chart_patch(patch, positions, &untangle_budget))
          repaired = try_positions(positions), repaired_in_pass = repaired_in_pass || repaired;
        for (int v : fixed) free_index[u(v)] = -1;
      }
      for (int v : free_vertices) free_index[u(v)] = -1;
    }
    // A failed face seldom gets repaired by a later face's patch: of the trials on the shared
    // and hard meshes that repaired every fold, none had one. The other faces' patches, each
    // up to 63 rings with a sparse LU per ring count, would be spent on a trial already lost
    // (cones_60k: 4 failed trials with 5 to 17 such faces, 0.6-1.9 s each).
    if (!repaired && options.stop_at_first_failure) break;
  }
  return count_flips(mesh, s);
}

// ------------------------------------------------------------------------- area optimization
namespace {

/// One face seen from one of its vertices i, with everything the local energy of i reads:
/// the other two vertices (counter-clockwise, as slots: AreaOptimizer::Tables), the face's target area
/// and the cotangents of the mesh angles at i, j and k (MIPS term). Stored contiguously per
/// vertex, so a local energy reads one block instead of following vertex → face → (vertices,
/// target, cotangents) indirections (igea_134k: the optimization about 20 % faster).
struct Corner {
  int j, k;
  double target;
  double cot_i, cot_j, cot_k;
};

struct LocalEval {
  double energy = 0;
  Eigen::Vector3d grad = Eigen::Vector3d::Zero();
  Eigen::Matrix3d gn = Eigen::Matrix3d::Zero();
  bool valid = true;
};

/// The regularised area (A + root)/2, root = sqrt(A² + 4ε²T²), for `eps2_T2` = 4ε²T²: for A < 0
/// as 4ε²T² / (2 (root − A)), the same number without the cancellation of A against root (an
/// inverted face's A_eps is far below |A|, and (A + root)/2 kept only the last bits of it).
inline double regularized_area(double A, double root, double eps2_T2) {
  return A >= 0 ? 0.5 * (A + root) : eps2_T2 / (2 * (root - A));
}

/// The faces around one vertex as lanes (structure of arrays): the other two vertices'
/// positions, gathered once per move and read by each of its tries, and the faces' constants.
/// The lanes come in blocks of `block`; those past the last face repeat it (their values are
/// computed, never summed), so that every loop over a block has a fixed length and vectorizes.
class FanLanes {
 public:
  static constexpr std::size_t block = 8;
  enum Field : std::size_t { pjx, pjy, pjz, pkx, pky, pkz, target, cot_i, cot_j, cot_k, field_count };

  template <class Position>
  void gather(const Corner* first, const Corner* last, const Position& position) {
    count_ = static_cast<std::size_t>(last - first);
    padded_ = (count_ + block - 1) / block * block;
    if (data_.size() < field_count * padded_) data_.resize(field_count * padded_);
    for (std::size_t f = 0; f < padded_; ++f) {
      const Corner& c = first[std::min(f, count_ - 1)];
      const Vec3 &pj = position(c.j), &pk = position(c.k);
      const double values[field_count] = {pj.x(), pj.y(),   pj.z(),  pk.x(),  pk.y(),
                                          pk.z(), c.target, c.cot_i, c.cot_j, c.cot_k};
      for (std::size_t field = 0; field < field_count; ++field) data_[field * padded_ + f] = values[field];
    }
  }
  [[nodiscard]] std::size_t count() const { return count_; }
  [[nodiscard]] std::size_t padded() const { return padded_; }
  [[nodiscard]] const double* operator[](Field field) const { return data_.data() + field * padded_; }

 private:
  std::size_t count_ = 0, padded_ = 0;
  std::vector<double> data_;
};

// The local energy's kernel in two builds on x86-64 with GCC, the default and one for AVX2 and FMA
// (x86-64-v3), chosen when the program loads: the face loops run 4 lanes at a time there.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define SPHPARAM_LANE_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define SPHPARAM_LANE_CLONES
#endif

/// Energy of the faces of `fan` around one vertex with that vertex at position x.
/// Area term log²(A/T) with A the signed spherical area; MIPS term on the chordal triangle.
/// Each quantity is computed for a whole block of faces before the next (loops without calls or
/// branches, which the compiler vectorizes); the few lanes that need a call (atan2 for large or
/// inverted triangles, std::log outside log_of_normal's range) are redone one by one after it.
/// The sums run in face order.
SPHPARAM_LANE_CLONES
LocalEval local_energy(const FanLanes& fan, const Vec3& x, double lambda, bool with_derivatives, double eps) {
  constexpr std::size_t block = FanLanes::block;
  using F = FanLanes::Field;
  const double *PJX = fan[F::pjx], *PJY = fan[F::pjy], *PJZ = fan[F::pjz];
  const double *PKX = fan[F::pkx], *PKY = fan[F::pky], *PKZ = fan[F::pkz];
  const double *TARGET = fan[F::target], *COT_I = fan[F::cot_i], *COT_J = fan[F::cot_j], *COT_K = fan[F::cot_k];
  const double x0 = x.x(), x1 = x.y(), x2 = x.z(), eps2 = 4 * eps * eps;
  LocalEval e;
  double gxx = 0, gxy = 0, gxz = 0, gyy = 0, gyz = 0, gzz = 0;
  for (std::size_t b = 0; b < fan.padded(); b += block) {
    const std::size_t n = std::min(block, fan.count() - b);
    const double *pjx = PJX + b, *pjy = PJY + b, *pjz = PJZ + b, *pkx = PKX + b, *pky = PKY + b, *pkz = PKZ + b;
    const double* T = TARGET + b;
    double jx[block], jy[block], jz[block], N[block], D[block], A[block], ratio[block], r[block];
    double called[block];  // 1 where the series does not apply (a double: the loop vectorizes)
    for (std::size_t f = 0; f < block; ++f) {
      jx[f] = pjy[f] * pkz[f] - pjz[f] * pky[f];
      jy[f] = pjz[f] * pkx[f] - pjx[f] * pkz[f];
      jz[f] = pjx[f] * pky[f] - pjy[f] * pkx[f];
      N[f] = x0 * jx[f] + x1 * jy[f] + x2 * jz[f];
      D[f] = 1 + x0 * (pjx[f] + pkx[f]) + x1 * (pjy[f] + pky[f]) + x2 * (pjz[f] + pkz[f]) +
             (pjx[f] * pkx[f] + pjy[f] * pky[f] + pjz[f] * pkz[f]);
      // triangle_area_from_det's series where it applies; atan2 below for the other lanes
      A[f] = twice_atan_series(N[f] / D[f]);
      called[f] = triangle_area_series_applies(N[f], D[f]) ? 0.0 : 1.0;
    }
    for (std::size_t f = 0; f < n; ++f)
      if (called[f] != 0) A[f] = 2 * std::atan2(N[f], D[f]);
    if (eps > 0) {
      // Regularised (untangling) mode: A_eps = (A + sqrt(A² + 4ε²T²))/2 > 0 also for inverted
      // faces, so vertices may pass through inverted states (Garanzha et al.'s continuation).
      double root[block];
      for (std::size_t f = 0; f < block; ++f) {
        const double eps2_T2 = eps2 * T[f] * T[f];
        root[f] = std::sqrt(A[f] * A[f] + eps2_T2);
        ratio[f] = regularized_area(A[f], root[f], eps2_T2) / T[f];
        r[f] = log_of_normal(ratio[f]);
      }
      for (std::size_t f = 0; f < n; ++f)
        if (!is_normal_positive(ratio[f])) r[f] = std::log(ratio[f]);
      if (!with_derivatives) {
        for (std::size_t f = 0; f < n; ++f) e.energy += r[f] * r[f];
        continue;
      }
      // dA/dx = 2 (D jk − N (pj + pk)) / (N² + D²) and dA_eps/dA = (1 + A/root)/2 = A_eps/root,
      // so dr = dA_eps/A_eps = dA/root: one division
      double drx[block], dry[block], drz[block];
      for (std::size_t f = 0; f < block; ++f) {
        const double c = 2 / ((N[f] * N[f] + D[f] * D[f]) * root[f]);
        drx[f] = c * (D[f] * jx[f] - N[f] * (pjx[f] + pkx[f]));
        dry[f] = c * (D[f] * jy[f] - N[f] * (pjy[f] + pky[f]));
        drz[f] = c * (D[f] * jz[f] - N[f] * (pjz[f] + pkz[f]));
      }
      for (std::size_t f = 0; f < n; ++f) {
        e.energy += r[f] * r[f];
        e.grad += 2 * r[f] * Vec3(drx[f], dry[f], drz[f]);
        gxx += 2 * drx[f] * drx[f], gxy += 2 * drx[f] * dry[f], gxz += 2 * drx[f] * drz[f];
        gyy += 2 * dry[f] * dry[f], gyz += 2 * dry[f] * drz[f], gzz += 2 * drz[f] * drz[f];
      }
      continue;
    }
    const double *ci = COT_I + b, *cj = COT_J + b, *ck = COT_K + b;
    // chordal triangle (x, pj, pk): ej = pj − x, ek = pk − x, twice its area |ej × ek|
    double nx[block], ny[block], nz[block], A2[block], C[block], mips[block];
    bool invalid = false;
    for (std::size_t f = 0; f < block; ++f) {
      const double ejx = pjx[f] - x0, ejy = pjy[f] - x1, ejz = pjz[f] - x2;
      const double ekx = pkx[f] - x0, eky = pky[f] - x1, ekz = pkz[f] - x2;
      nx[f] = ejy * ekz - ejz * eky, ny[f] = ejz * ekx - ejx * ekz, nz[f] = ejx * eky - ejy * ekx;
      A2[f] = std::sqrt(nx[f] * nx[f] + ny[f] * ny[f] + nz[f] * nz[f]);
      ratio[f] = A[f] / T[f];
      r[f] = log_of_normal(ratio[f]);
      // Σ_e cot(opposite) l_e²: edge jk opposite i, edge (x,pk) opposite j, edge (x,pj) opposite k
      const double djkx = pjx[f] - pkx[f], djky = pjy[f] - pky[f], djkz = pjz[f] - pkz[f];
      C[f] = ci[f] * (djkx * djkx + djky * djky + djkz * djkz) + cj[f] * (ekx * ekx + eky * eky + ekz * ekz) +
             ck[f] * (ejx * ejx + ejy * ejy + ejz * ejz);
      mips[f] = C[f] / (2 * A2[f]) - 1;  // = (σ1/σ2 + σ2/σ1)/2 − 1 ≥ 0
    }
    for (std::size_t f = 0; f < n; ++f) {
      invalid = invalid || !(N[f] > 0) || !(A2[f] > 0);
      if (!is_normal_positive(ratio[f])) r[f] = std::log(ratio[f]);
    }
    if (invalid) {
      e.valid = false;
      return e;
    }
    if (!with_derivatives) {
      for (std::size_t f = 0; f < n; ++f) e.energy += r[f] * r[f] + lambda * mips[f];
      continue;
    }
    double drx[block], dry[block], drz[block], dmx[block], dmy[block], dmz[block], curvature[block];
    for (std::size_t f = 0; f < block; ++f) {
      // dr = dA/dx / A (dA/dx as above); one division for each vector, not one per coordinate
      const double c = 2 / ((N[f] * N[f] + D[f] * D[f]) * A[f]);
      drx[f] = c * (D[f] * jx[f] - N[f] * (pjx[f] + pkx[f]));
      dry[f] = c * (D[f] * jy[f] - N[f] * (pjy[f] + pky[f]));
      drz[f] = c * (D[f] * jz[f] - N[f] * (pjz[f] + pkz[f]));
      const double ejx = pjx[f] - x0, ejy = pjy[f] - x1, ejz = pjz[f] - x2;
      const double ekx = pkx[f] - x0, eky = pky[f] - x1, ekz = pkz[f] - x2;
      const double djkx = pjx[f] - pkx[f], djky = pjy[f] - pky[f], djkz = pjz[f] - pkz[f];
      // dC = −2 cj ek − 2 ck ej; dA2 = (pj − pk) × nrm / A2; dm = (dC A2 − C dA2) / (2 A2²)
      const double inv_A2 = 1 / A2[f], half_inv2 = 0.5 * inv_A2 * inv_A2;
      const double dAx = inv_A2 * (djky * nz[f] - djkz * ny[f]);
      const double dAy = inv_A2 * (djkz * nx[f] - djkx * nz[f]);
      const double dAz = inv_A2 * (djkx * ny[f] - djky * nx[f]);
      dmx[f] = half_inv2 * ((-2 * cj[f] * ekx - 2 * ck[f] * ejx) * A2[f] - C[f] * dAx);
      dmy[f] = half_inv2 * ((-2 * cj[f] * eky - 2 * ck[f] * ejy) * A2[f] - C[f] * dAy);
      dmz[f] = half_inv2 * ((-2 * cj[f] * ekz - 2 * ck[f] * ejz) * A2[f] - C[f] * dAz);
      // crude curvature of the MIPS term: isotropic, from its scale C / A2 per squared length
      curvature[f] = (std::abs(ci[f]) + std::abs(cj[f]) + std::abs(ck[f]) + 1) * inv_A2;
    }
    for (std::size_t f = 0; f < n; ++f) {
      e.energy += r[f] * r[f] + lambda * mips[f];
      e.grad += 2 * r[f] * Vec3(drx[f], dry[f], drz[f]) + lambda * Vec3(dmx[f], dmy[f], dmz[f]);
      const double iso = lambda * curvature[f];
      gxx += 2 * drx[f] * drx[f] + iso, gxy += 2 * drx[f] * dry[f], gxz += 2 * drx[f] * drz[f];
      gyy += 2 * dry[f] * dry[f] + iso, gyz += 2 * dry[f] * drz[f], gzz += 2 * drz[f] * drz[f] + iso;
    }
  }
  e.gn << gxx, gxy, gxz, gxy, gyy, gyz, gxz, gyz, gzz;
  return e;
}

/// Greedy colouring of the vertex graph (no two neighbours share a colour), as index lists.
std::vector<std::vector<int>> colour_classes(const Topology& topo, std::size_t nv) {
  std::vector<int> colour(nv, -1);
  std::vector<char> taken;
  std::vector<std::vector<int>> classes;
  for (std::size_t v = 0; v < nv; ++v) {
    taken.assign(classes.size() + 1, 0);
    for (int k = topo.nbr_offsets[v]; k < topo.nbr_offsets[v + 1]; ++k) {
      const int c = colour[u(topo.nbrs[u(k)])];
      if (c >= 0) taken[u(c)] = 1;
    }
    int c = 0;
    while (taken[u(c)]) ++c;
    colour[v] = c;
    if (u(c) == classes.size()) classes.emplace_back();
    classes[u(c)].push_back(static_cast<int>(v));
  }
  return classes;
}

/// What move_vertex did.
enum class Move { skipped, rejected, accepted, accepted_significantly };

/// One damped Gauss–Newton move of the vertex in `slot` in its tangent plane (2×2 system,
/// Levenberg damping `mu`, updated): the first try `over_relaxation` times the step, then damped
/// until the local energy decreases. `positions` and `corners` in slot order (AreaOptimizer::Tables).
/// Accepted significantly: the decrease exceeds the activity threshold (options), relative to
/// the smaller of the vertex's energy and `mean_vertex_energy`.
Move move_vertex(const Corner* first, const Corner* last, std::vector<Vec3>& positions, std::size_t slot, double& mu,
                 const OptimizeOptions& options, double over_relaxation, double mean_vertex_energy) {
  const auto position = [&positions](int other) -> const Vec3& { return positions[u(other)]; };
  thread_local FanLanes fan;
  fan.gather(first, last, position);
  const Vec3 x = positions[slot];
  const LocalEval e0 = local_energy(fan, x, options.angle_weight, true, options.regularization);
  if (!e0.valid) return Move::skipped;
  const Vec3 t1 = (std::abs(x.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(x).normalized();
  const Vec3 t2 = x.cross(t1);
  Eigen::Matrix<double, 3, 2> P;
  P.col(0) = t1, P.col(1) = t2;
  const Eigen::Vector2d grad2 = P.transpose() * e0.grad;
  const Eigen::Matrix2d H = P.transpose() * e0.gn * P;
  const double scale = H.trace() * 0.5 + 1e-300;
  double m = mu;
  for (int tries = 0; tries < 6; ++tries) {
    // the damped 2×2 system (symmetric positive definite) by Cramer's rule
    const double h00 = H(0, 0) + m * scale, h11 = H(1, 1) + m * scale, h01 = 0.5 * (H(0, 1) + H(1, 0));
    const double relaxation = tries == 0 ? over_relaxation : 1.0;
    const double factor = -relaxation / (h00 * h11 - h01 * h01);
    const Eigen::Vector2d d(factor * (h11 * grad2.x() - h01 * grad2.y()), factor * (h00 * grad2.y() - h01 * grad2.x()));
    const Vec3 y = (x + P * d).normalized();
    const LocalEval e1 = local_energy(fan, y, options.angle_weight, false, options.regularization);
    if (e1.valid && e1.energy < e0.energy) {
      positions[slot] = y;
      mu = std::max(m * 0.3, 1e-4);
      return e0.energy - e1.energy > options.activity_threshold * (std::min(e0.energy, mean_vertex_energy) + 1e-12)
                 ? Move::accepted_significantly
                 : Move::accepted;
    }
    m = m * 10 + 1e-2;
  }
  mu = std::min(m, 1e3);
  return Move::rejected;
}

}  // namespace

int sweep_limit(const OptimizeOptions& options) {
  if (options.max_sweeps >= 0) return options.max_sweeps;
  return options.angle_weight > default_angle_weight ? 2000 : 200;
}

double area_first_visit_limit(const OptimizeOptions& options) {
  // only under the automatic visit limit: finite exactly for automatic limits and λ up to the default
  const double automatic = options.max_visits_per_vertex < 0 ? visit_limit(options) : 0;
  if (!(options.area_first_visits > 0 && options.angle_weight > 0 && options.regularization == 0 &&
        std::isfinite(automatic)))
    return 0;
  return std::min(options.area_first_visits, automatic);
}

double visit_limit(const OptimizeOptions& options) {
  if (options.max_visits_per_vertex >= 0) return options.max_visits_per_vertex;
  if (options.max_sweeps >= 0 || options.angle_weight > default_angle_weight)
    return std::numeric_limits<double>::infinity();
  return 20;
}

/// The optimizer's view of the mesh in visit order: the vertices of colour class 0, then those
/// of class 1, and so on, each class in vertex order; a vertex's place in it is its slot. A sweep
/// then reads the corner table front to back, and the positions of each class lie together,
/// where in vertex order every class strides across all of them (the loads of a corner and of
/// the neighbours' positions were about a third of the local energy's time on spiky_120k).
struct AreaOptimizer::Tables {
  std::vector<int> vertex_of_slot, slot_of_vertex;
  std::vector<std::size_t> class_offsets;  // the slots of class c: [class_offsets[c], class_offsets[c + 1])
  std::vector<int> corner_offsets;         // the corners of slot q: [corner_offsets[q], corner_offsets[q + 1])
  std::vector<Corner> corners;             // j and k as slots
  std::vector<int> nbr_offsets, nbrs;      // the neighbours of each slot, as slots
  Tables(const Mesh& mesh, const Topology& topo, const std::vector<double>& targets);
};

AreaOptimizer::Tables::Tables(const Mesh& mesh, const Topology& topo, const std::vector<double>& targets) {
  Tables& t = *this;
  const std::size_t nv = mesh.vertices.size();
  t.class_offsets.push_back(0);
  for (const auto& colour : colour_classes(topo, nv)) {
    t.vertex_of_slot.insert(t.vertex_of_slot.end(), colour.begin(), colour.end());
    t.class_offsets.push_back(t.vertex_of_slot.size());
  }
  t.slot_of_vertex.assign(nv, -1);
  for (std::size_t q = 0; q < nv; ++q) t.slot_of_vertex[u(t.vertex_of_slot[q])] = static_cast<int>(q);
  t.corner_offsets.assign(nv + 1, 0);
  t.nbr_offsets.assign(nv + 1, 0);
  for (std::size_t q = 0; q < nv; ++q) {
    const auto i = u(t.vertex_of_slot[q]);
    t.corner_offsets[q + 1] = t.corner_offsets[q] + topo.face_offsets[i + 1] - topo.face_offsets[i];
    t.nbr_offsets[q + 1] = t.nbr_offsets[q] + topo.nbr_offsets[i + 1] - topo.nbr_offsets[i];
  }
  t.corners.resize(topo.vfaces.size());
  t.nbrs.resize(topo.nbrs.size());
  const auto slots = static_cast<std::ptrdiff_t>(nv);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t slot = 0; slot < slots; ++slot) {
    const auto q = u(slot);
    const auto i = u(t.vertex_of_slot[q]);
    Corner* corner = &t.corners[u(t.corner_offsets[q])];
    for (int r = topo.face_offsets[i]; r < topo.face_offsets[i + 1]; ++r, ++corner) {
      const int f = topo.vfaces[u(r)];
      const auto& face = mesh.faces[u(f)];
      const int c = face[0] == static_cast<int>(i) ? 0 : (face[1] == static_cast<int>(i) ? 1 : 2);
      const int j = face[u((c + 1) % 3)], k = face[u((c + 2) % 3)];
      const Vec3 &pi = mesh.vertices[i], &pj = mesh.vertices[u(j)], &pk = mesh.vertices[u(k)];
      *corner = {t.slot_of_vertex[u(j)], t.slot_of_vertex[u(k)], targets[u(f)],
                 cot_angle(pi, pj, pk),  cot_angle(pj, pk, pi),  cot_angle(pk, pi, pj)};
    }
    int* nbr = &t.nbrs[u(t.nbr_offsets[q])];
    for (int r = topo.nbr_offsets[i]; r < topo.nbr_offsets[i + 1]; ++r) *nbr++ = t.slot_of_vertex[u(topo.nbrs[u(r)])];
  }
}

AreaOptimizer::AreaOptimizer(const Mesh& mesh, const Topology& topo, const std::vector<double>& targets)
    : mesh_(mesh), targets_(targets), tables_(std::make_unique<Tables>(mesh, topo, targets)) {}

AreaOptimizer::~AreaOptimizer() = default;

double AreaOptimizer::vertex_energy(const std::vector<Vec3>& s, int vertex, const Vec3& x,
                                    const OptimizeOptions& options, Vec3* gradient) const {
  if (vertex < 0 || u(vertex) >= s.size() || s.size() != mesh_.vertices.size())
    throw std::invalid_argument("vertex " + std::to_string(vertex) + " of " + std::to_string(s.size()) +
                                " positions for a mesh of " + std::to_string(mesh_.vertices.size()) + " vertices");
  const Tables& t = *tables_;
  const auto q = u(t.slot_of_vertex[u(vertex)]);
  const auto position = [&](int slot) -> const Vec3& { return s[u(t.vertex_of_slot[u(slot)])]; };
  FanLanes fan;
  fan.gather(&t.corners[u(t.corner_offsets[q])], t.corners.data() + t.corner_offsets[q + 1], position);
  const LocalEval e = local_energy(fan, x, options.angle_weight, gradient != nullptr, options.regularization);
  if (gradient) *gradient = e.grad;
  return e.valid ? e.energy : std::numeric_limits<double>::quiet_NaN();
}

OptimizeResult optimize_area(const Mesh& mesh, const Topology& topo, const std::vector<double>& targets,
                             std::vector<Vec3>& s, const OptimizeOptions& options) {
  return AreaOptimizer(mesh, topo, targets).run(s, options);
}

OptimizeResult AreaOptimizer::run(std::vector<Vec3>& s, const OptimizeOptions& options) const {
  if (!(std::isfinite(options.angle_weight) && options.angle_weight >= 0))
    throw std::invalid_argument("angle_weight: must be a finite number >= 0, got " +
                                std::to_string(options.angle_weight));
  if (std::isnan(options.max_visits_per_vertex))
    throw std::invalid_argument("max_visits_per_vertex: must be a number, got NaN");
  if (!(options.over_relaxation > 0 && options.over_relaxation < 2))
    throw std::invalid_argument("over_relaxation: must be in (0, 2), got " + std::to_string(options.over_relaxation));
  if (!(std::isfinite(options.area_first_visits) && options.area_first_visits >= 0))
    throw std::invalid_argument("area_first_visits: must be a finite number >= 0, got " +
                                std::to_string(options.area_first_visits));
  if (s.size() != mesh_.vertices.size())
    throw std::invalid_argument("positions: " + std::to_string(s.size()) + " for a mesh of " +
                                std::to_string(mesh_.vertices.size()) + " vertices");
  if (const double area_first = area_first_visit_limit(options); area_first > 0) {
    const double visits_per_vertex = visit_limit(options);
    const auto nv = static_cast<double>(s.size());
    OptimizeOptions area_only = options;
    area_only.angle_weight = 0;
    area_only.max_sweeps = sweep_limit(options) / 2;  // a long tail of few active vertices leaves the rest
    area_only.max_visits_per_vertex = area_first;
    area_only.area_first_visits = 0;
    const auto start = std::chrono::steady_clock::now();
    const OptimizeResult first = run_once(s, area_only);
    OptimizeOptions with_angles = options;
    with_angles.max_sweeps = sweep_limit(options) - first.sweeps;
    with_angles.max_visits_per_vertex = std::max(0.0, visits_per_vertex - static_cast<double>(first.visits) / nv);
    with_angles.time_budget_s =
        options.time_budget_s - std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    with_angles.start_active.clear();
    with_angles.area_first_visits = 0;
    OptimizeResult second = run_once(s, with_angles);
    second.sweeps += first.sweeps;
    second.visits += first.visits;
    second.energy_start = first.energy_start;
    return second;
  }
  return run_once(s, options);
}

OptimizeResult AreaOptimizer::run_once(std::vector<Vec3>& s, const OptimizeOptions& options) const {
  const Mesh& mesh = mesh_;
  const std::vector<double>& targets = targets_;
  const Tables& t = *tables_;
  const auto start = std::chrono::steady_clock::now();
  const std::size_t nv = s.size();
  // The faces' terms in parallel, summed in face order: the same bits on any thread count.
  std::vector<double> face_energy(mesh.faces.size());
  auto total_energy = [&] {
    const auto nf = static_cast<std::ptrdiff_t>(mesh.faces.size());
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t f = 0; f < nf; ++f) {
      const auto& face = mesh.faces[u(f)];
      const double A = signed_spherical_triangle_area(s[u(face[0])], s[u(face[1])], s[u(face[2])]);
      const double T = targets[u(f)];
      const double eps2_T2 = 4 * options.regularization * options.regularization * T * T;
      const double Ae = options.regularization > 0 ? regularized_area(A, std::sqrt(A * A + eps2_T2), eps2_T2) : A;
      const double r = std::log(Ae / T);
      face_energy[u(f)] = Ae > 0 ? r * r : std::numeric_limits<double>::infinity();
    }
    double E = 0;
    for (double e : face_energy) E += e;
    return E;
  };
  OptimizeResult result;
  result.energy_start = total_energy();
  // Each face's energy is part of its three vertices' local energies.
  const double mean_vertex_energy = 3 * result.energy_start / static_cast<double>(nv);
  // The positions, the damping and the active set in slot order (Tables).
  std::vector<Vec3> positions(nv);
  for (std::size_t q = 0; q < nv; ++q) positions[q] = s[u(t.vertex_of_slot[q])];
  std::vector<double> mu(nv, 1e-3);  // per-vertex Levenberg damping
  // Active set: a vertex is revisited while it or a neighbour moved noticeably. Each move marks
  // its own slot only, and the next active set is read from those marks after the sweep: marking
  // the neighbours from the moves had both threads write the same cache lines all sweep long.
  std::vector<char> active(nv, 1), next_active(nv, 0), moved(nv, 0);
  if (options.start_active.size() == nv)
    for (std::size_t q = 0; q < nv; ++q) active[q] = options.start_active[u(t.vertex_of_slot[q])];
  // Gauss–Seidel, one colour class at a time: vertices of one colour share no face, so their
  // moves are independent and run in parallel. Small classes run serially: a parallel region per
  // class and sweep costs more than it saves there, and much more when the machine is loaded.
  const int max_sweeps = sweep_limit(options);
  const double max_visits = visit_limit(options) * static_cast<double>(nv);
  // Over-relaxed moves only where the area error is above its noise level (OptimizeOptions).
  result.over_relaxation = result.energy_start < plain_steps_below_face_energy * static_cast<double>(mesh.faces.size())
                               ? 1.0
                               : options.over_relaxation;
  for (int sweep = 0; sweep < max_sweeps; ++sweep) {
    std::size_t visited = 0;
    std::fill(moved.begin(), moved.end(), 0);
    for (std::size_t colour = 0; colour + 1 < t.class_offsets.size(); ++colour) {
      const auto first = static_cast<std::ptrdiff_t>(t.class_offsets[colour]);
      const auto last = static_cast<std::ptrdiff_t>(t.class_offsets[colour + 1]);
#pragma omp parallel for schedule(dynamic, 256) reduction(+ : visited) if (last - first >= 4096)
      for (std::ptrdiff_t slot = first; slot < last; ++slot) {
        const auto q = u(slot);
        if (!active[q]) continue;
        ++visited;
        moved[q] =
            move_vertex(t.corners.data() + t.corner_offsets[q], t.corners.data() + t.corner_offsets[q + 1], positions,
                        q, mu[q], options, result.over_relaxation, mean_vertex_energy) == Move::accepted_significantly;
      }
    }
    const auto slots = static_cast<std::ptrdiff_t>(nv);
#pragma omp parallel for schedule(static) if (slots >= 4096)
    for (std::ptrdiff_t slot = 0; slot < slots; ++slot) {
      const auto q = u(slot);
      char any = moved[q];
      for (int k = t.nbr_offsets[q]; k < t.nbr_offsets[q + 1]; ++k)
        any = static_cast<char>(any | moved[u(t.nbrs[u(k)])]);
      next_active[q] = any;
    }
    active.swap(next_active);
    result.sweeps = sweep + 1;
    result.visits += visited;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (visited == 0 || elapsed > options.time_budget_s || static_cast<double>(result.visits) >= max_visits) break;
  }
  for (std::size_t q = 0; q < nv; ++q) s[u(t.vertex_of_slot[q])] = positions[q];
  result.energy_end = total_energy();
  if (result.sweeps == 0) result.energy_end = result.energy_start;
  return result;
}

std::size_t untangle_by_laplacian_rounds(const Mesh& mesh, const Topology& topo, const AreaOptimizer& optimizer,
                                         std::vector<Vec3>& s, int max_rounds, int* rounds) {
  std::size_t flips = count_flips(mesh, s);
  for (int round = 0; round < max_rounds && flips > 0; ++round) {
    if (rounds) ++*rounds;
    untangle(mesh, topo, s, 30, false);  // monotone moves rearrange the stuck spots
    OptimizeOptions uo;
    uo.angle_weight = 0;
    uo.max_sweeps = 100;
    uo.activity_threshold = 1e-5;
    uo.over_relaxation = 1;  // around stuck folds: local moves
    for (double eps : {1e-2, 1e-3, 1e-4, 1e-5}) {
      uo.regularization = eps;
      // From the vertices within 4 rings of the folds (a move still wakes its neighbours), not
      // from every vertex: the global area work is the final optimization's (cones_60k, the one
      // shared or hard mesh that gets here: this round 0.93 s -> 0.02 s, final area mean|d|
      // 0.0923 -> 0.0917).
      uo.start_active = near_flipped_faces(mesh, topo, s, 4);
      optimizer.run(s, uo);
      flips = count_flips(mesh, s);
      if (flips == 0) break;
    }
  }
  return flips;
}

Mesh subdivide(const Mesh& mesh) {
  Mesh out;
  out.vertices = mesh.vertices;
  std::unordered_map<std::uint64_t, int> mid;
  mid.reserve(mesh.faces.size() * 2);
  auto midpoint = [&](int a, int b) {
    const int lo = std::min(a, b), hi = std::max(a, b);
    const std::uint64_t k =
        (static_cast<std::uint64_t>(static_cast<std::uint32_t>(lo)) << 32) | static_cast<std::uint32_t>(hi);
    auto it = mid.find(k);
    if (it != mid.end()) return it->second;
    const int idx = static_cast<int>(out.vertices.size());
    out.vertices.push_back(0.5 * (mesh.vertices[u(a)] + mesh.vertices[u(b)]));
    mid.emplace(k, idx);
    return idx;
  };
  out.faces.reserve(mesh.faces.size() * 4);
  for (const auto& f : mesh.faces) {
    const int a = f[0], b = f[1], c = f[2];
    const int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
    out.faces.push_back({a, ab, ca});
    out.faces.push_back({ab, b, bc});
    out.faces.push_back({ca, bc, c});
    out.faces.push_back({ab, bc, ca});
  }
  return out;
}

namespace {
/// Per vertex, the lightest vertex Dirac within one ring of it, the faces split by `levels`
/// (a vertex Dirac is a third of the sub-triangles' targets around it).
std::vector<double> lightest_dirac_in_ring(const Mesh& mesh, const std::vector<double>& targets,
                                           const std::vector<int>& levels) {
  std::vector<double> mass(mesh.vertices.size(), 0.0);
  for (std::size_t f = 0; f < mesh.faces.size(); ++f)
    for (int v : mesh.faces[f]) mass[u(v)] += targets[f] / std::ldexp(3.0, 2 * levels[f]);
  std::vector<double> ring(mesh.vertices.size(), std::numeric_limits<double>::infinity());
  for (const auto& t : mesh.faces) {
    const double lightest = std::min({mass[u(t[0])], mass[u(t[1])], mass[u(t[2])]});
    for (int v : t) ring[u(v)] = std::min(ring[u(v)], lightest);
  }
  return ring;
}
}  // namespace

double largest_dirac_jump(const Mesh& mesh, const std::vector<double>& targets) {
  const auto ring = lightest_dirac_in_ring(mesh, targets, std::vector<int>(mesh.faces.size(), 0));
  double largest = 0;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& t = mesh.faces[f];
    largest = std::max(largest, targets[f] / std::min({ring[u(t[0])], ring[u(t[1])], ring[u(t[2])]}));
  }
  return largest;
}

std::vector<int> graded_levels(const Mesh& mesh, const std::vector<double>& targets, double ratio, int max_level) {
  std::vector<int> levels(mesh.faces.size(), 0);
  // A face's sub-triangles against the lightest vertex Dirac within one ring of its corners, not
  // against its neighbouring faces: a sliver next to large faces has vertices as heavy as theirs.
  // Raising a face's level lightens its corners, which may raise the next ring's levels: repeat
  // until nothing changes (levels only grow, up to max_level).
  for (bool changed = true; changed;) {
    changed = false;
    const auto ring = lightest_dirac_in_ring(mesh, targets, levels);
    for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
      const auto& t = mesh.faces[f];
      const double bound = ratio * std::min({ring[u(t[0])], ring[u(t[1])], ring[u(t[2])]});
      int level = levels[f];
      while (level < max_level && targets[f] / std::ldexp(1.0, 2 * level) > bound) ++level;
      if (level != levels[f]) levels[f] = level, changed = true;
    }
  }
  return levels;
}

DiracSet lattice_diracs(const Mesh& mesh, const std::vector<Vec3>& s, const std::vector<double>& targets,
                        const std::vector<int>& levels) {
  const std::size_t nv = s.size();
  DiracSet out;
  out.sites = s;
  out.masses.assign(nv, 0.0);
  const int max_level = levels.empty() ? 0 : *std::max_element(levels.begin(), levels.end());
  const std::uint64_t steps = std::uint64_t{1} << max_level;  // edge positions, in units of 2^-max_level
  std::unordered_map<std::uint64_t, int> edge_points;
  auto add = [&](const Vec3& p) {
    out.sites.push_back(p);
    out.masses.push_back(0.0);
    return static_cast<int>(out.sites.size() - 1);
  };
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& t = mesh.faces[f];
    const int m = 1 << levels[f];
    const double share = targets[f] / (3.0 * m * m);  // a third of a sub-triangle's target
    // lattice point (i, j) of the face: weights (m - i - j, i, j) on (t[0], t[1], t[2])
    auto point = [&](int i, int j) -> int {
      const int w[3] = {m - i - j, i, j};
      int zeros = 0;
      for (int k = 0; k < 3; ++k) zeros += w[k] == 0;
      if (zeros == 2)
        for (int k = 0; k < 3; ++k)
          if (w[k] == m) return t[u(k)];
      if (zeros == 1) {
        // on the edge opposite the zero weight: keyed by its ends (lower index first) and the
        // position from the lower end, so both faces find the same point at the same place
        int k = 0;
        while (w[k] != 0) ++k;
        int a = t[u((k + 1) % 3)], b = t[u((k + 2) % 3)];
        int wb = w[(k + 2) % 3];
        if (a > b) std::swap(a, b), wb = w[(k + 1) % 3];
        const std::uint64_t pos = static_cast<std::uint64_t>(wb) * (steps / static_cast<std::uint64_t>(m));
        const std::uint64_t key =
            (static_cast<std::uint64_t>(a) * nv + static_cast<std::uint64_t>(b)) * (steps + 1) + pos;
        const auto found = edge_points.find(key);
        if (found != edge_points.end()) return found->second;
        const double x = static_cast<double>(pos) / static_cast<double>(steps);
        const int idx = add(((1 - x) * s[u(a)] + x * s[u(b)]).normalized());
        edge_points.emplace(key, idx);
        return idx;
      }
      return add(((w[0] * s[u(t[0])] + w[1] * s[u(t[1])] + w[2] * s[u(t[2])]) / m).normalized());
    };
    if (m == 1) {
      for (int v : t) out.masses[u(v)] += share;
      continue;
    }
    // corners get 1 sub-triangle, edge points 3, interior points 6
    for (int i = 0; i <= m; ++i)
      for (int j = 0; i + j <= m; ++j) {
        const int zeros = (i == 0) + (j == 0) + (i + j == m);
        const int idx = point(i, j);
        out.masses[u(idx)] += share * (zeros == 2 ? 1 : zeros == 1 ? 3 : 6);
      }
  }
  return out;
}

}  // namespace sphparam

namespace sphparam {

// ------------------------------------------------------------------- coarse-to-fine initial map
namespace {

/// One level of the hierarchy: the faces before its collapses and the collapses (removed vertex,
/// the neighbour it went into). No two removed vertices are neighbours, so each one's fan is the
/// same in `faces` as at its collapse, and their reversals are independent of each other.
struct CollapseLevel {
  std::vector<Face> faces;
  std::vector<std::pair<int, int>> collapses;
};

/// Vertices of a face list as a compact mesh (original coordinates), with the map back.
Mesh compact_mesh(const Mesh& mesh, const std::vector<Face>& faces, std::vector<int>& global_of,
                  std::vector<int>& local_of) {
  std::fill(local_of.begin(), local_of.end(), -1);
  global_of.clear();
  Mesh out;
  for (const auto& f : faces)
    for (int v : f)
      if (local_of[u(v)] < 0) {
        local_of[u(v)] = static_cast<int>(global_of.size());
        global_of.push_back(v);
        out.vertices.push_back(mesh.vertices[u(v)]);
      }
  out.faces.reserve(faces.size());
  for (const auto& f : faces) out.faces.push_back({local_of[u(f[0])], local_of[u(f[1])], local_of[u(f[2])]});
  return out;
}

}  // namespace

std::vector<Vec3> hierarchical_sphere_map(const Mesh& mesh, std::size_t base_vertices, HierarchyInfo* info) {
  const std::size_t nv = mesh.vertices.size();
  std::vector<CollapseLevel> levels;
  std::vector<Face> faces = mesh.faces;
  std::vector<char> alive(nv, 1), marked(nv, 0);
  std::size_t alive_count = nv;
  std::vector<std::vector<int>> nbrs(nv);
  std::vector<int> order(nv);
  std::vector<double> shortest(nv);
  // Edge cost: the angle between the vertex normals, plus a tie-break by length. Along a tube
  // the normals are parallel and around it they turn: collapses shorten tubes before they thin
  // them (a tube thinned to 3 vertices around cannot be shortened: the link condition fails).
  std::vector<Vec3> normal(nv, Vec3::Zero());
  double mean_edge = 0;
  for (const auto& f : mesh.faces) {
    const Vec3 n =
        (mesh.vertices[u(f[1])] - mesh.vertices[u(f[0])]).cross(mesh.vertices[u(f[2])] - mesh.vertices[u(f[0])]);
    for (int v : f) normal[u(v)] += n;
    mean_edge += (mesh.vertices[u(f[1])] - mesh.vertices[u(f[0])]).norm();
  }
  mean_edge /= static_cast<double>(std::max<std::size_t>(mesh.faces.size(), 1));
  for (auto& n : normal) n = n.norm() > 0 ? Vec3(n.normalized()) : Vec3::UnitZ();
  auto cost = [&](int a, int b) {
    return std::acos(std::clamp(normal[u(a)].dot(normal[u(b)]), -1.0, 1.0)) +
           0.01 * (mesh.vertices[u(a)] - mesh.vertices[u(b)]).norm() / mean_edge;
  };
  // Each vertex's share of the surface (a third of its faces' areas); a collapse adds the removed
  // vertex's share to the vertex it goes into, so that a coarse vertex carries the area of all
  // that was collapsed into it. The coarse meshes' own face areas would not do: the collapses
  // shorten the tubes, whose coarse faces then stand for far more surface than they have
  // (tubes_25k: final area mean|d| 0.560 with those, 0.313 with these).
  std::vector<double> mass = vertex_targets(mesh, face_targets(mesh, {}));
  while (alive_count > base_vertices) {
    for (auto& n : nbrs) n.clear();
    for (const auto& f : faces)
      for (int k = 0; k < 3; ++k) nbrs[u(f[u(k)])].push_back(f[u((k + 1) % 3)]);  // one per face
    for (auto& n : nbrs) std::sort(n.begin(), n.end());
    // cheapest edges first
    std::iota(order.begin(), order.end(), 0);
    for (std::size_t v = 0; v < nv; ++v) {
      shortest[v] = 1e300;
      for (int w : nbrs[v]) shortest[v] = std::min(shortest[v], cost(static_cast<int>(v), w));
    }
    std::sort(order.begin(), order.end(), [&](int a, int b) { return shortest[u(a)] < shortest[u(b)]; });
    std::fill(marked.begin(), marked.end(), 0);
    CollapseLevel level;
    for (int v : order) {
      // v and its neighbours are marked: no two removed vertices are neighbours, so each one's
      // fan is the same at its collapse as in the level's faces
      if (!alive[u(v)] || marked[u(v)] || nbrs[u(v)].size() < 3) continue;
      // the neighbour along the shortest edge that keeps the mesh a manifold: exactly two common
      // neighbours (the link condition), both of degree > 3, and no vertex of degree above 12
      int into = -1;
      double best = 1e300;
      for (int w : nbrs[u(v)]) {
        const double length = cost(v, w);
        if (length >= best || nbrs[u(w)].size() + nbrs[u(v)].size() > 16) continue;
        std::vector<int> common;
        std::set_intersection(nbrs[u(v)].begin(), nbrs[u(v)].end(), nbrs[u(w)].begin(), nbrs[u(w)].end(),
                              std::back_inserter(common));
        if (common.size() != 2 || nbrs[u(common[0])].size() <= 3 || nbrs[u(common[1])].size() <= 3) continue;
        into = w, best = length;
      }
      if (into < 0) continue;
      level.collapses.emplace_back(v, into);
      // v and its neighbours marked, and the collapse made in the neighbour lists, so that the
      // next collapses' link conditions and degrees see it: v's neighbours become `into`'s.
      marked[u(v)] = 1;
      auto& target = nbrs[u(into)];
      target.erase(std::lower_bound(target.begin(), target.end(), v));
      for (int x : nbrs[u(v)]) {
        marked[u(x)] = 1;
        if (x == into) continue;
        auto& around = nbrs[u(x)];
        around.erase(std::lower_bound(around.begin(), around.end(), v));
        const auto at = std::lower_bound(around.begin(), around.end(), into);
        if (at == around.end() || *at != into) {
          around.insert(at, into);
          target.insert(std::lower_bound(target.begin(), target.end(), x), x);
        }
      }
      nbrs[u(v)].clear();
    }
    if (level.collapses.size() * 200 < alive_count) break;  // nothing left worth a level
    level.faces = faces;
    std::vector<int> into(nv, -1);
    for (auto [v, w] : level.collapses) into[u(v)] = w, alive[u(v)] = 0, mass[u(w)] += mass[u(v)];
    alive_count -= level.collapses.size();
    std::vector<Face> coarse;
    coarse.reserve(faces.size());
    for (auto f : faces) {
      bool dropped = false;
      for (int& x : f)
        if (into[u(x)] >= 0) {
          const int w = into[u(x)];
          dropped = dropped || f[0] == w || f[1] == w || f[2] == w;  // the two faces on the edge
          x = w;
        }
      if (!dropped) coarse.push_back(f);
    }
    faces = std::move(coarse);
    levels.push_back(std::move(level));
  }

  // The base: Tutte, then its areas corrected (a flip-free optimization keeps it an embedding).
  std::vector<int> global_of, local_of(nv, -1);
  std::vector<Vec3> s(nv, Vec3::Zero());
  auto relax = [&](const std::vector<Face>& level_faces, int sweeps) {
    const Mesh level_mesh = compact_mesh(mesh, level_faces, global_of, local_of);
    const Topology level_topo(level_mesh);
    std::vector<Vec3> local(global_of.size());
    for (std::size_t i = 0; i < global_of.size(); ++i) local[i] = s[u(global_of[i])];
    // face targets: each vertex's share spread evenly over its faces
    std::vector<int> face_count(global_of.size(), 0);
    for (const auto& f : level_mesh.faces)
      for (int x : f) ++face_count[u(x)];
    std::vector<double> level_targets(level_mesh.faces.size(), 0.0);
    for (std::size_t f = 0; f < level_mesh.faces.size(); ++f)
      for (int x : level_mesh.faces[f]) level_targets[f] += mass[u(global_of[u(x)])] / face_count[u(x)];
    OptimizeOptions o;
    o.max_sweeps = sweeps;
    o.over_relaxation = 1;  // a few sweeps after each level's insertions: local errors
    optimize_area(level_mesh, level_topo, level_targets, local, o);
    for (std::size_t i = 0; i < global_of.size(); ++i) s[u(global_of[i])] = local[i];
  };
  {
    const Mesh base = compact_mesh(mesh, faces, global_of, local_of);
    const Topology base_topo(base);
    std::vector<Vec3> base_map;
    if (base.vertices.size() == 4) {
      // A tetrahedron (the collapses went all the way): the regular one, oriented like the mesh.
      // Tutte's map of it puts the outer face on a hemisphere, a degenerate face on which the
      // inversion-free optimization and insertions are stuck.
      base_map = {Vec3(1, 1, 1).normalized(), Vec3(1, -1, -1).normalized(), Vec3(-1, 1, -1).normalized(),
                  Vec3(-1, -1, 1).normalized()};
      if (count_flips(base, base_map) > 0) std::swap(base_map[0], base_map[1]);
    } else {
      // uniform weights: the collapsed mesh's triangles are far from its surface's shape, and
      // their clamped cotangents span orders of magnitude; no stretch reweighting, which inverts
      // more of the base's faces
      base_map = tutte_sphere_map(base, base_topo, {}, 0, nullptr, nullptr, true);
    }
    for (std::size_t i = 0; i < global_of.size(); ++i) s[u(global_of[i])] = base_map[i];
    if (info) info->base_vertices = global_of.size(), info->base_flips = count_flips(base, base_map);
    relax(faces, 50);
  }
  // Coarse to fine: each removed vertex goes back next to the vertex it was collapsed into,
  // inside the wedge of its two faces on that edge, close enough that none of its faces is
  // inverted (its other faces are then near the positive faces they were collapsed into).
  for (std::size_t l = levels.size(); l-- > 0;) {
    const CollapseLevel& level = levels[l];
    for (auto [v, w] : level.collapses) mass[u(w)] -= mass[u(v)];  // the shares of this level's vertices
    std::vector<std::vector<int>> faces_of(level.collapses.size());
    std::vector<int> slot(nv, -1);
    for (std::size_t c = 0; c < level.collapses.size(); ++c) slot[u(level.collapses[c].first)] = static_cast<int>(c);
    for (std::size_t f = 0; f < level.faces.size(); ++f)
      for (int x : level.faces[f])
        if (slot[u(x)] >= 0) faces_of[u(slot[u(x)])].push_back(static_cast<int>(f));
    for (std::size_t c = 0; c < level.collapses.size(); ++c) {
      // plain names, not a structured binding: clang 14 cannot capture one in the lambda below
      const int v = level.collapses[c].first, w = level.collapses[c].second;
      const Vec3 p = s[u(w)];
      Vec3 left = Vec3::Zero(), right = Vec3::Zero();  // third vertices of (w, v, left), (v, w, right)
      double reach = 1e300;
      for (int f : faces_of[c]) {
        const auto& t = level.faces[u(f)];
        for (int k = 0; k < 3; ++k) {
          if (t[u(k)] == w && t[u((k + 1) % 3)] == v) left = s[u(t[u((k + 2) % 3)])];
          if (t[u(k)] == v && t[u((k + 1) % 3)] == w) right = s[u(t[u((k + 2) % 3)])];
          if (t[u(k)] != v && t[u(k)] != w) reach = std::min(reach, (s[u(t[u(k)])] - p).norm());
        }
      }
      // tangent directions at p: the step t needs det[p, t, left] > 0 and det[p, t, right] < 0
      const Vec3 e1 = p.unitOrthogonal(), e2 = p.cross(e1);
      const double to_left = std::atan2(left.dot(e2), left.dot(e1));
      double to_right = std::atan2(right.dot(e2), right.dot(e1));
      double arc = to_left - to_right;  // counter-clockwise from right to left
      if (arc <= 0) arc += 2 * M_PI;
      const double lower = std::max(0.0, arc - M_PI), upper = std::min(M_PI, arc);
      const double angle = to_right + 0.5 * (lower + upper);
      const Vec3 direction = std::cos(angle) * e1 + std::sin(angle) * e2;
      auto positive = [&](const Vec3& q) {
        s[u(v)] = q;
        for (int f : faces_of[c]) {
          const auto& t = level.faces[u(f)];
          if (!(s[u(t[0])].dot(s[u(t[1])].cross(s[u(t[2])])) > 0)) return false;
        }
        return true;
      };
      double step = 0.3 * reach;
      bool placed = false;
      for (int halving = 0; halving < 60 && !placed; ++halving, step *= 0.5)
        placed = positive((p + step * direction).normalized());
      if (!placed) positive((p + step * direction).normalized());  // rounding: left to the untangling
      if (placed) {
        // towards the mean of its neighbours while that inverts nothing
        Vec3 mean = Vec3::Zero();
        for (int f : faces_of[c])
          for (int x : level.faces[u(f)])
            if (x != v) mean += s[u(x)];
        const Vec3 start = s[u(v)];
        for (double t : {1.0, 0.5, 0.25}) {
          if (positive((start + t * (mean.normalized() - start)).normalized())) break;
          positive(start);
        }
      } else if (info) {
        ++info->unplaced;
      }
    }
    relax(level.faces, 24);
  }
  if (info) info->levels = static_cast<int>(levels.size());
  return s;
}

}  // namespace sphparam
