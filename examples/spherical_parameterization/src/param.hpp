#pragma once
/// \file param.hpp
/// The stages of the spherical area-preserving parameterization (docs/spherical_parameterization.md):
/// initial map (Tutte + inverse stereographic + Möbius balancing), OT with sdot::Sphere,
/// centroids, untangling, and a flip-free area-correcting optimization.

#include <Eigen/Core>
#include <array>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "mesh.hpp"

namespace sphparam {

/// From this many unknowns the Tutte systems are factorised by CHOLMOD's supernodal Cholesky,
/// which is faster there than Eigen's LDLᵀ (igea_134k: 0.61 s against 1.09 s). The Newton
/// systems go to the library's default solver (multigrid-preconditioned CG at these sizes).
/// Below it Eigen's LDLᵀ, its first system in AMD order and the others in METIS's (computed on
/// the other core meanwhile). From 20,000 rather than 45,000 unknowns (interleaved, the initial
/// map): spiky_25k 0.29-0.30 s -> 0.13-0.14 s, folds_25k 0.17 s -> 0.06-0.08 s, capsule40_25k
/// (16 systems, split in halves) 0.58 s -> 0.44 s, capsule_25k 0.67 s -> 0.50 s, bunny_35k
/// 0.54-0.85 s -> 0.51-0.54 s; but armadillo_43k (11 systems) 0.61-0.65 s -> 0.71-0.76 s, where
/// METIS's order needs a fifth of the flops of the nested dissections CHOLMOD's path makes
/// (6.4e7 against 3.5e8) and takes 0.25 s to compute. Below 20,000 within the noise.
inline constexpr long cholmod_from_unknowns = 20000;
/// Up to this many unknowns CHOLMOD amalgamates the Tutte factor's supernodes more than by
/// default: fewer, larger supernodes are faster at 120k unknowns; at 775k and 2.1M they cost
/// memory and no time (param.cpp, LaplacianSolver::analyse). The bound lies between.
inline constexpr long coarse_supernodes_up_to = 250000;

/// Vertex adjacency (CSR, sorted) and per-vertex incident faces of a closed triangle mesh.
struct Topology {
  std::vector<int> nbr_offsets, nbrs;
  std::vector<int> face_offsets, vfaces;
  explicit Topology(const Mesh& mesh);
  [[nodiscard]] int degree(int v) const { return nbr_offsets[v + 1] - nbr_offsets[v]; }
};

/// Target spherical area of each face: 4π · a_f · factor_f / Σ (a · factor), with a floor for
/// zero-area faces. `vertex_factors` (may be empty) scale regions (the area-controllable map).
std::vector<double> face_targets(const Mesh& mesh, const std::vector<double>& vertex_factors);
/// Target vertex masses: 1/3 of the incident face targets (sum 4π).
std::vector<double> vertex_targets(const Mesh& mesh, const std::vector<double>& face_target);

/// Elimination orders for the Tutte systems on CHOLMOD's path (the plane order, unless the graph
/// order needs 20 % fewer flops). `index` numbers the unknown vertices (−1: a fixed vertex) from 0 to `unknowns` − 1;
/// each result lists the unknowns in pivot order. Nested dissection by planes through the
/// vertices' `points`, at the median of the widest coordinate:
std::vector<int> plane_nested_dissection(const Topology& topo, const std::vector<Vec3>& points,
                                         const std::vector<int>& index, int unknowns);
/// and by breadth-first layers of the mesh graph, which cut thin parts across.
std::vector<int> graph_nested_dissection(const Topology& topo, const std::vector<int>& index, int unknowns);

/// Planar Tutte embedding (positive clamped-cotangent weights) with the largest face as the
/// outer triangle, mapped to the unit sphere by inverse stereographic projection, oriented
/// outward. The mesh must be outward oriented. With `targets` (face target areas), the weights
/// are then multiplied by the stretch (image area / target, clamped to e^±4; on the crushed
/// side to e^-10 while the 0.5 % quantile is between e^-20 and e^-6, for a map that starts
/// above e^-20) of the previous map, up to `max_reweightings` times, when more than 0.5% of the
/// faces are crushed below e^-4 relative to the median stretch and then until that 0.5 % quantile
/// is above e^-6 (the OT takes the rest): this opens up the exponentially
/// crushed protrusions of harmonic maps (fingers, ears, arm.off's hand). The stretch is measured
/// on the planar embedding (times the stereographic area factor): crushed faces there are 1e-12
/// across, far below what points on the unit sphere resolve. With `crushed`, the reweighting stops early when
/// four reweightings gain less than 0.25 on that quantile; `crushed` then says that the map is
/// still crushed (with --coarse-to-fine the pipeline then uses hierarchical_sphere_map). It
/// also stops so, with or without `crushed`, when the map is below rounding: that quantile's
/// faces under 1e-28 in area on the unit sphere (their vertices coincide there), or more than 1 %
/// of the faces flipped on the sphere (the planar map has none: their vertices were rounded
/// together); `crushed_below_rounding` then says so (the pipeline then always uses
/// hierarchical_sphere_map). `uniform_weights`: all edge weights 1 instead of the clamped
/// cotangents.
std::vector<Vec3> tutte_sphere_map(const Mesh& mesh, const Topology& topo, const std::vector<double>& targets = {},
                                   int max_reweightings = 0, int* reweightings = nullptr, bool* crushed = nullptr,
                                   bool uniform_weights = false, bool* crushed_below_rounding = nullptr);

struct HierarchyInfo {
  int levels = 0;                 ///< collapse levels
  std::size_t base_vertices = 0;  ///< vertices of the coarsest mesh
  std::size_t base_flips = 0;     ///< inverted faces of its Tutte map (rounding)
  std::size_t unplaced = 0;       ///< vertices that found no flip-free place when put back
};
/// Coarse-to-fine initial map for meshes whose Tutte map is crushed below rounding (long thin
/// tubes: a harmonic map crushes a tube of length L and radius r by about e^(-L/r), e^-100 at
/// L = 100 r, and positive weights on a triangulated tube cannot make it less than about
/// e^(-0.58 L/r)). Levels of edge collapses (edges whose vertex normals agree first, no two
/// removed vertices neighbours) reduce the mesh to `base_vertices` or until the collapses
/// stall; each collapse adds the removed vertex's area share to the vertex it goes into. A
/// 4-vertex base is mapped to the regular tetrahedron, a larger one by Tutte with uniform
/// weights; then every level puts its removed vertices back inside the wedge of their collapsed
/// edge, at a place that inverts none of their faces (`HierarchyInfo::unplaced` counts the
/// others), and runs 24 sweeps of the flip-free area optimization towards the level's area shares.
std::vector<Vec3> hierarchical_sphere_map(const Mesh& mesh, std::size_t base_vertices = 4,
                                          HierarchyInfo* info = nullptr);

/// Möbius balancing: applies ball automorphisms until the weighted mean of the points is at the
/// origin (|mean| ≤ tol). Returns the number of iterations.
int mobius_balance(std::vector<Vec3>& points, const std::vector<double>& weights, double tol = 1e-9,
                   int max_iterations = 200);

/// Number of faces with det[S0,S1,S2] <= 0 (the mesh is outward oriented).
std::size_t count_flips(const Mesh& mesh, const std::vector<Vec3>& s);

/// Laplacian untangling of flipped faces: moves the vertices of flipped faces (and rings around
/// them, growing when stuck) to the normalised mean of their neighbours. Returns remaining flips.
/// With `allow_free` false, moves never increase the number of flipped faces around a vertex.
std::size_t untangle(const Mesh& mesh, const Topology& topo, std::vector<Vec3>& s, int max_rounds = 400,
                     bool allow_free = true);

/// One flag per vertex: within `rings` edges of a vertex of a flipped face (det <= 0).
std::vector<char> near_flipped_faces(const Mesh& mesh, const Topology& topo, const std::vector<Vec3>& s, int rings);

/// Repairs flipped faces by re-embedding a disk around each: the vertices within k rings of a
/// flipped face are placed by a Floater (mean-value, positive-weight) embedding in a gnomonic
/// chart, with the next ring fixed; k grows (1, 2, 3, 4, 6, …, up to `max_rings`) until no face of
/// the patch is flipped; where that embedding folds (a fixed ring far from convex), the patch is
/// untangled from its current positions instead (untangle_chart_patch). Patches that cannot be
/// repaired are left as they were. Returns the number of flipped faces left.
/// `patches` (optional) counts the flipped faces whose patch was re-embedded, and
/// `chart_untangles` the patches that needed untangle_chart_patch.
inline constexpr std::size_t chart_untangling_work_per_face = 200;
struct PatchRepairOptions {
  int max_rings = 64;
  /// Beyond this many rings only Floater's embedding is tried. On the 16 shared meshes, 18 hard
  /// ones and 5 cones sizes the chart untangling repaired 38 folds, 37 of them at up to 4 rings and
  /// 1 at 9, never more; Floater's embedding of the wider disk repaired 8 of its 23 at 19 to 63
  /// rings. Each failed untangling of 13 to 42 rings spent up to 2·10⁷ face evaluations; on
  /// folds_150k, whose one fold Floater's embedding repairs at 63 rings, they took the untangling
  /// stage from 1.03–1.30 s to 2.15–2.43 s.
  int chart_untangling_max_rings = 9;
  /// The chart untanglings of all patches together evaluate at most this many faces per mesh
  /// face (a patch whose fixed ring leaves no room spends its whole share before it fails).
  std::size_t untangling_work_per_face = chart_untangling_work_per_face;
  /// For a trial that is kept only if it repairs every fold: return as soon as one flipped face
  /// has no repairing patch, instead of going on with the others.
  bool stop_at_first_failure = false;
};
std::size_t repair_flips_by_patches(const Mesh& mesh, const Topology& topo, std::vector<Vec3>& s,
                                    const PatchRepairOptions& options = {}, int* patches = nullptr,
                                    int* chart_untangles = nullptr);

/// A planar patch to untangle (the fallback of repair_flips_by_patches when Floater's embedding
/// folds, i.e. when the fixed ring is far from convex): vertices 0 … free_count-1 move, the others
/// are fixed; each face (counter-clockwise when untangled) has the inverse of its reference edge
/// matrix [r1-r0, r2-r0] and its reference area.
struct ChartPatch {
  std::vector<std::array<int, 3>> faces;
  std::vector<Eigen::Matrix2d> reference_inverse;
  std::vector<double> reference_area;
  Eigen::Index free_count = 0;
};
/// Foldover-free untangling energy (Garanzha, Kaporin, Kudryavtseva, Protais, Ray, Sokolov,
/// "Foldover-free maps in 50 lines of code", 2021): per face, with J the Jacobian from the
/// reference triangle and D = det J, area · ((|J|² + D² + 1) / (2 χ(D))), where
/// χ(D) = (D + sqrt(ε² + D²)) / 2 > 0 even for inverted faces. Returns the energy; fills the
/// gradient over the free vertices (x then y of each) and the smallest D.
double untangling_energy(const ChartPatch& patch, const Eigen::MatrixX2d& x, double eps, Eigen::VectorXd& gradient,
                         double& min_det);
/// Minimises the untangling energy from `x` for a decreasing ε (L-BFGS with backtracking at each
/// ε, the paper's ε rule) until every face is positively oriented: true then, with `x` updated.
/// False when that fails in 8 ε steps or about 2·10⁷ face evaluations (e.g. the fixed ring's
/// kernel is empty).
/// `face_budget` (optional): face evaluations left to spend; lowered by those spent.
bool untangle_chart_patch(const ChartPatch& patch, Eigen::MatrixX2d& x, std::size_t* face_budget = nullptr);

/// λ of the MIPS term by default (`--angle-weight`): it keeps the triangles well shaped for a
/// small cost in area.
inline constexpr double default_angle_weight = 0.005;

/// The noise level of the area energy for over-relaxation (OptimizeOptions::over_relaxation):
/// a mean log²(A/T) per face of 5e-5, an RMS log-area error of 0.7 %. slivers_60k's map starts
/// the final optimization at 1.4e-5, where ω = 1.6 kept 3 times as many vertices active (twice
/// the visits, 0.24 s → 0.62 s) for a slightly higher area error; the other meshes start at
/// 1.2e-4 (igea_134k) and above.
inline constexpr double plain_steps_below_face_energy = 5e-5;

struct OptimizeOptions {
  /// Sweeps at most; < 0: by the angle weight (sweep_limit).
  int max_sweeps = -1;
  /// Vertex visits at most, per vertex (the work of that many full sweeps); < 0: by the other
  /// limits (visit_limit).
  double max_visits_per_vertex = -1;
  /// λ ≥ 0, the weight of the MIPS (angle) term against the log² area term, per face: 0 is
  /// purely area-preserving; from about 10 the area term hardly counts (conformal-leaning).
  double angle_weight = default_angle_weight;
  double time_budget_s = 1e9;
  /// > 0: untangling mode, areas regularised as (A + sqrt(A² + 4ε²T²))/2 (no barrier, no MIPS).
  double regularization = 0;
  /// A vertex stays active while its move lowers its local energy by more than this fraction of
  /// the smaller of that energy and the mean local energy at the start: vertices that carry
  /// much of the error keep moving after the others have stopped. 1e-2 against 1e-3 (relative to
  /// the vertex's own energy) halved the optimization's time on bunny_35k and igea_134k for area
  /// mean|d| 0.0157 and 0.0044 instead of 0.0148 and 0.0033.
  double activity_threshold = 1e-2;
  /// The vertices active in the first sweep (one flag per vertex); empty: all of them.
  std::vector<char> start_active;
  /// ω in (0, 2): each vertex first tries ω times its Gauss–Newton step (successive
  /// over-relaxation), then the damped steps. ω > 1 moves smooth, far-reaching area errors
  /// faster, which plain Gauss–Seidel corrects slowly. It overshoots from a map far from
  /// converged (the OT map), and near a converged one: below a mean energy per face of
  /// plain_steps_below_face_energy at the start, the run takes plain steps whatever ω says.
  /// 1.6 for the final optimization: on the 16 shared meshes and the hard ones at 25k, 60k and
  /// 120k vertices, area mean|d| as low or lower than with 1 on every mesh (igea_134k 0.0044 →
  /// 0.0034, armadillo_43k 0.0226 → 0.0210), the mean angle error within ±0.35° except
  /// folds_25k (19.3° → 20.9°), and fewer sweeps on most (brain_48k 100 → 48).
  double over_relaxation = 1.6;
  /// With λ > 0 and the automatic limits (max_sweeps and max_visits_per_vertex < 0, λ up to
  /// default_angle_weight): this many of the visit limit's visits per vertex go to a first run
  /// at λ = 0 (at most half the sweep limit), and the rest to the run with the MIPS term. The
  /// area term alone moves the map nearer its area optimum, and the MIPS term's run keeps most
  /// of it (8 against none: brain_48k 0.0056 → 0.0049, cones_150k 0.0857 → 0.0841). 16 rather
  /// than 8 takes over the area work that the untangling's ε levels after the first no longer do
  /// (pipeline.cpp, step 4): see docs/spherical_parameterization.md for both measured together.
  /// 0: off.
  double area_first_visits = 16;
};
/// The sweep limit of `options`: max_sweeps when ≥ 0; otherwise 200 up to the default angle
/// weight, and 2000 above it. A large λ moves the map from area-preserving towards conformal,
/// which is a global change that vertex moves make slowly: on arm.off, λ = 5 still lowered the
/// mean angle error from 26.4° at 200 sweeps to 21.0° at 1000 (it stops by itself at 1870).
int sweep_limit(const OptimizeOptions& options);
/// The visit limit of `options`, per vertex: max_visits_per_vertex when ≥ 0; otherwise, with the
/// automatic sweep limit and up to the default angle weight, 20 (the work of 20 full sweeps),
/// and none (infinity) else. The runs stop after the sweep that reaches it. A map that starts
/// nearer the areas' optimum keeps more vertices above the activity threshold, which is relative
/// to its (lower) mean energy: spiky_120k's map from coarse-transported sites took 35 visits per
/// vertex (0.62 s → 1.45 s) for area mean|d| 0.0479, and 0.0496 at 20. Without that start every
/// shared and hard mesh takes 19 or fewer.
double visit_limit(const OptimizeOptions& options);

/// The visits per vertex of the area-first run of `options` (OptimizeOptions::area_first_visits):
/// 0 when there is none (λ = 0, explicit limits, a conformal-leaning λ or the untangling mode).
double area_first_visit_limit(const OptimizeOptions& options);

struct OptimizeResult {
  int sweeps = 0;
  std::size_t visits = 0;  ///< vertex updates tried
  double energy_start = 0, energy_end = 0;
  /// The ω the moves used: OptimizeOptions::over_relaxation, or 1 from a map at the noise level
  /// (plain_steps_below_face_energy); 0 when no run took place.
  double over_relaxation = 0;
};
/// Flip-free area-correcting optimization on the sphere: Gauss–Seidel over vertices, one colour
/// class of the vertex graph at a time in parallel (with an
/// active set) of E = Σ_f log²(A_f/T_f) + λ Σ_f MIPS_f, each move a damped Gauss–Newton step in
/// the tangent plane that is only accepted if no incident face degenerates or inverts and E
/// decreases. Requires a flip-free start (faces with det <= 0 are never created, never repaired).
/// With `regularization` ε > 0 it is the untangling variant: areas regularised, inversions allowed.
OptimizeResult optimize_area(const Mesh& mesh, const Topology& topo, const std::vector<double>& targets,
                             std::vector<Vec3>& s, const OptimizeOptions& options = {});

/// optimize_area for repeated calls on one mesh with one set of targets: its per-vertex tables
/// (each vertex's faces with their targets and cotangents, and the vertex colouring) are built
/// once instead of at every call (spiky_120k: 22 ms a call, 7 calls). `mesh` and `targets` must
/// outlive it (`topo` is read by the constructor only). The results are those of optimize_area,
/// bit for bit.
class AreaOptimizer {
 public:
  AreaOptimizer(const Mesh& mesh, const Topology& topo, const std::vector<double>& targets);
  ~AreaOptimizer();
  AreaOptimizer(const AreaOptimizer&) = delete;
  AreaOptimizer& operator=(const AreaOptimizer&) = delete;
  OptimizeResult run(std::vector<Vec3>& s, const OptimizeOptions& options = {}) const;
  /// The local energy each move lowers: the terms of the faces around `vertex`, with that vertex
  /// at `x` and the others at `s`, and (when `gradient` is given) its gradient with respect to
  /// x ∈ R³, as the moves use it. NaN when one of the faces inverts or degenerates without
  /// `options.regularization`. For checking the derivatives.
  double vertex_energy(const std::vector<Vec3>& s, int vertex, const Vec3& x, const OptimizeOptions& options,
                       Vec3* gradient = nullptr) const;

 private:
  struct Tables;
  /// One run of the sweeps under `options`' limits (run adds the area-first run before it).
  OptimizeResult run_once(std::vector<Vec3>& s, const OptimizeOptions& options) const;
  const Mesh& mesh_;
  const std::vector<double>& targets_;
  std::unique_ptr<Tables> tables_;
};

/// What is left of the folds after the regularised sweeps and the patches: up to `max_rounds`
/// rounds, while faces are flipped, of monotone Laplacian moves (untangle without free moves)
/// and then the regularised area energy (ε = 1e-2 down to 1e-5, 100 sweeps each at most) from
/// the vertices within 4 rings of the folds. Returns the flipped faces left; `rounds`
/// (optional) counts the rounds run.
std::size_t untangle_by_laplacian_rounds(const Mesh& mesh, const Topology& topo, const AreaOptimizer& optimizer,
                                         std::vector<Vec3>& s, int max_rounds, int* rounds = nullptr);

/// 1-to-4 subdivision (edge midpoints): the refined mesh keeps the original vertices first.
Mesh subdivide(const Mesh& mesh);

/// Diracs of the OT stage: the mesh vertices first (at `s`, in order), then lattice points of
/// the faces refined by `levels` (face f split into 4^levels[f] sub-triangles; points on an edge
/// shared when both faces have them). Each sub-triangle gives a third of its share of the face's
/// target to each corner, so the masses sum to the targets' sum.
struct DiracSet {
  std::vector<Vec3> sites;
  std::vector<double> masses;
};
DiracSet lattice_diracs(const Mesh& mesh, const std::vector<Vec3>& s, const std::vector<double>& targets,
                        const std::vector<int>& levels);

/// Refinement levels (0 to `max_level`) that grade the Dirac masses: each face is split until its
/// sub-triangles' targets are at most `ratio` times the lightest vertex Dirac (a third of the
/// sub-triangles around the vertex) within one ring of its corners, or it is at `max_level`.
/// All 0 when no face is more than `ratio` times the lightest vertex Dirac near it.
std::vector<int> graded_levels(const Mesh& mesh, const std::vector<double>& targets, double ratio, int max_level);

/// The largest ratio of a face's target to the lightest vertex Dirac within one ring of its
/// corners (unsplit faces): how far the Dirac masses jump across the mesh.
double largest_dirac_jump(const Mesh& mesh, const std::vector<double>& targets);

}  // namespace sphparam
