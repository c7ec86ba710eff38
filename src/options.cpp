#include "sdot/options.hpp"

#include <cmath>

#include "sdot/error.hpp"

namespace sdot {

std::string Options::validation_error() const {
  auto field = [](const char* name, const std::string& problem) {
    return std::string("options.") + name + ": " + problem;
  };
  if (!(std::isfinite(tolerance) && tolerance > 0))
    return field("tolerance", "must be a positive number, got " + std::to_string(tolerance));
  if (max_iterations < 0) return field("max_iterations", "must be >= 0, got " + std::to_string(max_iterations));
  if (max_step_halvings < 1 || max_step_halvings > 60)
    return field("max_step_halvings", "must be in [1, 60], got " + std::to_string(max_step_halvings));
  if (linear_solver == LinearSolverKind::cholmod && !has_cholmod())
    return field("linear_solver", "CHOLMOD is not available in this build (install libsuitesparse-dev and rebuild)");
  if (!(std::isfinite(cg_tolerance) && cg_tolerance > 0)) return field("cg_tolerance", "must be a positive number");
  if (!(std::isfinite(precision_floor_threshold) && precision_floor_threshold >= 0))
    return field("precision_floor_threshold", "must be a non-negative number");
  if (!(std::isfinite(mass_sum_tolerance) && mass_sum_tolerance >= 0))
    return field("mass_sum_tolerance", "must be a non-negative number");
  return {};
}

void Options::validate() const {
  const std::string error = validation_error();
  if (error.empty()) return;
  const auto colon = error.find(": ");
  throw InputError(error.substr(0, colon), error.substr(colon + 2));
}

LinearSolverKind linear_solver_from_name(std::string_view name) {
  if (name == "auto") return LinearSolverKind::automatic;
  if (name == "ldlt") return LinearSolverKind::ldlt;
  if (name == "cg") return LinearSolverKind::conjugate_gradient;
  if (name == "cholmod") return LinearSolverKind::cholmod;
  if (name == "multigrid") return LinearSolverKind::multigrid;
  throw InputError("linear_solver", "must be \"auto\", \"ldlt\", \"cg\", \"cholmod\" or \"multigrid\", got \"" +
                                        std::string(name) + "\"");
}

std::string_view to_string(Status status) {
  switch (status) {
    case Status::converged:
      return "converged";
    case Status::iteration_limit:
      return "iteration_limit";
    case Status::line_search_failure:
      return "line_search_failure";
    case Status::linear_solve_failure:
      return "linear_solve_failure";
    case Status::precision_floor:
      return "precision_floor";
  }
  return "unknown";
}

}  // namespace sdot
