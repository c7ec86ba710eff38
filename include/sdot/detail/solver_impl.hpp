#pragma once
// Implementation of solver.hpp (templates).

#include <Eigen/SparseCore>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <limits>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

namespace sdot::detail {

using Clock = std::chrono::steady_clock;
/// A number for messages: 3 significant digits (std::to_string would print 1e-10 as 0.000000).
inline std::string format_number(double x) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.3g", x);
  return buffer;
}

inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

struct MassError {
  double max_relative = 0, rms_relative = 0, l2 = 0;
  Eigen::Index worst = 0;
};

inline MassError mass_error(const Eigen::VectorXd& masses, const Eigen::VectorXd& targets) {
  MassError e;
  double sum_sq = 0;
  for (Eigen::Index i = 0; i < masses.size(); ++i) {
    const double relative = std::abs(masses[i] - targets[i]) / targets[i];
    if (relative > e.max_relative || std::isnan(relative)) e.max_relative = relative, e.worst = i;
    sum_sq += relative * relative;
    e.l2 += (masses[i] - targets[i]) * (masses[i] - targets[i]);
  }
  e.rms_relative = std::sqrt(sum_sq / static_cast<double>(std::max<Eigen::Index>(masses.size(), 1)));
  e.l2 = std::sqrt(e.l2);
  return e;
}

/// Hessian of E with the gauge fixed: H + s e₀e₀ᵀ. With Σ rhs = 0 the solution has d₀ = 0
/// and solves H d = rhs, so this pins w₀ without building a reduced matrix.
/// Built in compressed columns directly: each column gathers its off-diagonal entries, sorts
/// them by row (a few per column) and sums a pair's repeats (two cells can share several
/// facets); four times faster than setFromTriplets, whose generic path sorted and merged four
/// triplets per facet (bunny_35k's sites: 7–11 ms against 1.6–3.2 ms per matrix).
/// From 2¹⁶ facets the columns are split in one contiguous range per thread: each thread reads
/// every facet weight in order and keeps those of its columns, so every column gathers its
/// entries, and sums its diagonal, in the order of `facet_weights` whatever the thread count;
/// equal input gives an equal matrix, bit for bit.
/// With `arc_weights` (partial transport), they add to the diagonal; the matrix is then definite
/// as soon as one arc weight is positive, and no site is pinned.
inline SparseMatrix assemble_hessian(Eigen::Index n, const std::vector<Eigen::Triplet<double>>& facet_weights,
                                     const Eigen::VectorXd& arc_weights = {}) {
  const auto column_size = static_cast<std::size_t>(n);
  std::vector<int> start(column_size + 1, 0);
  double largest = 0;
  for (const auto& t : facet_weights) {
    ++start[static_cast<std::size_t>(t.row()) + 1], ++start[static_cast<std::size_t>(t.col()) + 1];
    largest = std::max(largest, std::abs(t.value()));
  }
  for (std::size_t c = 0; c < column_size; ++c) start[c + 1] += start[c];
  struct Entry {
    int row;
    double value;
  };
  // Not value-initialised: every entry is written below (zeroing them cost a third of the time).
  const std::unique_ptr<Entry[]> entries(new Entry[static_cast<std::size_t>(start[column_size])]);
  Eigen::VectorXd diagonal = Eigen::VectorXd::Zero(n);
  std::vector<int> merged(column_size);  // each column's entry count once repeats are summed, diagonal included
  const bool parallel = facet_weights.size() >= (std::size_t{1} << 16);
#pragma omp parallel if (parallel)
  {
#ifdef _OPENMP
    const auto threads = static_cast<std::size_t>(omp_get_num_threads());
    const auto thread = static_cast<std::size_t>(omp_get_thread_num());
#else
    const std::size_t threads = 1, thread = 0;
#endif
    const std::size_t first_column = column_size * thread / threads;
    const std::size_t last_column = column_size * (thread + 1) / threads;
    std::vector<int> cursor(start.begin() + static_cast<std::ptrdiff_t>(first_column),
                            start.begin() + static_cast<std::ptrdiff_t>(last_column));
    auto mine = [&](int c) {
      return static_cast<std::size_t>(c) >= first_column && static_cast<std::size_t>(c) < last_column;
    };
    for (const auto& t : facet_weights) {
      const int i = t.row(), j = t.col();
      const double w = t.value();
      if (mine(j)) {
        entries[static_cast<std::size_t>(cursor[static_cast<std::size_t>(j) - first_column]++)] = Entry{i, -w};
        diagonal[j] += w;
      }
      if (mine(i)) {
        entries[static_cast<std::size_t>(cursor[static_cast<std::size_t>(i) - first_column]++)] = Entry{j, -w};
        diagonal[i] += w;
      }
    }
    // Sorted by row (insertion sort: stable, so a pair's repeats are summed in input order, and
    // fast on a few entries), repeats summed in place.
    for (std::size_t c = first_column; c < last_column; ++c) {
      Entry* const first = entries.get() + start[c];
      Entry* const last = entries.get() + start[c + 1];
      for (Entry* it = first; it != last; ++it)
        for (Entry* back = it; back != first && (back - 1)->row > back->row; --back) std::swap(back[-1], back[0]);
      Entry* out = first;
      for (Entry* it = first; it != last; ++it)
        if (out != first && (out - 1)->row == it->row)
          (out - 1)->value += it->value;
        else
          *out++ = *it;
      merged[c] = static_cast<int>(out - first) + 1;
    }
  }
  if (arc_weights.size() == n) diagonal += arc_weights;
  if (!(arc_weights.size() == n && arc_weights.maxCoeff() > 0)) diagonal[0] += largest > 0 ? largest : 1.0;
  SparseMatrix hessian(n, n);
  int* outer = hessian.outerIndexPtr();
  outer[0] = 0;
  for (std::size_t c = 0; c < column_size; ++c) outer[c + 1] = outer[c] + merged[c];
  hessian.resizeNonZeros(outer[column_size]);
  int* inner = hessian.innerIndexPtr();
  double* values = hessian.valuePtr();
#pragma omp parallel for schedule(static) if (parallel)
  for (std::ptrdiff_t column = 0; column < static_cast<std::ptrdiff_t>(n); ++column) {
    const auto c = static_cast<std::size_t>(column);
    const Entry* it = entries.get() + start[c];
    const Entry* const last = it + (merged[c] - 1);
    int written = outer[c];
    for (; it != last && it->row < column; ++it) inner[written] = it->row, values[written++] = it->value;
    inner[written] = static_cast<int>(column), values[written++] = diagonal[column];
    for (; it != last; ++it) inner[written] = it->row, values[written++] = it->value;
  }
  return hessian;
}

/// How accurately an iterative solver must solve the Newton system at max relative mass error
/// `error` (inexact Newton, Dembo–Eisenstat–Steihaug): each cell's linearised mass within
/// 0.03·error² of its target, relatively, keeps the quadratic convergence (the Newton remainder
/// itself is about 0.2–0.26·error² on all three geometries, so 0.1·error² cost H² an iteration at
/// 10⁵ sites); at most 0.1, so that a full step cannot empty a cell through the solver's error
/// alone; at least a tenth of the tolerance, which is all the last step needs.
inline double newton_accuracy(double error, double tolerance) {
  return std::max(std::min(0.1, 0.03 * error * error), 0.1 * tolerance);
}

/// Whether a line search's trial keeps every cell's mass above its floor: ε₀ (KMT's rule, math.md
/// §3) for a cell whose current mass is at least 2ε₀; half its current mass for a cell already
/// below that, yet never below ε₀/8. The floor is uniform (ε₀/8), so KMT's convergence argument
/// holds with ε₀/8, and a short enough step always passes (to first order a cell loses at most a
/// fraction of its mass proportional to the step).
/// Why: a cell near ε₀ that the Newton step shrinks a little held every step back. On a spiky
/// mesh's spherical map (cones_60k, 77,208 sites), one cell at 1.03ε₀ would have gone to 0.6ε₀
/// with the full step, which cut the mass error's ‖·‖₂ 24-fold; KMT's rule kept steps of ⅛ to
/// 1/32 for 5 iterations along ε₀ (13 Newton iterations in all, 10 with this rule).
inline bool above_mass_floor(const Eigen::VectorXd& trial_masses, const Eigen::VectorXd& current_masses,
                             double epsilon0) {
  for (Eigen::Index i = 0; i < trial_masses.size(); ++i) {
    const double floor = std::max(epsilon0 / 8, std::min(epsilon0, current_masses[i] / 2));
    if (!(trial_masses[i] >= floor)) return false;
  }
  return true;
}

/// Step halvings at most in a line search once the error is below Options::precision_floor_threshold.
inline constexpr int floor_step_halvings = 10;

/// The relative residual ‖rhs − H d‖₂ / ‖rhs‖₂ asked of an iterative Newton solve, next to the
/// per-cell bound of newton_accuracy().
inline constexpr double newton_descent_factor = 0.1;

/// How much a Newton step may ask a cell to grow: to at most this factor of its current mass (see
/// limit_newton_growth).
inline constexpr double newton_growth_limit = 4;

/// The Newton right-hand side ν − μ (`rhs`) towards nearer targets ν': each ν_i lowered to at most
/// newton_growth_limit times the current mass μ_i, then, unless `partial` (whose total mass
/// moves), all scaled up so that Σν' = Σμ, as every diagram's masses do. Used when some target
/// moved and ‖ν' − ν‖₂ ≤ ¼‖ν − μ‖₂; otherwise `rhs` is returned unchanged.
/// Why: from a Voronoi start some cells are far smaller than their targets, and the full step
/// that grows them to it emptied a cell on all four geometries, so that the first line search
/// built two or three diagrams for nothing and kept a step of ¼ or ⅛ (sphere, 10⁵ uniform random
/// sites: max relative error 3.97 → 3.02); towards the nearer targets the full step is taken
/// (→ 0.91). Only growth is limited: limiting shrinking as well cost 1–2 more iterations where
/// the targets vary 100× (the conformance suite's random problems). The quarter bound keeps the
/// line search's test within reach: to first order a step t moves the error e = μ − ν to e + t·c
/// (c = ν' − μ), and ‖e + c‖₂ ≤ ¼‖e‖₂ gives ‖e + t·c‖₂ ≤ (1 − ¾t)‖e‖₂ < (1 − t/2)‖e‖₂, so short
/// steps pass, as Newton's do. The targets stay above the line search's floor ε₀ (at most half of
/// every ν_i, and below every accepted μ_i): ν'_i ≥ min(ν_i, 4μ_i). Near the solution no target
/// moves and the step is Newton's.
inline Eigen::VectorXd limit_newton_growth(const Eigen::VectorXd& rhs, const Eigen::VectorXd& masses, bool partial) {
  Eigen::VectorXd limited = rhs.cwiseMin((newton_growth_limit - 1) * masses);
  if (limited == rhs) return rhs;
  if (!partial) {
    const Eigen::VectorXd targets = masses + limited;
    limited = targets * (masses.sum() / targets.sum()) - masses;
    limited.array() -= limited.mean();  // round-off, as for Newton's right-hand side
  }
  return (limited - rhs).norm() <= 0.25 * rhs.norm() ? limited : rhs;
}

template <class S>
class NewtonLinearSolver {
 public:
  explicit NewtonLinearSolver(const Options& options) {
    if constexpr (requires(S s) { s.setTolerance(1.0); }) solver_.setTolerance(options.cg_tolerance);
#ifdef SDOT_HAVE_CHOLMOD
    if constexpr (std::is_same_v<S, CholmodSolver>) use_single_threaded_blas();
#endif
  }
  /// Solves H d = rhs; false when the factorisation or the iteration failed. An iterative solver
  /// that takes a scaled tolerance (MultigridSolver) stops once every cell's predicted mass is
  /// within `relative_accuracy` of its target, |(rhs − H d)_i| ≤ relative_accuracy·ν_i, and
  /// ‖rhs − H d‖₂ ≤ newton_descent_factor·‖rhs‖₂.
  bool solve(const SparseMatrix& hessian, const Eigen::VectorXd& rhs, Eigen::VectorXd& direction,
             const Eigen::VectorXd& targets = {}, double relative_accuracy = 0) {
    if constexpr (requires(S s) { s.set_scaled_tolerance(targets, 1.0); })
      if (targets.size() == rhs.size()) {
        solver_.set_scaled_tolerance(targets.cwiseInverse(), relative_accuracy);
        // ‖r‖₂ ≤ η‖rhs‖₂ with η < 1 makes the step a descent direction of the mass error; the
        // per-cell bound alone did not (a bound of 0.1·ν_i in every cell can exceed the error of
        // a nearly converged diagram, and the line search then failed). η = 0.1 is enough for
        // that; the accuracy comes from the per-cell bound. η = relative_accuracy instead asked
        // for up to 7 more digits than the per-cell bound near the solution (plane, 10⁶ sites,
        // tolerance 1e-6: 83 conjugate-gradient iterations in all, against 57 with η = 0.1, for
        // the same Newton steps).
        solver_.setTolerance(newton_descent_factor);
      }
    if constexpr (FactorizingLinearSolver<S>) {
      if (!same_pattern(hessian)) {
        solver_.analyzePattern(hessian);
        outer_.assign(hessian.outerIndexPtr(), hessian.outerIndexPtr() + hessian.outerSize() + 1);
        inner_.assign(hessian.innerIndexPtr(), hessian.innerIndexPtr() + hessian.nonZeros());
      }
      solver_.factorize(hessian);
    } else {
      solver_.compute(hessian);
    }
    if (solver_.info() != Eigen::Success) return false;
    direction = solver_.solve(rhs);
    return solver_.info() == Eigen::Success && direction.allFinite();
  }
  /// How many symbolic analyses were done (pattern reuse is visible in tests).
  [[nodiscard]] int analyses() const {
    return analyses_;
  }

 private:
  bool same_pattern(const SparseMatrix& m) {
    const bool same = static_cast<Eigen::Index>(outer_.size()) == m.outerSize() + 1 &&
                      static_cast<Eigen::Index>(inner_.size()) == m.nonZeros() &&
                      std::equal(outer_.begin(), outer_.end(), m.outerIndexPtr()) &&
                      std::equal(inner_.begin(), inner_.end(), m.innerIndexPtr());
    if (!same) ++analyses_;
    return same;
  }
  S solver_;
  std::vector<int> outer_, inner_;
  int analyses_ = 0;
};

/// ρ_t = a·ρ + b (b uniform): the continuation density for sources that vanish on part of the domain.
template <class D>
struct BlendedDensity {
  const D& density;
  double density_factor;
  double uniform_level;
  template <class G>
  [[nodiscard]] CellIntegrals<typename G::Point> integrate_cell(const G& geometry, const Cell<typename G::Point>& cell,
                                                                const typename G::Point& site,
                                                                bool with_cost = true) const {
    auto result = density.integrate_cell(geometry, cell, site, with_cost);
    const auto uniform = geometry.integrate(cell, site, with_cost);
    result.mass = density_factor * result.mass + uniform_level * uniform.mass;
    result.first_moment = density_factor * result.first_moment + uniform_level * uniform.first_moment;
    result.cost = density_factor * result.cost + uniform_level * uniform.cost;
    return result;
  }
  template <class G>
  [[nodiscard]] double facet_weight(const G& geometry, const typename G::Point& a, const typename G::Point& b,
                                    const typename G::Point& site_i, double weight_i, const typename G::Point& site_j,
                                    double weight_j) const {
    return density_factor * density.facet_weight(geometry, a, b, site_i, weight_i, site_j, weight_j) +
           uniform_level * geometry.facet_weight(a, b, site_i, weight_i, site_j, weight_j);
  }
};

/// The geometry's diagram; with `stop_at_empty_cell`, geometries that can (an optional
/// `build_diagram(sites, weights, true)`) stop at the first empty cell and leave the rest empty.
template <class G>
Diagram<typename G::Point> build_diagram(const G& geometry, std::span<const typename G::Point> sites,
                                         const Eigen::VectorXd& weights, bool stop_at_empty_cell) {
  if constexpr (requires { geometry.build_diagram(sites, weights, true); })
    return geometry.build_diagram(sites, weights, stop_at_empty_cell);
  else
    return geometry.build_diagram(sites, weights);
}

inline bool usable_status(Status status) {
  return status == Status::converged || status == Status::precision_floor;
}

/// The indices of `points` sorted along a Morton (Z-order) curve over their bounding box, ties
/// by index: deterministic, O(n log n), for points of any fixed dimension.
template <class Point>
std::vector<Eigen::Index> spatial_order(std::span<const Point> points) {
  constexpr int dimension = Point::RowsAtCompileTime;
  static_assert(dimension > 0 && dimension <= 3, "spatial_order: points of dimension 1 to 3");
  constexpr int bits = 63 / dimension;
  Point low = Point::Constant(std::numeric_limits<double>::infinity()), high = -low;
  for (const auto& p : points) low = low.cwiseMin(p), high = high.cwiseMax(p);
  std::vector<std::pair<std::uint64_t, Eigen::Index>> keyed(points.size());
  const double cells = std::ldexp(1.0, bits) - 1;
  for (std::size_t i = 0; i < points.size(); ++i) {
    std::uint64_t code = 0;
    std::array<std::uint64_t, 3> cell{};
    for (int d = 0; d < dimension; ++d) {
      const double extent = high[d] - low[d];
      const double t = extent > 0 ? (points[i][d] - low[d]) / extent : 0;
      cell[static_cast<std::size_t>(d)] = static_cast<std::uint64_t>(std::clamp(t, 0.0, 1.0) * cells);
    }
    for (int bit = bits - 1; bit >= 0; --bit)
      for (std::size_t d = 0; d < static_cast<std::size_t>(dimension); ++d)
        code = (code << 1) | ((cell[d] >> bit) & 1u);
    keyed[i] = {code, static_cast<Eigen::Index>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<Eigen::Index> order(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) order[i] = keyed[i].second;
  return order;
}

template <LinearSolver S, Geometry G, Density<G> D>
Result<typename G::Point> solve_in_order(const G& geometry, const D& density, std::span<const typename G::Point> sites,
                                         const Eigen::VectorXd& target_masses, const Options& options,
                                         std::optional<Eigen::VectorXd> initial_weights,
                                         std::span<const Eigen::Index> original, Clock::time_point start);

/// Weights for a partial start from `weights`, whose uncut Laguerre cells are `diagram`: with
/// `common_shift`, first weights + K, K the shift (which leaves the Laguerre diagram as it is) at
/// which the cut cells together carry the target mass (Illinois' regula falsi, to 0.1 %); then the
/// weight of each cell that would still be empty raised until its ball reaches a tenth of the way
/// across its cell's cost range. Raising a weight shrinks the neighbours' Laguerre cells, so the
/// caller checks the result; with `common_floor` the raise is one common shift instead (the
/// largest such raise), which keeps the diagram and so cannot empty a cell.
template <PartialGeometry G>
Eigen::VectorXd partial_start_weights(const G& geometry, std::span<const typename G::Point> sites,
                                      const Eigen::VectorXd& weights, const Diagram<typename G::Point>& diagram,
                                      const Eigen::VectorXd& targets, bool common_shift, bool common_floor = false) {
  const auto n = static_cast<Eigen::Index>(sites.size());
  double lowest = INFINITY, highest = -INFINITY;
  Eigen::VectorXd reach = Eigen::VectorXd::Constant(n, -INFINITY);  // the least weight that reaches in
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto& cell = diagram.cells[static_cast<std::size_t>(i)];
    if (cell.empty()) continue;
    const auto [nearest, farthest] = geometry.cost_range(cell, sites[static_cast<std::size_t>(i)]);
    lowest = std::min(lowest, nearest - weights[i]), highest = std::max(highest, farthest - weights[i]);
    reach[i] = nearest + 0.01 * (farthest - nearest);
  }
  double shift = 0;
  Eigen::VectorXd masses(n);
  auto excess = [&](double k) {  // the cut cells' total mass minus the targets'
#pragma omp parallel for schedule(dynamic, 256)
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto& site = sites[static_cast<std::size_t>(i)];
      const auto cut = geometry.cut_by_ball(diagram.cells[static_cast<std::size_t>(i)], site, weights[i] + k);
      masses[i] = cut.empty() ? 0.0 : geometry.integrate(cut, site, false).mass;
    }
    return masses.sum() - targets.sum();
  };
  if (common_shift && lowest < highest) {
    double a = lowest, fa = -targets.sum(), b = highest, fb = excess(highest);
    shift = b;
    for (int iteration = 0; iteration < 100 && fb != fa; ++iteration) {
      shift = (a * fb - b * fa) / (fb - fa);
      const double fc = excess(shift);
      if (std::abs(fc) <= 1e-3 * targets.sum()) break;
      if ((fc > 0) != (fb > 0)) {
        a = b, fa = fb;
      } else {
        fa /= 2;
      }
      b = shift, fb = fc;
    }
  }
  if (common_floor) return weights.array() + std::max(shift, (reach - weights).maxCoeff());
  // Raise only the cells that would start empty (`masses` already holds the cuts at the final
  // shift when the regula falsi ran: its last evaluation is at `shift`).
  if (!(common_shift && lowest < highest)) excess(shift);
  Eigen::VectorXd result = weights.array() + shift;
  for (Eigen::Index i = 0; i < n; ++i)
    if (!(masses[i] > 0)) result[i] = std::max(result[i], reach[i]);
  return result;
}

/// The start of a partial solve: replaces `weights` (the Voronoi or default weights, whose uncut
/// diagram `uncut_given` has every cell non-empty) by weights at which every cut cell is non-empty, and returns their
/// evaluation. First choice: each ball with the area of its target mass (right when the sites are sparse); where that
/// empties a cell (a small target next to a large one), the common shift of the given weights with the empty cells
/// raised (partial_start_weights), repeated a few times, and as a last resort one common shift large enough for every
/// cell.
template <PartialGeometry G, Density<G> D>
Evaluation<typename G::Point> partial_start(const G& geometry, const D& density,
                                            std::span<const typename G::Point> sites, const Eigen::VectorXd& targets,
                                            Eigen::VectorXd& weights, const Diagram<typename G::Point>& uncut_given,
                                            Timings& timings) {
  Eigen::VectorXd discs = targets.unaryExpr([&](double mass) { return double(geometry.ball_weight(mass)); });
  if (discs.allFinite()) {
    auto trial = evaluate(geometry, density, sites, discs, true, &timings, false, true, true);
    if (trial.masses.minCoeff() > 0) {
      weights = std::move(discs);
      return trial;
    }
  }
  const Eigen::VectorXd given = weights;
  weights = partial_start_weights(geometry, sites, given, uncut_given, targets, true);
  for (int round = 0; round < 10; ++round) {
    auto trial = evaluate(geometry, density, sites, weights, true, &timings, false, false, true);
    if (trial.masses.minCoeff() > 0) return trial;
    const auto uncut = evaluate(geometry, density, sites, weights, false, &timings, false);
    if (std::any_of(uncut.diagram.cells.begin(), uncut.diagram.cells.end(),
                    [](const auto& cell) { return cell.empty(); }))
      break;
    weights = partial_start_weights(geometry, sites, weights, uncut.diagram, targets, false);
  }
  weights = partial_start_weights(geometry, sites, given, uncut_given, targets, true, true);
  return evaluate(geometry, density, sites, weights, true, &timings, false, false, true);
}

inline void validate_targets(const Eigen::VectorXd& targets, std::size_t site_count) {
  if (static_cast<std::size_t>(targets.size()) != site_count)
    throw InputError("masses", "there are " + std::to_string(targets.size()) + " masses for " +
                                   std::to_string(site_count) + " sites");
  for (Eigen::Index i = 0; i < targets.size(); ++i)
    if (!(std::isfinite(targets[i]) && targets[i] > 0))
      throw InputError(indexed("masses", static_cast<std::size_t>(i)),
                       "must be a positive finite number, got " + std::to_string(targets[i]));
}

}  // namespace sdot::detail

template <sdot::Geometry G, sdot::Density<G> D>
sdot::Evaluation<typename G::Point> sdot::evaluate(const G& geometry, const D& density,
                                                   std::span<const typename G::Point> sites,
                                                   const Eigen::VectorXd& weights, bool with_hessian, Timings* timings,
                                                   bool with_cost, bool stop_at_empty_cell, bool partial) {
  using Point = typename G::Point;
  if constexpr (!PartialGeometry<G>)
    if (partial)
      throw InputError("partial", std::string("the ") + std::string(G::name()) + " geometry has no ball cuts");
  auto start = detail::Clock::now();
  Evaluation<Point> result;
  result.diagram = detail::build_diagram(geometry, sites, weights, stop_at_empty_cell);
  if (timings) timings->diagram_s += detail::seconds_since(start);
  start = detail::Clock::now();
  const auto n = static_cast<std::ptrdiff_t>(sites.size());
  result.integrals.resize(sites.size());
  result.masses.resize(n);
  // Densities may reject their input (InputError) from inside the parallel loop; exceptions
  // cannot leave an OpenMP region, so the first one is carried out and rethrown.
  std::exception_ptr failure;
  // Cells go in blocks of 256; each block keeps its own facet weights, and the blocks are joined
  // in index order. The result is the same whatever thread ran a block (reproducible Hessians)
  // without sorting all the weights afterwards.
  constexpr std::ptrdiff_t block_size = 256;
  const std::ptrdiff_t block_count = (n + block_size - 1) / block_size;
  std::vector<std::vector<Eigen::Triplet<double>>> block_weights(with_hessian ? static_cast<std::size_t>(block_count)
                                                                              : 0);
  if (partial && with_hessian) result.arc_weights = Eigen::VectorXd::Zero(n);
#pragma omp parallel for schedule(dynamic, 1)
  for (std::ptrdiff_t block = 0; block < block_count; ++block)
    for (std::ptrdiff_t i = block * block_size; i < std::min(n, (block + 1) * block_size); ++i) try {
        auto& cell = result.diagram.cells[i];
        if constexpr (PartialGeometry<G>)
          if (partial) cell = geometry.cut_by_ball(cell, sites[i], weights[i]);
        if (cell.empty()) {
          result.integrals[i] = CellIntegrals<Point>{};
          result.masses[i] = 0;
          continue;
        }
        result.integrals[i] = density.integrate_cell(geometry, cell, sites[i], with_cost);
        result.masses[i] = result.integrals[i].mass;
        if (!with_hessian) continue;
        if constexpr (PartialGeometry<G>)
          if (partial) result.arc_weights[i] = geometry.arc_weight(cell, sites[i]);
        auto& local = block_weights[static_cast<std::size_t>(block)];
        for (std::size_t k = 0; k < cell.size(); ++k) {
          const int j = cell.neighbors[k];
          if (is_boundary(j) || j <= i) continue;  // each pair once, from the lower index
          const Point& a = cell.vertices[k];
          const Point& b = cell.vertices[(k + 1) % cell.size()];
          const double w = density.facet_weight(geometry, a, b, sites[i], weights[i], sites[j], weights[j]);
          if (w != 0) local.emplace_back(static_cast<int>(i), j, w);
        }
      } catch (...) {
#pragma omp critical
        if (!failure) failure = std::current_exception();
      }
  if (failure) std::rethrow_exception(failure);
  std::size_t total = 0;
  for (const auto& block : block_weights) total += block.size();
  result.facet_weights.reserve(total);
  for (auto& block : block_weights) {
    result.facet_weights.insert(result.facet_weights.end(), block.begin(), block.end());
    std::vector<Eigen::Triplet<double>>().swap(block);  // no second copy of every weight at once
  }
  if (timings) timings->assembly_s += detail::seconds_since(start);
  return result;
}

/// The solver on sites in the order `solve_with` chose: `original[i]` is the caller's index of
/// site i, used in every message that names a site. Input already validated.
template <sdot::LinearSolver S, sdot::Geometry G, sdot::Density<G> D>
sdot::Result<typename G::Point> sdot::detail::solve_in_order(
    const G& geometry, const D& density, std::span<const typename G::Point> sites, const Eigen::VectorXd& target_masses,
    const Options& options, std::optional<Eigen::VectorXd> initial_weights, std::span<const Eigen::Index> original,
    Clock::time_point start) {
  using Point = typename G::Point;
  const auto n = static_cast<Eigen::Index>(sites.size());
  auto site_name = [&](Eigen::Index i) { return std::to_string(original[static_cast<std::size_t>(i)]); };

  Result<Point> result;
  Summary& summary = result.summary;
  Eigen::VectorXd weights;
  const bool user_weights = initial_weights.has_value();
  const bool partial = options.partial;
  if (user_weights) {
    weights = std::move(*initial_weights);
  } else if (partial) {
    weights = Eigen::VectorXd::Zero(n);  // see the start of partial transport below
  } else {
    weights = geometry.default_weights(sites);
  }
  // Partial transport has no free constant: the weights set the balls' radii.
  if (!partial) weights.array() -= weights.mean();

  Evaluation<Point> current =
      evaluate(geometry, density, sites, weights, true, &summary.timings, false, false, partial && user_weights);
  if (partial && !user_weights &&
      std::any_of(current.diagram.cells.begin(), current.diagram.cells.end(),
                  [](const auto& cell) { return cell.empty(); })) {
    weights = geometry.default_weights(sites);  // the Voronoi diagram has empty cells
    current = evaluate(geometry, density, sites, weights, true, &summary.timings, false);
  }
  // The lowest caller's index among the empty cells of `current`, or −1.
  auto first_empty_cell = [&] {
    Eigen::Index first = -1;
    for (Eigen::Index i = 0; i < n; ++i)
      if (current.diagram.cells[static_cast<std::size_t>(i)].empty() &&
          (first < 0 || original[static_cast<std::size_t>(i)] < original[static_cast<std::size_t>(first)]))
        first = i;
    return first;
  };
  auto empty_start_error = [&](Eigen::Index i) {
    return InputError(indexed("weights", static_cast<std::size_t>(original[static_cast<std::size_t>(i)])),
                      "the initial weights leave the cell of site " + site_name(i) +
                          " empty; the damped Newton method needs every cell non-empty at the start");
  };
  // Before the source mass, which is summed over the cells: with every cell empty it would blame
  // the density. Every cell empty means no diagram at all: the builders' bisectors overflow or
  // keep no digit.
  if (!partial && std::all_of(current.diagram.cells.begin(), current.diagram.cells.end(),
                              [](const auto& cell) { return cell.empty(); })) {
    if (user_weights)
      throw InputError("weights", "the initial weights, from " + detail::format_number(weights.minCoeff()) + " to " +
                                      detail::format_number(weights.maxCoeff()) +
                                      " after centring, give no diagram in double precision");
    throw InputError("sites", "the default weights give no diagram of these sites in double precision");
  }
  if (user_weights && !partial) {
    if (const Eigen::Index i = first_empty_cell(); i >= 0) throw empty_start_error(i);
  }
  if (partial && user_weights) {
    summary.source_mass = evaluate(geometry, density, sites, weights, false, nullptr, false).masses.sum();
  } else {
    summary.source_mass = current.masses.sum();
  }
  if (!(summary.source_mass > 0))
    throw InputError("density", "has no mass on the source domain (it vanishes wherever the domain is)");
  Eigen::VectorXd targets = target_masses;
  const double target_sum = targets.sum();
  if (partial) {
    if (!(target_sum < summary.source_mass))
      throw InputError("masses", "partial transport needs masses that sum to less than the source mass; they sum to " +
                                     detail::format_number(target_sum) + ", the source mass is " +
                                     detail::format_number(summary.source_mass));
    if constexpr (PartialGeometry<G>)
      if (!user_weights)
        current = partial_start(geometry, density, sites, targets, weights, current.diagram, summary.timings);
  } else {
    summary.mass_scale = summary.source_mass / target_sum;
    if (!options.rescale_masses && std::abs(summary.mass_scale - 1) > options.mass_sum_tolerance)
      throw InputError("masses", "they sum to " + detail::format_number(target_sum) + " but the source mass is " +
                                     detail::format_number(summary.source_mass) +
                                     " (enable options.rescale_masses to rescale them)");
    targets *= summary.mass_scale;
  }

  const Eigen::Index first_empty = first_empty_cell();
  auto finish = [&](Status status, std::string message) {
    summary.status = status;
    summary.message = std::move(message);
    result.weights = weights;
    result.masses = current.masses;
    result.target_masses = targets;
    // The transport cost, needed only now: integrated once on the final cells.
    result.transport_cost = std::numeric_limits<double>::quiet_NaN();
    if (options.compute_transport_cost) {
      const auto cost_start = detail::Clock::now();
      Eigen::VectorXd costs = Eigen::VectorXd::Zero(n);
      std::exception_ptr failure;  // as in evaluate(): exceptions cannot leave the OpenMP region
#pragma omp parallel for schedule(dynamic, 256)
      for (Eigen::Index i = 0; i < n; ++i) try {
          if (!current.diagram.cells[i].empty())
            costs[i] = density.integrate_cell(geometry, current.diagram.cells[i], sites[i], true).cost;
        } catch (...) {
#pragma omp critical
          if (!failure) failure = std::current_exception();
        }
      if (failure) std::rethrow_exception(failure);
      summary.timings.assembly_s += detail::seconds_since(cost_start);
      result.transport_cost = costs.sum();
    }
    result.centroids.resize(sites.size());
    for (Eigen::Index i = 0; i < n; ++i)
      result.centroids[i] = current.masses[i] > 0 ? Point(geometry.centroid(current.integrals[i])) : sites[i];
    result.diagram = std::move(current.diagram);
    if constexpr (PartialGeometry<G>)
      if (partial) result.ball_radii = weights.unaryExpr([&](double w) { return double(geometry.ball_radius(w)); });
    summary.timings.total_s = detail::seconds_since(start);
    // Moved, not copied: `result` is captured by reference, so a plain return would copy every
    // cell (sphere, 10⁵ sites: 17 ms).
    return std::move(result);
  };
  if (first_empty >= 0) {
    if (user_weights) throw empty_start_error(first_empty);
    return finish(Status::line_search_failure,
                  "the cell of site " + site_name(first_empty) + " is empty at the default start");
  }

  // Optional so that its multigrid hierarchy can be freed before the result is assembled.
  std::optional<detail::NewtonLinearSolver<S>> linear_solver(std::in_place, options);
  auto& linear = *linear_solver;
  detail::MassError error;
  int iteration = 0;
  auto record = [&](double step) {
    IterationRecord r{iteration, error.max_relative, error.rms_relative, step, detail::seconds_since(start)};
    summary.history.push_back(r);
    summary.iterations = iteration;
    summary.max_relative_error = error.max_relative;
    summary.rms_relative_error = error.rms_relative;
    if (options.callback) options.callback(r);
  };
  auto floor_message = [&] {
    return "stopped at the precision floor: max relative mass error " + detail::format_number(error.max_relative) +
           " (tolerance " + detail::format_number(options.tolerance) +
           " is below what double precision reaches for this problem)";
  };
  // Damped Newton (KMT) for `source` from the current weights down to `tolerance`; `current`
  // must hold the evaluation of `source` at `weights`.
  auto newton = [&](const auto& source, double tolerance) -> std::pair<Status, std::string> {
    const double epsilon0 = 0.5 * std::min(current.masses.minCoeff(), targets.minCoeff());
    error = detail::mass_error(current.masses, targets);
    record(0);
    int small_steps = 0;  // consecutive heavily damped steps near the solution
    for (;;) {
      if (error.max_relative <= tolerance)
        return {Status::converged, "converged: max relative mass error " + detail::format_number(error.max_relative) +
                                       " <= " + detail::format_number(tolerance)};
      if (iteration >= options.max_iterations)
        return {Status::iteration_limit, "iteration limit (" + std::to_string(options.max_iterations) +
                                             ") reached with max relative mass error " +
                                             detail::format_number(error.max_relative) + " at site " +
                                             site_name(error.worst)};
      ++iteration;
      auto linear_start = detail::Clock::now();
      Eigen::VectorXd rhs = targets - current.masses;
      // Σ rhs = Σν − Σμ is zero up to summation round-off (~1e-13 for 10⁴ cells); spread it evenly
      // (putting it on the pinned site would cap that site's accuracy at ~1e-9). Not so for partial
      // transport, whose total mass moves with the weights.
      if (!partial) rhs.array() -= rhs.mean();
      rhs = detail::limit_newton_growth(rhs, current.masses, partial);
      Eigen::VectorXd direction;
      bool solved = false;
      {
        // From here on only the current masses are needed: the cells, integrals and facet weights
        // (about 300 bytes per site) are freed for the linear solve and the trial diagrams, and
        // rebuilt should no step be accepted. The cells go before the matrix is assembled, which
        // was the solve's peak of memory (sphere, 10⁶ sites: 1027 MB, 983 MB with this order).
        current.diagram = {};
        current.integrals = {};
        const SparseMatrix hessian = detail::assemble_hessian(n, current.facet_weights, current.arc_weights);
        current.facet_weights = {};
        current.arc_weights = {};
        solved = linear.solve(hessian, rhs, direction, targets, detail::newton_accuracy(error.max_relative, tolerance));
      }
      summary.timings.linear_solve_s += detail::seconds_since(linear_start);
      auto restore_current = [&] {
        current = evaluate(geometry, source, sites, weights, true, &summary.timings, false, false, partial);
      };
      if (!solved) {
        restore_current();
        return {Status::linear_solve_failure,
                "the Newton system could not be solved (is the cell adjacency graph, or the density's support, "
                "disconnected?)"};
      }

      bool accepted = false;
      // Trial steps 1, ¾, ½, ¼, …: KMT's halvings with ¾ between the first two, whose test
      // (1 − ¾/2) is KMT's at that length, so their convergence argument is unchanged. Why: far from
      // the solution the full step often empties a cell where ¾ does not, and ½ only halves
      // the error (55 spherical maps of sdot-sphere-param: 327 Newton iterations in all → 291,
      // 31 meshes fewer, 1 more; cones_60k 10 → 7). Not near the precision floor, where each
      // trial is a diagram for round-off.
      const bool three_quarters = error.max_relative > options.precision_floor_threshold;
      double step = 1;
      for (int halving = 0; halving <= options.max_step_halvings;
           step = three_quarters && step == 1 ? 0.75 : (++halving, std::ldexp(1.0, -halving))) {
        // Near the precision floor a direction that does not descend at step 2⁻¹⁰ gives nothing
        // but round-off below it, and every halving costs a diagram (the plane's floor test: 57
        // diagrams with the 40 halvings, 27 with 10).
        if (halving > detail::floor_step_halvings && error.max_relative <= options.precision_floor_threshold) break;
        Eigen::VectorXd trial_weights = weights + step * direction;
        if (!partial) trial_weights.array() -= trial_weights.mean();
        // A step that empties a cell is rejected (ε₀ > 0): the builder may stop at the first one.
        Evaluation<Point> trial =
            evaluate(geometry, source, sites, trial_weights, true, &summary.timings, false, true, partial);
        if (!detail::above_mass_floor(trial.masses, current.masses, epsilon0)) continue;
        const auto trial_error = detail::mass_error(trial.masses, targets);
        if (trial_error.l2 <= (1 - step / 2) * error.l2) {
          weights = std::move(trial_weights);
          current = std::move(trial);
          error = trial_error;
          accepted = true;
          break;
        }
      }
      if (!accepted) restore_current();
      if (!accepted && error.max_relative <= options.precision_floor_threshold)
        return {Status::precision_floor, floor_message()};
      if (!accepted)
        return {Status::line_search_failure,
                "no step length decreased the mass error after " + std::to_string(options.max_step_halvings) +
                    " halvings at max relative mass error " + detail::format_number(error.max_relative) +
                    " (above options.precision_floor_threshold: not a round-off floor)"};
      record(step);
      small_steps = step <= 1.0 / 16 && error.max_relative <= options.precision_floor_threshold ? small_steps + 1 : 0;
      if (small_steps >= 3 && error.max_relative > tolerance) return {Status::precision_floor, floor_message()};
    }
  };

  std::string prefix;
  if constexpr (std::is_same_v<D, UniformDensity>) {
    // A non-empty cell always has mass under ρ ≡ 1 (only a degenerate polygon has none).
    if (current.masses.minCoeff() <= 0)
      return finish(Status::line_search_failure, "a cell has zero area at the default start");
  } else if (current.masses.minCoeff() <= 0) {
    // Some cells lie where ρ vanishes, so the Newton system is singular. Continuation: solve for
    // ρ_t = (1 − t)ρ + t·ρ̄ (ρ̄ uniform with the same total mass, every cell gets mass) with t
    // decreasing until every cell gets mass from ρ itself.
    double area = 0;
    for (Eigen::Index i = 0; i < n; ++i)
      if (!current.diagram.cells[i].empty()) area += geometry.integrate(current.diagram.cells[i], sites[i], false).mass;
    int stages = 0;
    bool reached = false;
    std::pair<Status, std::string> outcome{Status::converged, ""};
    for (double t = 0.5; t >= 1e-12 && !reached; t *= 0.1) {
      const detail::BlendedDensity<D> blended{density, 1 - t, t * summary.source_mass / area};
      current = evaluate(geometry, blended, sites, weights, true, &summary.timings, false);
      ++stages;
      outcome = newton(blended, std::max(options.tolerance, 1e-3));
      if (!detail::usable_status(outcome.first)) break;
      current = evaluate(geometry, density, sites, weights, true, &summary.timings, false);
      reached = current.masses.minCoeff() > 0;
    }
    if (!reached) {
      // Name the sites whose cells get no mass from ρ (evaluated at the last weights).
      current = evaluate(geometry, density, sites, weights, false, &summary.timings, false);
      std::vector<Eigen::Index> starved;  // the caller's indices
      for (Eigen::Index i = 0; i < n; ++i)
        if (!(current.masses[i] > 0)) starved.push_back(original[static_cast<std::size_t>(i)]);
      std::sort(starved.begin(), starved.end());
      if (!starved.empty()) {
        std::string list;
        for (std::size_t k = 0; k < std::min<std::size_t>(starved.size(), 5); ++k)
          list += (k ? ", " : "") + std::to_string(starved[k]);
        if (starved.size() > 5) list += ", …";
        throw InputError(indexed("sites", static_cast<std::size_t>(starved.front())),
                         "the cell of this site cannot receive mass: the density vanishes everywhere its cell can "
                         "reach (" +
                             std::to_string(starved.size()) + " such sites: " + list + ")");
      }
      return finish(outcome.first, "continuation from a uniform density failed: " + outcome.second);
    }
    prefix = "after " + std::to_string(stages) + " continuation stage" + (stages > 1 ? "s" : "") +
             " (the density vanishes on part of the domain): ";
  }
  auto [status, message] = newton(density, options.tolerance);
  linear_solver.reset();
  return finish(status, prefix + message);
}

template <sdot::LinearSolver S, sdot::Geometry G, sdot::Density<G> D>
sdot::Result<typename G::Point> sdot::solve_with(const G& geometry, const D& density,
                                                 std::span<const typename G::Point> sites,
                                                 const Eigen::VectorXd& target_masses, const Options& options,
                                                 std::optional<Eigen::VectorXd> initial_weights) {
  using Point = typename G::Point;
  const auto start = detail::Clock::now();
  options.validate();
  if (sites.empty()) throw InputError("sites", "at least one site is needed");
  geometry.validate_sites(sites);
  detail::validate_targets(target_masses, sites.size());
  const auto n = static_cast<Eigen::Index>(sites.size());
  if (options.partial) {
    if constexpr (!PartialGeometry<G>)
      throw InputError("partial", "the " + std::string(G::name()) + " geometry has no partial transport (ball cuts)");
    if constexpr (!std::is_same_v<D, UniformDensity>)
      throw InputError("density", "partial transport is implemented for the uniform density only");
  }
  if (initial_weights) {
    if (initial_weights->size() != n)
      throw InputError("weights", "there are " + std::to_string(initial_weights->size()) + " weights for " +
                                      std::to_string(n) + " sites");
    for (Eigen::Index i = 0; i < n; ++i)
      if (!std::isfinite((*initial_weights)[i]))
        throw InputError(indexed("weights", static_cast<std::size_t>(i)), "is not finite");
  }
  // The solve runs on the sites in a space-filling-curve order: neighbouring cells then have
  // nearby indices, which keeps the diagram, the integration and the Hessian's rows in cache and
  // lets the multigrid smoother split the rows into independent blocks. The result comes back in
  // the caller's order.
  const std::vector<Eigen::Index> order = detail::spatial_order(sites);
  std::vector<Point> local_sites(sites.size());
  Eigen::VectorXd local_targets(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    local_sites[static_cast<std::size_t>(k)] = sites[static_cast<std::size_t>(order[static_cast<std::size_t>(k)])];
    local_targets[k] = target_masses[order[static_cast<std::size_t>(k)]];
  }
  std::optional<Eigen::VectorXd> local_weights;
  if (initial_weights) {
    local_weights.emplace(n);
    for (Eigen::Index k = 0; k < n; ++k) (*local_weights)[k] = (*initial_weights)[order[static_cast<std::size_t>(k)]];
  }
  Result<Point> local = detail::solve_in_order<S>(geometry, density, std::span<const Point>(local_sites), local_targets,
                                                  options, std::move(local_weights), order, start);
  Result<Point> result;
  result.transport_cost = local.transport_cost;
  result.summary = std::move(local.summary);
  result.weights.resize(n), result.masses.resize(n), result.target_masses.resize(n);
  result.centroids.resize(sites.size());
  result.diagram.cells.resize(sites.size());
  // `order` is a permutation, so the loop below writes disjoint entries, on both cores (sphere,
  // 10⁵ sites: 9 ms on one).
  if (local.ball_radii.size() == n) result.ball_radii.resize(n);
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Index i = order[static_cast<std::size_t>(k)];
    result.weights[i] = local.weights[k];
    result.masses[i] = local.masses[k];
    result.target_masses[i] = local.target_masses[k];
    result.centroids[static_cast<std::size_t>(i)] = local.centroids[static_cast<std::size_t>(k)];
    if (local.ball_radii.size() == n) result.ball_radii[i] = local.ball_radii[k];
    auto& cell = result.diagram.cells[static_cast<std::size_t>(i)];
    cell = std::move(local.diagram.cells[static_cast<std::size_t>(k)]);
    for (int& label : cell.neighbors)
      if (!is_boundary(label)) label = static_cast<int>(order[static_cast<std::size_t>(label)]);
  }
  result.summary.timings.total_s = detail::seconds_since(start);
  return result;
}

template <sdot::Geometry G, sdot::Density<G> D>
sdot::Result<typename G::Point> sdot::solve(const G& geometry, const D& density,
                                            std::span<const typename G::Point> sites,
                                            const Eigen::VectorXd& target_masses, const Options& options,
                                            std::optional<Eigen::VectorXd> initial_weights) {
  switch (options.linear_solver) {
    case LinearSolverKind::conjugate_gradient:
      return solve_with<ConjugateGradientSolver>(geometry, density, sites, target_masses, options,
                                                 std::move(initial_weights));
    case LinearSolverKind::multigrid:
      return solve_with<MultigridSolver>(geometry, density, sites, target_masses, options, std::move(initial_weights));
    case LinearSolverKind::cholmod:
#ifdef SDOT_HAVE_CHOLMOD
      return solve_with<CholmodSolver>(geometry, density, sites, target_masses, options, std::move(initial_weights));
#endif
    case LinearSolverKind::ldlt:
      return solve_with<DefaultLinearSolver>(geometry, density, sites, target_masses, options,
                                             std::move(initial_weights));
    case LinearSolverKind::automatic:
    default:
      return solve_with<AutomaticLinearSolver>(geometry, density, sites, target_masses, options,
                                               std::move(initial_weights));
  }
}
