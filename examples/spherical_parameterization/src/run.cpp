#include "run.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <utility>

namespace sphparam {

using json = nlohmann::json;

json metrics_json(const Metrics& m) {
  return {{"area_mean_abs", m.area_mean_abs},
          {"area_std", m.area_std},
          {"area_max_abs", m.area_max_abs},
          {"area_nonfinite", m.area_nonfinite},
          {"angle_mean_abs_deg", m.angle_mean_abs_deg},
          {"angle_p95_deg", m.angle_p95_deg},
          {"flips", m.flips},
          {"sph_area_sum_over_4pi", m.sph_area_sum_over_4pi}};
}

RunResult run_parameterization(const Mesh& raw, const ReadInfo& info, PipelineOptions options,
                               const std::vector<double>& vertex_factors, bool initial_metrics,
                               const std::string& input_name) {
  return run_parameterization(Mesh(raw), info, std::move(options), vertex_factors, initial_metrics, input_name);
}

RunResult run_parameterization(Mesh&& raw, const ReadInfo& info, PipelineOptions options,
                               const std::vector<double>& vertex_factors, bool initial_metrics,
                               const std::string& input_name) {
  RunResult result;
  json& report = result.report;
  report["input"] = input_name;
  // One copy of the mesh all along (2 M vertices: 100 MB a copy): taken over from the caller,
  // scaled, stripped of unreferenced vertices and oriented in place.
  // The map does not depend on the mesh's scale, but its arithmetic does: coordinates of 1e200
  // overflow the areas, and 1e-200 underflow them. A power-of-two scale bringing the largest
  // coordinate into [0.5, 1) is exact, so ordinary meshes give the same bits as unscaled.
  Mesh mesh = std::move(raw);
  const std::size_t vertices_in_file = mesh.vertices.size();
  const int exponent = scale_by_power_of_two(mesh);
  const auto validation_start = std::chrono::steady_clock::now();
  const Validation v = validate(mesh, info);
  const double validate_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - validation_start).count();
  json defects = json::array();
  for (const auto& d : v.defects) {
    defects.push_back({{"defect", d.name}, {"count", d.count}, {"fatal", d.fatal}, {"message", d.message}});
    if (d.fatal) result.errors.push_back(d.message);
  }
  report["input_statistics"] = {{"format", info.format},
                                {"vertices_in_file", vertices_in_file},
                                {"vertices", v.vertices},
                                {"faces", v.faces},
                                {"edges", v.edges},
                                {"euler_characteristic", v.euler_characteristic},
                                {"components", v.components},
                                {"signed_volume", std::ldexp(v.signed_volume, 3 * exponent)},
                                {"orientation", v.inward ? -1 : 1},
                                {"min_angle_deg", v.min_angle_deg},
                                {"area_ratio_max_min", v.area_ratio},
                                {"defects", defects}};
  if (!v.ok()) {
    result.status = report["status"] = "invalid_input";
    return result;
  }
  if (options.progress)
    options.progress("read " + input_name + " (" + std::to_string(v.vertices) + " vertices, " +
                     std::to_string(v.faces) + " faces)");
  std::vector<int>& kept = result.kept;
  if (v.unreferenced > 0) {
    mesh = drop_unreferenced(mesh, &kept);
  } else {
    kept.resize(mesh.vertices.size());
    std::iota(kept.begin(), kept.end(), 0);
  }
  if (!vertex_factors.empty()) {
    options.vertex_factors.resize(kept.size());
    for (std::size_t i = 0; i < kept.size(); ++i)
      options.vertex_factors[i] = vertex_factors[static_cast<std::size_t>(kept[i])];
  }
  auto reverse_faces = [&mesh] {
    for (auto& f : mesh.faces) std::swap(f[1], f[2]);
  };
  if (v.inward) reverse_faces();  // the pipeline works on the outward-oriented mesh
  const auto start = std::chrono::steady_clock::now();
  PipelineResult R = parameterize(mesh, options);
  const double compute_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  double target_error = 0;  // against the weighted targets (with --target-weights)
  if (!options.vertex_factors.empty())
    target_error = target_area_error(mesh, R.sphere, face_targets(mesh, options.vertex_factors));
  if (v.inward) reverse_faces();  // the input's faces again

  for (std::size_t i = 0; i < R.sphere.size(); ++i)
    if (!R.sphere[i].allFinite()) {  // never written: a bug to report, not a map
      result.status = report["status"] = "failed";
      report["error"] = "the map of vertex " + std::to_string(kept[i]) + " is not finite";
      result.errors.push_back(report["error"].get<std::string>());
      return result;
    }

  const double sign = v.inward ? -1.0 : 1.0;
  if (initial_metrics) result.initial = evaluate_map(mesh, R.initial, sign);
  std::vector<Vec3>().swap(R.initial);
  result.final_map = evaluate_map(mesh, R.sphere, sign);
  // A flip-free map from an OT that stopped short of its tolerance has areas far from the mesh's:
  // not "ok" (armadillo_43k with 2 stretch reweightings and no coarse transport: the OT's line
  // search failed, the rerun on refined Diracs found an empty cell at its start, area mean|d| 1.9).
  const bool ot_converged = R.ot.status == "converged" || R.ot.status == "precision_floor" || R.ot.status == "skipped";
  result.status = report["status"] =
      result.final_map.flips > 0 ? "flipped_faces" : (ot_converged ? "ok" : "ot_not_converged");
  json stages = json::array();
  json times = {{"validate_s", validate_s}};
  for (const auto& s : R.stages) {
    stages.push_back({{"stage", s.name},
                      {"seconds", s.seconds},
                      {"target_area_mean_abs", s.area_mean_abs},
                      {"flips", s.flips},
                      {"note", s.note}});
    times[s.name + "_s"] = times.value(s.name + "_s", 0.0) + s.seconds;  // summed over OT reruns
  }
  times["compute_s"] = compute_s;
  report["times"] = times;
  report["stages"] = stages;
  report["ot"] = {{"status", R.ot.status},
                  {"message", R.ot.message},
                  {"newton_iterations", R.ot.iterations},
                  {"max_relative_mass_error", R.ot.max_relative_error},
                  {"rms_relative_mass_error", R.ot.rms_relative_error},
                  {"diracs", R.ot.sites},
                  {"refinement_levels", R.ot.refine},
                  {"graded_faces", R.ot.graded_faces},
                  {"height_range", R.ot.height_range},
                  {"error_history", R.ot.error_history}};
  const double visits_per_vertex = visit_limit(options.optimizer);
  report["optimizer"] = {
      {"angle_weight", options.optimizer.angle_weight},
      {"sweep_limit", sweep_limit(options.optimizer)},
      // null: no limit
      {"visit_limit_per_vertex", std::isfinite(visits_per_vertex) ? json(visits_per_vertex) : json(nullptr)},
      // of those, the first run's at angle weight 0 (0: none)
      {"area_first_visits_per_vertex", area_first_visit_limit(options.optimizer)},
      {"over_relaxation", R.optimizer.over_relaxation},
      {"sweeps", R.optimizer.sweeps},
      {"visits", R.optimizer.visits},
      {"energy_start", R.optimizer.energy_start},
      {"energy_end", R.optimizer.energy_end},
      {"untangle_remaining_flips", R.untangle_remaining}};
  report["untangling"] = {{"levels", R.untangling.levels},
                          {"global_sweeps", R.untangling.global_sweeps},
                          {"local_sweeps", R.untangling.local_sweeps},
                          {"visits", R.untangling.visits}};
  const FallbackCounts& fb = R.fallbacks;
  report["fallbacks"] = {{"total", fb.total()},
                         {"hierarchical_initial_map", fb.hierarchical_initial_map},
                         {"separation_passes", fb.separation_passes},
                         {"flip_patches", fb.flip_patches},
                         {"chart_untangles", fb.chart_untangles},
                         {"ot_reruns", fb.ot_reruns},
                         {"laplacian_rounds", fb.laplacian_rounds},
                         {"free_smoothing", fb.free_smoothing}};
  report["sub_resolution_vertices"] = R.sub_resolution_vertices;
  report["initial_map"] = metrics_json(result.initial);
  report["final_map"] = metrics_json(result.final_map);
  if (!options.vertex_factors.empty()) report["final_map"]["target_area_mean_abs"] = target_error;
  result.output.faces = std::move(mesh.faces);
  result.output.vertices = std::move(R.sphere);
  for (auto& p : result.output.vertices) p.normalize();
  return result;
}

}  // namespace sphparam
