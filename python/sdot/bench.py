"""`python -m sdot.bench`: the benchmark of `sdot bench`, solved through the Python package.

    python -m sdot.bench --geometry plane --n 100000 --tolerance 1e-6

prints one JSON line with the same fields as `sdot bench` (the same problem: the same sites,
equal masses, the same domain), plus `wall_s`, the time of the `sdot.solve` call as Python sees
it, and `python_overhead_s` = wall_s − time_s: what the package adds to the C++ solve
(argument checks, conversions in and out, packing the cells).
"""

import argparse
import json
import os
import sys
import time

from . import _sdot
from ._solve import GEOMETRIES, LINEAR_SOLVERS, solve


def run(geometry, n, seed=1, tolerance=1e-6, linear_solver="auto", progress=False):
    """Solves the benchmark problem and returns the bench line as a dict."""
    problem = dict(_sdot.bench_problem(geometry, n, seed))
    problem.pop("geometry")
    start = time.perf_counter()
    result = solve(
        geometry=geometry, tolerance=tolerance, linear_solver=linear_solver, progress=progress, **problem
    )
    wall = time.perf_counter() - start
    t = result.timings
    return {
        "geometry": geometry,
        "n": n,
        "status": result.status,
        "iterations": result.iterations,
        "max_relative_mass_error": result.max_relative_error,
        "time_s": t["total_s"],
        "diagram_s": t["diagram_s"],
        "assembly_s": t["assembly_s"],
        "linear_solve_s": t["linear_solve_s"],
        "peak_rss_mb": _sdot.peak_rss_mb(),
        "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY", "default"),
        "mmap_threshold": "default",  # the package leaves glibc's malloc as it is
        "glibc_malloc_hugetlb": _hugetlb_setting(os.environ.get("GLIBC_TUNABLES", "")),
        "wall_s": wall,
        "python_overhead_s": wall - t["total_s"],
    }


def _hugetlb_setting(tunables):
    """The value of glibc.malloc.hugetlb in GLIBC_TUNABLES, or "default" (as the sdot command reports it)."""
    values = [item.split("=", 1)[1] for item in tunables.split(":") if item.startswith("glibc.malloc.hugetlb=")]
    return values[-1] if values else "default"


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m sdot.bench", description=__doc__.split("\n\n")[0])
    parser.add_argument("--geometry", required=True, choices=GEOMETRIES)
    parser.add_argument("--n", type=int, required=True)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--tolerance", type=float, default=1e-6)
    parser.add_argument("--linear-solver", default="auto", choices=LINEAR_SOLVERS)
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    args = parser.parse_args(argv)
    if args.n < 1:
        parser.error("--n must be at least 1")
    line = run(args.geometry, args.n, args.seed, args.tolerance, args.linear_solver, progress=not args.quiet)
    print(json.dumps(line))
    return 0 if line["status"] in ("converged", "precision_floor") else 3


if __name__ == "__main__":
    sys.exit(main())
