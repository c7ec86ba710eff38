#pragma once
/// \file run.hpp
/// One parameterization from a mesh as read to the mapped mesh and its report: validation,
/// removal of unreferenced vertices, orientation, the pipeline, metrics and the report JSON.
/// The `sdot-sphere-param` command and the Python package (`sdot.sphere_parameterization`) both
/// call it, so they give the same map and the same report.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "mesh.hpp"
#include "pipeline.hpp"

namespace sphparam {

struct RunResult {
  /// "ok", "flipped_faces", "ot_not_converged" (flip-free, but the last OT solve stopped short of
  /// its tolerance, so the areas are not those of the mesh; the report's `ot` says why),
  /// "invalid_input" (then `output` is empty and the report lists the defects) or "failed" (an
  /// internal error: the map is not finite; `errors` says where).
  std::string status;
  /// The mesh mapped onto the unit sphere: the input's referenced vertices in file order (a
  /// vertex that no face uses is dropped and the faces renumbered) and its faces in file order.
  Mesh output;
  /// The input index of each vertex of `output`.
  std::vector<int> kept;
  nlohmann::json report;
  Metrics initial;  ///< metrics of the initial map (empty unless asked for)
  Metrics final_map;
  /// One sentence per fatal defect when the input is invalid.
  std::vector<std::string> errors;
};

/// Parameterizes `raw` (as read from `input_name`, `info` from the reader). `vertex_factors`,
/// when not empty, has one positive factor per vertex of `raw`. `initial_metrics` asks for the
/// initial map's metrics (report and histogram only; they cost a pass over the faces).
RunResult run_parameterization(const Mesh& raw, const ReadInfo& info, PipelineOptions options,
                               const std::vector<double>& vertex_factors, bool initial_metrics,
                               const std::string& input_name);
/// The same, working on `raw` itself instead of a copy (the command: at 2 M vertices every copy
/// of the mesh is 100 MB).
RunResult run_parameterization(Mesh&& raw, const ReadInfo& info, PipelineOptions options,
                               const std::vector<double>& vertex_factors, bool initial_metrics,
                               const std::string& input_name);

/// The report's view of a Metrics.
nlohmann::json metrics_json(const Metrics& metrics);

}  // namespace sphparam
