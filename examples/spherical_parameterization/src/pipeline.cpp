// The parameterization pipeline. The OT stage uses the library's sphere geometry and solver.
#include "pipeline.hpp"
#include "point_grid.hpp"
#include "sub_resolution.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <unordered_map>

#ifdef SPHPARAM_HAVE_SPHERE
#include <sdot/geometries/sphere.hpp>
#include <sdot/solver.hpp>
#endif

namespace sphparam {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

std::string fmt_g(double x) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", x);
  return b;
}

#ifdef SPHPARAM_HAVE_SPHERE
struct OtOutcome {
  bool usable = false;
  std::vector<Vec3> centroids;
  std::vector<double> cell_masses;
};

/// One OT solve with sdot::Sphere, from zero weights (the Voronoi diagram of the sites) straight
/// to the targets; fills `rec` (status, iterations, errors). A continuation (stages geometric in
/// log(ν/μ0) from the Voronoi areas μ0, each warm-starting the next) took more Newton iterations
/// than the damped Newton method alone on every mesh where it ran, with max |log(ν/μ0)| from
/// e^6.3 to e^10.7 (lion_50k 11 → 7, maxplanck_12k 12 → 8, arm.off 13 → 8, cow_igl 11 → 7;
/// bunny_35k with --target-weights from e^-6 to e^6, 12 → 6).
OtOutcome solve_ot(const std::vector<Vec3>& sites, const std::vector<double>& masses, double tolerance,
                   int max_iterations, const std::function<void(const std::string&)>& say, OtRecord* rec) {
  OtOutcome out;
  Eigen::VectorXd nu(static_cast<Eigen::Index>(masses.size()));
  for (std::size_t i = 0; i < masses.size(); ++i) nu[static_cast<Eigen::Index>(i)] = masses[i];
  sdot::Options opt;
  opt.tolerance = tolerance;
  opt.max_iterations = max_iterations;
  opt.compute_transport_cost = false;  // only the centroids are used
  if (rec) rec->error_history.clear(), rec->iterations = 0;
  opt.callback = [&](const sdot::IterationRecord& r) {
    if (rec) rec->error_history.push_back(r.max_relative_error);
    say("  Newton " + std::to_string(r.iteration) + ": max rel. mass error " + fmt_g(r.max_relative_error) + ", step " +
        fmt_g(r.step) + ", " + fmt_g(r.elapsed_s) + " s");
  };
  try {
    sdot::Sphere sphere;
    // The hull builder (the default; updated by flips between Newton iterates) is about 10x
    // faster here than the clipping builder, whose kd-tree certification suffers from cells far
    // from their sites; both give the same cells. Named, so that a change of default shows here.
    sphere.set_builder(sdot::Sphere::Builder::hull);
    const std::span<const Vec3> span(sites);
    auto result = sdot::solve(sphere, sdot::UniformDensity{}, span, nu, opt);
    const auto& sum = result.summary;
    say("  final solve: " + std::to_string(sum.iterations) + " Newton it, " + fmt_g(sum.timings.total_s) +
        " s (diagrams " + fmt_g(sum.timings.diagram_s) + " s, integration " + fmt_g(sum.timings.assembly_s) +
        " s, linear solves " + fmt_g(sum.timings.linear_solve_s) + " s)");
    std::string status;
    switch (sum.status) {
      case sdot::Status::converged:
        status = "converged";
        break;
      case sdot::Status::line_search_failure:
        // A stall at a small error is the precision floor of clustered sites: a result, not a failure.
        status = sum.max_relative_error < 1e-3 ? "precision_floor" : "line_search_failure";
        break;
      case sdot::Status::precision_floor:
        status = "precision_floor";
        break;  // the solver's own floor detection
      case sdot::Status::iteration_limit:
        status = "iteration_limit";
        break;
      case sdot::Status::linear_solve_failure:
        status = "linear_solve_failure";
        break;
    }
    out.usable = sum.iterations > 0 || sum.status == sdot::Status::converged;
    if (!out.usable) status = "failed";
    if (rec) {
      rec->status = status;
      rec->message = sum.message;
      rec->iterations = sum.iterations;
      rec->max_relative_error = sum.max_relative_error;
      rec->rms_relative_error = sum.rms_relative_error;
      rec->height_range = result.weights.size() ? result.weights.maxCoeff() - result.weights.minCoeff() : 0;
    }
    out.centroids.resize(sites.size());
    out.cell_masses.resize(sites.size());
    for (std::size_t i = 0; i < sites.size(); ++i) {
      out.centroids[i] = result.centroids[i].normalized();
      out.cell_masses[i] = result.masses[static_cast<Eigen::Index>(i)];
    }
  } catch (const std::exception& e) {
    if (rec) rec->status = "failed", rec->message = e.what();
  }
  return out;
}

/// δ-separated representatives of the points `s` and the clusters around them.
struct Clusters {
  std::vector<Vec3> sites;     ///< the representatives' positions
  std::vector<int> owner;      ///< per point: its nearest representative (an index into sites)
  std::vector<double> masses;  ///< per representative: its cluster's summed mass
};

/// Greedy representatives (hash grid): a point, taken in `order`, becomes one when none is within
/// δ of it; then each point joins its nearest one.
Clusters cluster_around_representatives(const std::vector<Vec3>& s, const std::vector<double>& masses, double delta,
                                        const std::vector<int>& order) {
  Clusters c;
  PointGrid grid(delta);
  const auto nearest = [&](const Vec3& p) {
    int best = -1;
    double best_distance = delta * delta;
    grid.for_each_near(p, [&](int r) {
      const double d = (c.sites[u(r)] - p).squaredNorm();
      if (d < best_distance) best_distance = d, best = r;
    });
    return best;
  };
  for (int v : order)
    if (nearest(s[u(v)]) < 0) grid.insert(s[u(v)], static_cast<int>(c.sites.size())), c.sites.push_back(s[u(v)]);
  // Each point's representative in parallel; the masses summed in point order (the same bits on
  // any thread count).
  c.owner.resize(s.size());
  const auto count = static_cast<std::ptrdiff_t>(s.size());
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t v = 0; v < count; ++v)
    c.owner[u(v)] = std::max(nearest(s[u(v)]), 0);  // always ≥ 0: every point has a representative within δ
  c.masses.assign(c.sites.size(), 0.0);
  for (std::size_t v = 0; v < s.size(); ++v) c.masses[u(c.owner[v])] += masses[v];
  return c;
}

/// Greedy δ-separated representatives, each vertex joins its nearest one; one OT
/// solve on the representatives with the cluster masses; each cluster is then moved rigidly
/// (rotation taking its representative to the cell centroid) and scaled by the square root of
/// the ratio of its cell area to its Voronoi area. Spreads exponentially crushed regions.
std::string separate_clusters(std::vector<Vec3>& s, const std::vector<double>& masses, double delta, OtRecord& rec) {
  const std::size_t n = s.size();
  // heaviest first: big vertices are good representatives
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return masses[u(a)] > masses[u(b)]; });
  const Clusters clusters = cluster_around_representatives(s, masses, delta, order);
  const std::vector<Vec3>& sites = clusters.sites;
  const std::vector<int>& owner = clusters.owner;
  const std::vector<double>& cmass = clusters.masses;
  OtRecord local;
  OtOutcome o = solve_ot(
      sites, cmass, 1e-6, 40, [](const std::string&) {}, &local);
  if (!o.usable) {
    rec.message = "separation pass failed: " + local.message;
    return "failed: " + local.message;
  }
  // Voronoi areas of the representatives (h = 0)
  sdot::Sphere sphere;
  sphere.set_builder(sdot::Sphere::Builder::hull);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(sites.size()));
  auto ev = sdot::evaluate(sphere, sdot::UniformDensity{}, std::span<const Vec3>(sites), zero, false);
  std::vector<Eigen::Matrix3d> rot(sites.size());
  std::vector<double> scale(sites.size());
  for (std::size_t r = 0; r < sites.size(); ++r) {
    rot[r] = Eigen::Quaterniond::FromTwoVectors(sites[r], o.centroids[r]).toRotationMatrix();
    const double vor = ev.masses[static_cast<Eigen::Index>(r)];
    scale[r] = vor > 0 ? std::sqrt(std::max(o.cell_masses[r], 1e-300) / vor) : 1.0;
  }
  for (std::size_t v = 0; v < n; ++v) {
    const auto r = u(owner[v]);
    const Vec3 offset = s[v] - sites[r];
    s[v] = (o.centroids[r] + scale[r] * (rot[r] * offset)).normalized();
  }
  return std::to_string(sites.size()) + " clusters, OT " + local.status + " in " + std::to_string(local.iterations) +
         " it";
}

/// Moves every site most of the way its OT will take it, at a coarse scale: δ-separated
/// representatives (each vertex's mass goes to its nearest one) go to their OT cells' centroids,
/// and each site follows the displacement field that a moving least-squares fit (linear in the
/// site's tangent plane, weights (1 − r²/R²)³ within R = 2.5 δ) interpolates from theirs.
/// The fine OT then starts nearer its solution: fewer of its damped Newton steps (spiky_120k 7 → 5).
/// Leaves `s` as it is when the coarse OT fails, and says so.
std::string coarse_transport(std::vector<Vec3>& s, const std::vector<double>& masses, double delta) {
  const std::size_t n = s.size();
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  const Clusters clusters = cluster_around_representatives(s, masses, delta, order);
  const std::vector<Vec3>& sites = clusters.sites;
  // A loose tolerance: the fine OT corrects what the coarse one leaves.
  OtRecord coarse;
  const OtOutcome o = solve_ot(
      sites, clusters.masses, 1e-2, 40, [](const std::string&) {}, &coarse);
  const std::string what = std::to_string(sites.size()) + " representatives, OT " + coarse.status + " in " +
                           std::to_string(coarse.iterations) + " it";
  if (!o.usable) return what + ": sites left where they were (" + coarse.message + ")";
  const double radius = 2.5 * delta;
  PointGrid reach(radius);
  for (std::size_t r = 0; r < sites.size(); ++r) reach.insert(sites[r], static_cast<int>(r));
  std::vector<Vec3> moved(n);
#pragma omp parallel for schedule(dynamic, 1024)
  for (std::ptrdiff_t vv = 0; vv < static_cast<std::ptrdiff_t>(n); ++vv) {
    const auto v = u(vv);
    const Vec3 e1 = s[v].unitOrthogonal(), e2 = s[v].cross(e1);
    // normal equations of the fit: basis (1, tangent coordinates / R); columns of b: x, y, z
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero(), b = Eigen::Matrix3d::Zero();
    Vec3 weighted_sum = Vec3::Zero();
    double total_weight = 0;
    reach.for_each_near(s[v], [&](int r) {
      const Vec3 d = sites[u(r)] - s[v];
      const double q = d.squaredNorm() / (radius * radius);
      if (q >= 1) return;
      const double weight = (1 - q) * (1 - q) * (1 - q);
      const Vec3 displacement = o.centroids[u(r)] - sites[u(r)];
      weighted_sum += weight * displacement, total_weight += weight;
      const Eigen::Vector3d basis(1, d.dot(e1) / radius, d.dot(e2) / radius);
      normal += weight * basis * basis.transpose();
      b += weight * basis * displacement.transpose();
    });
    Vec3 displacement = Vec3::Zero();
    if (total_weight > 0) {
      // the linear fit where the representatives around surround the site, their weighted mean elsewhere
      displacement = weighted_sum / total_weight;
      const Eigen::LDLT<Eigen::Matrix3d> fit(normal);
      const Eigen::Vector3d pivots = fit.vectorD();
      if (fit.isPositive() && pivots.minCoeff() > 1e-3 * pivots.maxCoeff())
        displacement = fit.solve(b).row(0).transpose();
    }
    moved[v] = (s[v] + displacement).normalized();
  }
  s = std::move(moved);
  return what;
}
#endif

double min_edge_length(const Mesh& mesh, const std::vector<Vec3>& s) {
  double m = 1e300;
  for (const auto& f : mesh.faces)
    for (int k = 0; k < 3; ++k) m = std::min(m, (s[u(f[u(k)])] - s[u(f[u((k + 1) % 3)])]).norm());
  return m;
}

}  // namespace

double target_area_error(const Mesh& mesh, const std::vector<Vec3>& s, const std::vector<double>& targets) {
  double sum = 0;
  std::size_t n = 0;
  for (std::size_t f = 0; f < mesh.faces.size(); ++f) {
    const auto& t = mesh.faces[f];
    const double a = spherical_triangle_area(s[u(t[0])], s[u(t[1])], s[u(t[2])]);
    const double d = std::log(a / targets[f]);
    if (std::isfinite(d)) sum += std::abs(d), ++n;
  }
  return n ? sum / static_cast<double>(n) : std::nan("");
}

static void say_progress(const PipelineOptions& options, const std::string& line) {
  if (options.progress) options.progress(line);
}

/// Appends the record of a stage (area error of `s` against `targets`, flips) and prints its line.
static void record_stage(PipelineResult& R, const Mesh& mesh, const std::vector<double>& targets,
                         const std::vector<Vec3>& s, const PipelineOptions& options, const std::string& name,
                         double seconds, std::string note) {
  StageRecord r{name, seconds, target_area_error(mesh, s, targets), count_flips(mesh, s), std::move(note)};
  say_progress(options, name + ": " + fmt_g(seconds) + " s, area mean|d| " + fmt_g(r.area_mean_abs) + ", flips " +
                            std::to_string(r.flips) + (r.note.empty() ? "" : " (" + r.note + ")"));
  R.stages.push_back(std::move(r));
}

/// The pipeline on a mesh without sub-resolution vertices (or with them kept).
static PipelineResult map_mesh(const Mesh& mesh, const PipelineOptions& options) {
  PipelineResult R;
  auto say = [&](const std::string& s) { say_progress(options, s); };
  const Topology topo(mesh);
  const auto targets = face_targets(mesh, options.vertex_factors);
  // built at its first use, then shared by the untangling's calls and the final optimization
  std::optional<AreaOptimizer> area_optimizer;
  auto optimizer = [&]() -> const AreaOptimizer& {
    if (!area_optimizer) area_optimizer.emplace(mesh, topo, targets);
    return *area_optimizer;
  };
  const auto masses = vertex_targets(mesh, targets);
  auto record = [&](const std::string& name, double seconds, const std::vector<Vec3>& s, std::string note = "") {
    record_stage(R, mesh, targets, s, options, name, seconds, std::move(note));
  };

  // 1. Initial map: Tutte embedding, inverse stereographic projection, Möbius balancing.
  auto t = Clock::now();
  int reweightings = 0;
  bool crushed = false, below_rounding = false;
  std::vector<Vec3> s = tutte_sphere_map(mesh, topo, targets, options.max_reweightings, &reweightings,
                                         options.hierarchical_initial_map ? &crushed : nullptr, false, &below_rounding);
  std::string how = "Tutte + " + std::to_string(reweightings) + " stretch reweightings + stereographic";
  if ((crushed && options.hierarchical_initial_map) || below_rounding) {
    // tubes that the reweighting cannot open: their sites would coincide on the sphere
    s = hierarchical_sphere_map(mesh, 4, &R.hierarchy);
    ++R.fallbacks.hierarchical_initial_map;
    how += ", still crushed: coarse-to-fine map instead (" + std::to_string(R.hierarchy.levels) + " levels, " +
           std::to_string(R.hierarchy.base_vertices) + " base vertices with " + std::to_string(R.hierarchy.base_flips) +
           " inverted faces, " + std::to_string(R.hierarchy.unplaced) + " vertices unplaced)";
  }
  // The coarse-to-fine map is area-corrected at every level; a Möbius map would magnify its
  // smallest faces below rounding.
  const int mobius_iterations = R.fallbacks.hierarchical_initial_map ? 0 : mobius_balance(s, masses);
  R.initial = s;
  record("initial_map", since(t), s, how + " + Moebius (" + std::to_string(mobius_iterations) + " it)");

  // 2. OT with sdot::Sphere: sites = current positions (+ refined Diracs), masses = vertex areas.
  t = Clock::now();
  int refine = options.refine;
  if (refine < 0) refine = mesh.vertices.size() <= 15000 ? 1 : 0;
  R.ot.refine = refine;
  // A flip-free coarse-to-fine map goes straight to the flip-free optimization (step 5): it is
  // area-corrected at every level already, and it is far from conformal (thin strips for the
  // tubes), where the OT cells are not: their centroids folded 17,376 of tubes_25k's 49,520
  // faces, and 166 were left after the untangling, the rerun with finer Diracs and the Laplacian
  // rounds (33 s).
  if (R.fallbacks.hierarchical_initial_map > 0 && R.stages.back().flips == 0) {  // the initial map's record
    R.ot.status = "skipped";
    R.ot.message = "the coarse-to-fine initial map is flip-free and area-corrected";
    record("ot_centroids", since(t), s, "OT skipped: coarse-to-fine start");
  } else {
#ifdef SPHPARAM_HAVE_SPHERE
    {
      // 2a. Separate crushed sites: coarse OT passes on well-separated representatives.
      const double h0 = std::sqrt(4 * M_PI / static_cast<double>(s.size()));
      for (int pass = 0; pass < 8; ++pass) {
        const double spacing = min_edge_length(mesh, s);
        if (spacing >= options.min_spacing * h0) break;
        const auto tp = Clock::now();
        const std::string note = separate_clusters(s, masses, options.separation_delta * h0, R.ot);
        ++R.fallbacks.separation_passes;
        record("separation_pass_" + std::to_string(pass + 1), since(tp), s, note);
      }
      // 2b. Coarse transport: the fine OT starts from sites moved by a coarse one. It saves 2-3
      //     Newton steps of about 0.1 s per 60k sites; on smaller meshes the saving is smaller
      //     than what the changed start costs the untangling (spiky_25k 0.91 s -> 1.21 s, arm.off
      //     0.61 s -> 0.72 s in total).
      if (options.coarse_transport_spacing > 0 && s.size() >= options.coarse_transport_from_vertices &&
          s.size() <= options.coarse_transport_up_to_vertices) {
        const auto tc = Clock::now();
        const std::string note = coarse_transport(s, masses, options.coarse_transport_spacing * h0);
        record("coarse_transport", since(tc), s, note);
      }
    }
    // 2c–4. OT on the mesh vertices (and refined Diracs), centroids, untangling. Should flips
    //       survive the untangling, the stage reruns from the same start with one more Dirac
    //       refinement level: finer Diracs sample the mesh better and leave fewer, smaller folds.
    // The OT start; `s` is rebuilt from it at every level (at 2 M vertices each copy is 52 MB).
    const std::vector<Vec3> separated = std::move(s);
    const int max_refine = std::max(refine, options.max_refine);
    for (int level = refine;; ++level) {
      s.clear();
      R.ot = OtRecord{};
      R.ot.refine = level;
      t = Clock::now();
      {
        // Without refinement the Diracs are the vertices, with their masses: no copies.
        Mesh dirac_mesh;
        std::vector<Vec3> refined_sites;
        std::vector<double> factors = level > 0 ? options.vertex_factors : std::vector<double>{};
        for (int split = 0; split < level; ++split) {
          const Mesh& coarse_mesh = split == 0 ? mesh : dirac_mesh;
          Mesh fine = subdivide(coarse_mesh);
          if (split == 0) refined_sites = separated;
          refined_sites.resize(fine.vertices.size());
          if (!factors.empty()) factors.resize(fine.vertices.size());
          for (std::size_t fi = 0; fi < coarse_mesh.faces.size(); ++fi) {
            const auto& coarse = coarse_mesh.faces[fi];
            const auto& centre = fine.faces[4 * fi + 3];  // (ab, bc, ca)
            const int ends[3][2] = {{coarse[0], coarse[1]}, {coarse[1], coarse[2]}, {coarse[2], coarse[0]}};
            for (int k = 0; k < 3; ++k) {
              const auto m = u(centre[u(k)]);
              refined_sites[m] = (refined_sites[u(ends[k][0])] + refined_sites[u(ends[k][1])]).normalized();
              if (!factors.empty()) factors[m] = 0.5 * (factors[u(ends[k][0])] + factors[u(ends[k][1])]);
            }
          }
          dirac_mesh = std::move(fine);
        }
        std::vector<double> refined_masses;
        if (level > 0) refined_masses = vertex_targets(dirac_mesh, face_targets(dirac_mesh, factors));
        // Graded Diracs where the masses jump. On cones_25k a spike's faces are up to 240 times the
        // lightest vertex Dirac beside its base. Vertex Diracs there (up to 139 times their
        // neighbours) put the cell centroids far out and fold the faces around the bases: 17 stayed
        // flipped through the 9 ε levels of the untangling, then the OT and the untangling ran again
        // on 4 times the Diracs (9.5 s in all). Faces split to grade the masses by at most 8 times
        // per ring: 38,082 Diracs, no rerun, 2.7 s, final area mean|d| 0.1045 -> 0.1040. Not on
        // milder jumps: on armadillo_43k (26 times) a ratio of 8 split 116 faces and raised the final
        // area mean|d| 0.0196 -> 0.0207.
        DiracSet graded;
        if (level == 0 && options.graded_dirac_ratio > 0 &&
            largest_dirac_jump(mesh, targets) > options.graded_diracs_from) {
          const std::vector<int> levels = graded_levels(mesh, targets, options.graded_dirac_ratio, 3);
          const int deepest = *std::max_element(levels.begin(), levels.end());
          graded = lattice_diracs(mesh, separated, targets, levels);
          R.ot.graded_faces =
              static_cast<std::size_t>(std::count_if(levels.begin(), levels.end(), [](int l) { return l > 0; }));
          say("graded Diracs: " + std::to_string(R.ot.graded_faces) + " faces split, up to 4^" +
              std::to_string(deepest) + " sub-triangles");
        }
        const bool use_graded = !graded.sites.empty();
        const std::vector<Vec3>& sites = use_graded ? graded.sites : level > 0 ? refined_sites : separated;
        const std::vector<double>& dirac_masses = use_graded ? graded.masses : level > 0 ? refined_masses : masses;
        R.ot.sites = sites.size();
        say("OT: " + std::to_string(sites.size()) + " Diracs (refinement " + std::to_string(level) + ")");
        OtOutcome o = solve_ot(sites, dirac_masses, options.ot_tolerance, options.ot_max_iterations, say, &R.ot);
        if (o.usable) {
          o.centroids.resize(separated.size());  // the mesh vertices come first
          s = std::move(o.centroids);
        } else {
          s = separated;
        }
      }
      record("ot_centroids", since(t), s, "OT " + R.ot.status + ", " + std::to_string(R.ot.iterations) + " Newton it");
      // 4. Untangle. First area-aware: a regularised area energy log²(A_ε/T) with a decreasing ε
      //    (inverted faces have finite energy, vertices can pass through them); then monotone
      //    Laplacian moves around what is left, then free Laplacian smoothing on growing rings.
      t = Clock::now();
      if (count_flips(mesh, s) > 0) {
        // In chunks of 10 sweeps, up to 60 per ε: once no face is flipped, the flip-free area
        // optimization (step 5) takes over, which improves the areas at a lower cost per sweep
        // (bunny_35k: 1.05 s → 0.18 s here, final area mean|d| 0.0126 → 0.0150).
        OptimizeOptions uo;
        uo.angle_weight = 0;
        uo.max_sweeps = 10;
        uo.activity_threshold = 1e-4;
        std::size_t flips = count_flips(mesh, s), previous_flips = flips;
        // Few flipped faces in a large mesh: each chunk starts from the vertices within 4 rings of
        // them (a move still wakes its neighbours) instead of from every vertex, and the flip-free
        // optimization (step 5) does the global area work (brain_48k Loop-subdivided twice, 775,762
        // vertices, 14 flipped faces after OT: untangling 3.83 s -> 0.29 s, the whole map 28.3 s ->
        // 20.1 s, final area mean|d| 0.0034 -> 0.0043).
        const bool local_untangling =
            mesh.vertices.size() >= local_untangling_from && flips * 1000 <= mesh.faces.size();
        int stalled_levels = 0;
        std::size_t failed_trial_at = 0;  // flipped faces at the last failed patch trial
        int eps_level = 0;                // of this untangling (an OT rerun untangles again)
        for (double eps : {1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5}) {
          uo.regularization = eps;
          int sweeps = 0;
          for (int chunk = 0; chunk < 6 && flips > 0; ++chunk) {
            // Chunk 0 opens most folds (spiky_120k: 4,311 flipped faces → 38); what is left of the
            // area error is smooth and far-reaching, which over-relaxed sweeps correct about twice
            // as fast. After two such chunks the area gained per chunk is small and the last folds
            // are local: the rest start near them (spiky_120k: untangling 2.39 s → 1.19 s, final
            // area mean|d| 0.0522 → 0.0512; igea_134k, flip-free after chunk 0, as before).
            // ω = 1.9 rather than 1.6: the same sweeps, a lower final area error on every mesh
            // that gets here (spiky_60k 0.0533 → 0.0507, folds_120k 0.0255 → 0.0234, arm.off
            // 0.0149 → 0.0130). Over-relaxing chunk 0 overshoots the maps OT leaves nearly
            // converged (igea_134k: final area mean|d| 0.0044 → 0.0058 with ω = 1.6).
            // Only the first ε level sweeps globally. The levels after it open the last folds
            // as well from their neighbourhoods (cones_120k: 36 → 15 → 12-13 → 10-11 flipped faces
            // after ε = 0.03, 0.01 and 0.003 both ways); their global chunks did area work, at
            // 0.6 s a level, that the area-first run of step 5 does for less (with its 16 visits:
            // cones_120k's untangling 3.0 s → 1.8 s, final area mean|d| 0.0841 → 0.0830).
            uo.over_relaxation = chunk >= 1 ? 1.9 : 1.0;
            const bool local = local_untangling || chunk >= 3 || eps_level > 0;
            if (local)
              uo.start_active = near_flipped_faces(mesh, topo, s, 4);
            else
              uo.start_active.clear();
            const OptimizeResult chunk_result = optimizer().run(s, uo);
            sweeps += chunk_result.sweeps;
            (local ? R.untangling.local_sweeps : R.untangling.global_sweeps) += chunk_result.sweeps;
            R.untangling.visits += chunk_result.visits;
            flips = count_flips(mesh, s);
          }
          ++eps_level, ++R.untangling.levels;
          say("  untangling, eps " + fmt_g(eps) + ": " + std::to_string(sweeps) + " sweeps, " + std::to_string(flips) +
              " flipped faces left");
          // After a failed trial, the next one waits until the sweeps have removed a quarter of the
          // flipped faces: the same folds fail the same way (cones_60k: trials at 43, 21, 14, 14,
          // 11, 10, 9, 9 and 9 flipped faces, all failed; now at 43, 21, 14 and 10, each stopped
          // at its first unrepaired face, about 0.25 s against 0.26 s of sweeps a level). Waiting for
          // half of them cost cones_120k its successful trial at 22 after a failed one at 31.
          // Up to 3 flipped faces a trial costs little and runs after every level, and for a single
          // one it gets the whole chart work: arm.off's last fold failed its quarter-work trials
          // after ε = 0.1 and 0.03 and then stuck through 3 more levels (0.79-0.87 s against its
          // budget of 0.75 s; now 0.57-0.64 s).
          if (flips > 0 && flips <= 50 && (failed_trial_at == 0 || 4 * flips <= 3 * failed_trial_at || flips <= 3)) {
            // a few stuck folds: the patch re-embedding (below) is far cheaper than more ε levels
            // (armadillo_43k: 2 flips left after ε = 0.1, then 8 more levels of 60 sweeps, 13 s).
            // A trial, kept only if it repairs every fold: a quarter of the chart-untangling work
            // of the repair after the last level. arm.off has a fold whose rings leave no room:
            // failed chart untanglings spent the whole share on it before the next level's sweeps
            // opened it (untangling 0.27-0.28 s -> 0.22 s).
            std::vector<Vec3> trial = s;
            PatchRepairOptions trial_options;
            trial_options.untangling_work_per_face =
                flips <= 1 ? chart_untangling_work_per_face : chart_untangling_work_per_face / 4;
            trial_options.stop_at_first_failure = true;
            if (repair_flips_by_patches(mesh, topo, trial, trial_options, &R.fallbacks.flip_patches,
                                        &R.fallbacks.chart_untangles) == 0) {
              s = std::move(trial);
              flips = 0;
              say("  untangling: the last flipped faces re-embedded in patches");
            } else {
              failed_trial_at = flips;
            }
          }
          // the same few folds after three levels: smaller ε will not open them (arm.off: 2 flips
          // from ε = 0.01 to 1e-5, 1.3 s); the steps below take over
          stalled_levels = flips > 0 && flips <= 50 && flips >= previous_flips ? stalled_levels + 1 : 0;
          previous_flips = flips;
          if (stalled_levels >= 3) break;
          if (flips == 0) break;
        }
        record("untangle_regularized", since(t), s, "regularised area energy, eps 0.1 -> 1e-5");
        t = Clock::now();
      }
      R.untangle_remaining = count_flips(mesh, s);
      if (R.untangle_remaining > 0) {
        // re-embed a growing disk around each flipped face (positive weights), then repair its areas
        const std::size_t before = R.untangle_remaining;
        R.untangle_remaining =
            repair_flips_by_patches(mesh, topo, s, {}, &R.fallbacks.flip_patches, &R.fallbacks.chart_untangles);
        record("untangle_patches", since(t), s, std::to_string(before) + " flipped faces before");
        t = Clock::now();
      }
      // Not after graded Diracs: the finer level splits every face in 4 and drops the grading, so
      // the heavy Diracs beside the spikes' bases stay as heavy against their neighbours (cones_60k:
      // 5 flipped faces left after the graded OT; the rerun on 237,162 Diracs left 10, and the
      // Laplacian rounds then took 18 s, 57 s and area mean|d| 0.309 in all; the rounds right
      // after the graded OT, 1.4 s, 19.5 s and 0.092).
      if (R.untangle_remaining > 0 && level < max_refine && R.ot.graded_faces == 0) {
        // the Laplacian rounds below are slow and rarely finish the job: refine the Diracs first
        say(std::to_string(R.untangle_remaining) + " flipped faces left: OT again with refinement " +
            std::to_string(level + 1));
        ++R.fallbacks.ot_reruns;
        continue;
      }
      if (R.untangle_remaining > 0)
        R.untangle_remaining =
            untangle_by_laplacian_rounds(mesh, topo, optimizer(), s, 4, &R.fallbacks.laplacian_rounds);
      if (R.untangle_remaining > 0) {
        ++R.fallbacks.free_smoothing;
        std::vector<Vec3> trial = s;  // free smoothing may destroy more than it repairs: keep the best
        const std::size_t left = untangle(mesh, topo, trial, 400, true);
        if (left < R.untangle_remaining) s = std::move(trial), R.untangle_remaining = left;
        if (R.untangle_remaining == 0) {
          // the smoothing damaged the area: repair it with the regularised energy, keep it if flip-free
          std::vector<Vec3> repaired = s;
          OptimizeOptions uo;
          uo.angle_weight = 0;
          uo.max_sweeps = 100;
          uo.activity_threshold = 1e-5;
          uo.over_relaxation = 1;  // repairs what the smoothing damaged: local moves
          for (double eps : {1e-3, 1e-4, 1e-5}) {
            uo.regularization = eps;
            optimizer().run(repaired, uo);
          }
          if (count_flips(mesh, repaired) == 0) s = std::move(repaired);
        }
      }
      record("untangle_laplacian", since(t), s, "monotone, then free on growing rings");
      break;
    }
#else
    R.ot.status = "unavailable";
    R.ot.message = "built without the sphere geometry";
    record("ot_centroids", since(t), s, "OT " + R.ot.status);
#endif
  }

  // 5. Flip-free area-correcting optimization.
  if (options.optimize && R.untangle_remaining == 0) {
    t = Clock::now();
    R.optimizer = optimizer().run(s, options.optimizer);
    record("area_optimization", since(t), s, std::to_string(R.optimizer.sweeps) + " sweeps");
  }
  R.sphere = std::move(s);
  return R;
}

PipelineResult parameterize(const Mesh& mesh, const PipelineOptions& options) {
  if (!(std::isfinite(options.coarse_transport_spacing) && options.coarse_transport_spacing >= 0))
    throw std::invalid_argument("coarse_transport_spacing: must be a finite number >= 0, got " +
                                std::to_string(options.coarse_transport_spacing));
  // the separation passes file sites into cubes of side separation_delta·√(4π/N)
  if (!(std::isfinite(options.separation_delta) && options.separation_delta > 0))
    throw std::invalid_argument("separation_delta: must be a finite number > 0, got " +
                                std::to_string(options.separation_delta));
  if (!(std::isfinite(options.graded_dirac_ratio) &&
        (options.graded_dirac_ratio == 0 || options.graded_dirac_ratio > 1)))
    throw std::invalid_argument("graded_dirac_ratio: must be 0 (off) or a finite number > 1, got " +
                                std::to_string(options.graded_dirac_ratio));
  if (!(std::isfinite(options.graded_diracs_from) && options.graded_diracs_from >= 1))
    throw std::invalid_argument("graded_diracs_from: must be a finite number >= 1, got " +
                                std::to_string(options.graded_diracs_from));
  if (!(std::isfinite(options.min_spacing) && options.min_spacing >= 0))
    throw std::invalid_argument("separation_threshold (min_spacing): must be a finite number >= 0, got " +
                                std::to_string(options.min_spacing));
  auto t = Clock::now();
  const MeshReduction reduction = options.sub_resolution_area_ratio > 0
                                      ? remove_sub_resolution_vertices(mesh, options.sub_resolution_area_ratio)
                                      : MeshReduction{};
  if (reduction.removed.empty()) return map_mesh(mesh, options);
  const double reduction_seconds = since(t);
  say_progress(options, "sub-resolution vertices: " + std::to_string(reduction.removed.size()) + " removed in " +
                            std::to_string(reduction.rounds) + " round(s) (" + fmt_g(reduction_seconds) +
                            " s), mapping " + std::to_string(reduction.reduced.vertices.size()) + " vertices");
  // The reduced mesh is mapped without the final optimization, which runs once on the full mesh.
  PipelineOptions reduced_options = options;
  reduced_options.optimize = false;
  if (!options.vertex_factors.empty()) {
    reduced_options.vertex_factors.clear();
    for (int v : reduction.kept) reduced_options.vertex_factors.push_back(options.vertex_factors[u(v)]);
  }
  PipelineResult R = map_mesh(reduction.reduced, reduced_options);
  R.sub_resolution_vertices = reduction.removed.size();
  t = Clock::now();
  const std::size_t nv = mesh.vertices.size();
  R.initial = restore_sub_resolution_vertices(reduction, R.initial, nv);
  R.sphere = restore_sub_resolution_vertices(reduction, R.sphere, nv);
  const Topology topo(mesh);
  const auto targets = face_targets(mesh, options.vertex_factors);
  record_stage(R, mesh, targets, R.sphere, options, "restore_sub_resolution", reduction_seconds + since(t),
               std::to_string(reduction.removed.size()) + " vertices put back at their barycentric places");
  R.untangle_remaining = R.stages.back().flips;
  if (options.optimize && R.untangle_remaining == 0) {
    t = Clock::now();
    R.optimizer = optimize_area(mesh, topo, targets, R.sphere, options.optimizer);
    record_stage(R, mesh, targets, R.sphere, options, "area_optimization", since(t),
                 std::to_string(R.optimizer.sweeps) + " sweeps");
  }
  return R;
}

}  // namespace sphparam
