"""sdot: semi-discrete optimal transport on the plane, the sphere and the hyperbolic plane.

    >>> import numpy as np, sdot
    >>> sites = np.random.default_rng(0).random((100, 2))
    >>> result = sdot.solve(sites)            # uniform density on the unit square, equal masses
    >>> result.status, result.weights.shape
    ('converged', (100,))

Functions: `solve`, `sphere_parameterization`, `read_mesh`, `write_mesh`; pictures in
`sdot.plot` (needs matplotlib); `python -m sdot.bench` times the solver like `sdot bench`.
Many problems at once on a Dask cluster: `sdot.batch` (needs dask and distributed).
"""

from ._mesh import read_mesh, sphere_parameterization, write_mesh
from ._solve import BALL_ARC, GEOMETRIES, SolveResult, solve

__version__ = "0.1.0"
__all__ = ["solve", "SolveResult", "BALL_ARC", "sphere_parameterization", "read_mesh", "write_mesh", "GEOMETRIES"]


def __getattr__(name):
    # sdot.plot imports matplotlib and sdot.batch Dask: only on first use.
    if name in ("plot", "batch"):
        import importlib

        return importlib.import_module("." + name, __name__)
    raise AttributeError(f"module 'sdot' has no attribute {name!r}")
