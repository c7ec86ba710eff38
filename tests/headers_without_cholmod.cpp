// Compiled (never run) without SDOT_HAVE_CHOLMOD, so that the public headers keep building for a
// library configured without SuiteSparse even when this build has it.
#ifdef SDOT_HAVE_CHOLMOD
#error "this translation unit must be compiled without SDOT_HAVE_CHOLMOD"
#endif
#include "sdot/linear_solver.hpp"
#include "sdot/options.hpp"

bool automatic_solver_reports_no_cholmod() {
  return !sdot::AutomaticLinearSolver{}.uses_cholmod();
}
