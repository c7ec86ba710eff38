#pragma once
/// \file pipeline.hpp
/// The whole parameterization: initial map → OT (sdot::Sphere + sdot::solve) → centroids →
/// untangling → flip-free area optimization, with timings and metrics of every stage.

#include <functional>
#include <string>
#include <vector>

#include "mesh.hpp"
#include "param.hpp"

namespace sphparam {

/// From this many vertices, and with at most one flipped face in 1000 after OT, the regularised
/// untangling starts from the flipped faces' neighbourhoods only.
inline constexpr std::size_t local_untangling_from = 500000;

struct PipelineOptions {
  /// Dirac refinement levels (each level splits every triangle in 4); −1 chooses by size.
  int refine = 0;
  /// Should flips survive the untangling, OT and untangling rerun with one more refinement
  /// level, up to this many levels.
  int max_refine = 1;
  /// Graded Diracs (refinement 0 only): where a face's target is more than
  /// `graded_diracs_from` times the lightest vertex Dirac within one ring of its corners, faces
  /// are split (up to 4^3 sub-triangles) until no sub-triangle exceeds `graded_dirac_ratio` times
  /// that lightest Dirac. 0 disables them.
  double graded_dirac_ratio = 8;
  double graded_diracs_from = 64;
  /// Max relative mass error of the OT solve. The map's per-face area error after OT is a sampling
  /// error of about one cell (area mean|d| 0.08–0.12), which tighter masses do not reduce: on the
  /// 16 shared meshes 1e-4 took 1–2 more Newton iterations and left the final figures of 13 meshes
  /// unchanged in every printed digit (arm, cow_igl, lion_50k: area mean|d| within 0.6 %).
  /// The Newton iterate before the last is at 0.07–0.15 on most meshes (the last at 0.001–0.003):
  /// 0.15 against 0.05 saved that iteration on 11 of the 34 shared and hard meshes (spiky_120k's
  /// OT 1.32 s → 1.07 s) and left the final area mean|d| within 1.5 % on all but arm.off
  /// (0.0138 → 0.0145) and the flips at 0.
  double ot_tolerance = 0.15;
  int ot_max_iterations = 60;
  /// Stretch reweightings of the Tutte map at most (only while regions are crushed).
  int max_reweightings = 40;
  /// Separation passes run while the shortest edge of the map is below this times sqrt(4π/N).
  double min_spacing = 5e-5;
  /// Separation radius of the representatives, times sqrt(4π/N).
  double separation_delta = 0.1;
  /// Meshes of coarse_transport_from_vertices to coarse_transport_up_to_vertices vertices: before
  /// the OT, every site moves by the displacement of an OT on representatives this far apart,
  /// times sqrt(4π/N), which saves Newton steps of the OT (spiky_120k, armadillo_43k, spiky_60k:
  /// 7-8 → 5); 0: off. At brain scale it saved one of 3 Newton iterations (igea_134k
  /// Loop-subdivided twice, 2.1 M vertices: the OT 19.8 s → 14.1 s) but took 2.7 s itself, its OT
  /// centroids folded 13 faces (0.8 s of untangling) and the final area mean|d| rose from
  /// 0.00124 to 0.00148.
  double coarse_transport_spacing = 8;
  std::size_t coarse_transport_from_vertices = 40000;
  std::size_t coarse_transport_up_to_vertices = 500000;
  /// When the reweighted Tutte map stays crushed, start from hierarchical_sphere_map instead
  /// (--coarse-to-fine). Without it, only a Tutte map crushed below rounding does (long thin
  /// tubes: tutte_sphere_map's `crushed_below_rounding`), where the OT cannot separate the
  /// coinciding vertices. Off by default: on meshes that the OT maps from a crushed Tutte map it
  /// gives worse areas (cow_igl: area mean|d| 0.0646 against 0.0443).
  bool hierarchical_initial_map = false;
  /// Vertices of valence 3 or 4 whose smallest incident face is below this times the largest are
  /// mapped by their barycentric place in the face that replaces them (sub_resolution.hpp);
  /// 0 keeps every vertex in the OT.
  double sub_resolution_area_ratio = 1e-2;
  bool optimize = true;  ///< run the final area-correcting optimization
  OptimizeOptions optimizer;
  std::vector<double> vertex_factors;  ///< --target-weights (empty: uniform)
  /// Progress lines (stage starts, Newton iterations); may be empty.
  std::function<void(const std::string&)> progress;
};

struct StageRecord {
  std::string name;
  double seconds = 0;
  double area_mean_abs = 0;  ///< against the targets, after the stage
  std::size_t flips = 0;
  std::string note;
};

struct OtRecord {
  std::string status = "not run";  ///< converged, precision_floor, iteration_limit, failed, unavailable, skipped (after
                                   ///< a flip-free coarse-to-fine map)
  std::string message;
  int iterations = 0;
  double max_relative_error = 0;
  double rms_relative_error = 0;
  std::size_t sites = 0;
  int refine = 0;
  std::size_t graded_faces = 0;  ///< faces split into graded Diracs (refinement 0)
  double min_site_distance = 0;
  double height_range = 0;  ///< max h − min h
  std::vector<double> error_history;
};

/// What the regularised untangling did (all 0 when the OT map had no flipped face).
struct UntanglingRecord {
  int levels = 0;          ///< ε levels run (0.1, 0.03, 0.01, …)
  int global_sweeps = 0;   ///< sweeps that started from every vertex
  int local_sweeps = 0;    ///< sweeps that started near the flipped faces
  std::size_t visits = 0;  ///< vertex updates tried in all of them
};

/// How often each fallback path ran: each is a repair of what the main path left, so on an
/// ordinary mesh they are all 0.
struct FallbackCounts {
  int hierarchical_initial_map = 0;  ///< the Tutte map stayed crushed: coarse-to-fine map instead
  int separation_passes = 0;         ///< OT passes on separated representatives of crushed sites
  int flip_patches = 0;              ///< flipped faces whose surrounding disk was re-embedded
  int chart_untangles = 0;           ///< of these, patches untangled by the foldover-free energy
  int ot_reruns = 0;                 ///< OT and untangling rerun with one more Dirac level
  int laplacian_rounds = 0;          ///< rounds of monotone Laplacian moves and the regularised energy
  int free_smoothing = 0;            ///< free Laplacian smoothing on growing rings
  [[nodiscard]] int total() const {
    return hierarchical_initial_map + separation_passes + flip_patches + chart_untangles + ot_reruns +
           laplacian_rounds + free_smoothing;
  }
};

struct PipelineResult {
  std::vector<Vec3> initial;  ///< the initial (Tutte + Möbius) map
  std::vector<Vec3> sphere;   ///< the final map
  std::vector<StageRecord> stages;
  OtRecord ot;
  std::size_t untangle_remaining = 0;
  UntanglingRecord untangling;
  OptimizeResult optimizer;
  FallbackCounts fallbacks;
  HierarchyInfo hierarchy;                  ///< when fallbacks.hierarchical_initial_map
  std::size_t sub_resolution_vertices = 0;  ///< removed before the map, put back after it
};

/// Parameterizes an outward-oriented, validated closed genus-0 mesh.
PipelineResult parameterize(const Mesh& mesh, const PipelineOptions& options);

/// Mean |log(A_sphere / target)| over faces (the area metric against the targets).
double target_area_error(const Mesh& mesh, const std::vector<Vec3>& s, const std::vector<double>& targets);

}  // namespace sphparam
