"""sdot.solve and its result: argument checking and conversion around the compiled core."""

import sys
from numbers import Integral, Real

import numpy as np

from . import _sdot

GEOMETRIES = ("plane", "sphere", "hyperbolic", "torus")
LINEAR_SOLVERS = ("auto", "ldlt", "cg", "cholmod", "multigrid")
#: The ``cell_neighbors`` label of an edge that is an arc of the site's ball (partial transport).
BALL_ARC = -(2**31)


def _float_array(value, name, ndim=None, columns=None):
    """`value` as a C-contiguous float64 array (a copy only when needed), checked for shape and
    finiteness: TypeError for a non-numeric dtype, ValueError naming `name` (and the index) else."""
    try:
        array = np.asarray(value)
    except (ValueError, TypeError) as error:
        raise ValueError(f"{name}: cannot be read as an array ({error})") from None
    if array.dtype == object or array.dtype.kind not in "iuf":
        raise TypeError(f"{name}: must be an array of real numbers, got dtype {array.dtype}")
    array = np.ascontiguousarray(array, dtype=np.float64)
    if ndim is not None and array.ndim != ndim:
        want = f"shape (n, {' or '.join(map(str, columns))})" if columns else f"{ndim} dimension(s)"
        raise ValueError(f"{name}: must be an array of {want}, got shape {array.shape}")
    if columns is not None and array.shape[1] not in columns:
        raise ValueError(f"{name}: must have {' or '.join(map(str, columns))} columns, got shape {array.shape}")
    finite = np.isfinite(array)
    if not finite.all():
        index = np.argwhere(~finite)[0]
        where = index[0] if array.ndim <= 2 else tuple(index)
        raise ValueError(f"{name}[{where}]: is not finite")
    return array


def _int_array(value, name):
    array = np.asarray(value)
    if array.dtype.kind not in "iu":
        raise TypeError(f"{name}: must be an array of integers, got dtype {array.dtype}")
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"{name}: must be an array of shape (m, 3), got shape {array.shape}")
    return np.ascontiguousarray(array, dtype=np.int64)


def _domain(domain, geometry):
    """The domain as the compiled core expects it (see each geometry's python adapter)."""
    if domain is None:
        return None
    if geometry == "sphere" and isinstance(domain, dict) and "center" in domain:
        unknown = set(domain) - {"center", "angle"}
        if unknown or "angle" not in domain:
            raise ValueError("domain: a cap is {'center': (x, y, z), 'angle': radians}")
        center = _float_array(domain["center"], "domain.center", ndim=1)
        return ("cap", [float(c) for c in center], float(domain["angle"]))
    if geometry == "plane" and isinstance(domain, (dict, list)) and (
        isinstance(domain, dict) or (domain and isinstance(domain[0], dict))
    ):
        polygons = [domain] if isinstance(domain, dict) else domain
        result = []
        for i, polygon in enumerate(polygons):
            name = "domain" if isinstance(domain, dict) else f"domain[{i}]"
            unknown = set(polygon) - {"outer", "holes"}
            if unknown or "outer" not in polygon:
                raise ValueError(f"{name}: a polygon with holes is {{'outer': ring, 'holes': [ring, ...]}}")
            outer = _float_array(polygon["outer"], f"{name}.outer", ndim=2, columns=(2,))
            holes = [
                _float_array(h, f"{name}.holes[{k}]", ndim=2, columns=(2,)) for k, h in enumerate(polygon.get("holes", []))
            ]
            result.append((outer, holes))
        return ("region", result)
    columns = {"plane": (2,), "sphere": (3,), "hyperbolic": (2, 3)}[geometry]
    return ("polygon", _float_array(domain, "domain", ndim=2, columns=columns))


def _periodic(periodic, geometry, domain):
    """For a periodic problem (`periodic` set, or geometry "torus"): the periodic axes (x, y) and
    the box ("box", x0, y0, x1, y1) as the compiled core expects them; None otherwise."""
    if geometry == "torus":  # periodic by default; periodic=False leaves the box, unwrapped
        periodic = True if periodic is None else (False, False) if periodic is False else periodic
    elif periodic is None or periodic is False:
        return None
    if geometry not in ("plane", "torus"):
        raise ValueError(f"periodic: only the plane has periodic domains, not the {geometry} geometry")
    if isinstance(periodic, (bool, np.bool_)):
        axes = (bool(periodic), bool(periodic))
    else:
        try:
            axes = tuple(periodic)
        except TypeError:
            axes = ()
        if len(axes) != 2 or not all(isinstance(a, (bool, np.bool_)) for a in axes):
            raise ValueError(f"periodic: must be True, False or two booleans (x, y), got {periodic!r}")
        axes = (bool(axes[0]), bool(axes[1]))
    box = "domain: a periodic problem needs a rectangular box: (x0, y0, x1, y1) or its 4 corners, shape (4, 2)"
    if domain is None:
        return axes, ("box", 0.0, 0.0, 1.0, 1.0)
    if isinstance(domain, dict):
        raise ValueError(box)
    array = _float_array(domain, "domain")
    if array.shape == (4,):
        return axes, ("box", *map(float, array))
    if array.shape != (4, 2):
        raise ValueError(f"{box}; got shape {array.shape}")
    low, high = array.min(axis=0), array.max(axis=0)
    for k, corner in enumerate(array):
        if not (corner[0] in (low[0], high[0]) and corner[1] in (low[1], high[1])):
            raise ValueError(f"domain[{k}]: {box[len('domain: '):]} (this corner is not one of an axis-aligned box)")
    if len({(float(x), float(y)) for x, y in array}) != 4:
        raise ValueError(f"{box} (its corners repeat)")
    return axes, ("box", float(low[0]), float(low[1]), float(high[0]), float(high[1]))


def _density(density, extent, interpolation, quadrature_order):
    """The density as the compiled core expects it: None, or a tagged tuple."""
    if density is None:
        if extent is not None or interpolation is not None:
            raise ValueError("extent and interpolation describe an image density, but there is none")
        return None
    if callable(density):
        return ("function", density, 8 if quadrature_order is None else int(quadrature_order))
    if isinstance(density, dict):
        unknown = set(density) - {"vertices", "triangles", "values", "triangle_values"}
        if unknown:
            raise ValueError(f"density.{sorted(unknown)[0]}: unknown field")
        if ("values" in density) == ("triangle_values" in density):
            raise ValueError("density: give exactly one of 'values' (per vertex) and 'triangle_values' (per triangle)")
        per_triangle = "triangle_values" in density
        vertices, triangles = density.get("vertices"), density.get("triangles")
        if vertices is None or triangles is None:
            raise ValueError("density: a mesh density needs 'vertices' and 'triangles'")
        values = density["triangle_values" if per_triangle else "values"]
        density = (vertices, triangles, values)
    else:
        per_triangle = None
    if isinstance(density, (tuple, list)):
        if len(density) != 3:
            raise ValueError("density: a mesh density is (vertices, triangles, values)")
        vertices = _float_array(density[0], "density.vertices", ndim=2, columns=(2, 3))
        triangles = _int_array(density[1], "density.triangles")
        values = _float_array(density[2], "density.values", ndim=1)
        if per_triangle is None:
            if len(values) == len(vertices):
                per_triangle = False
            elif len(values) == len(triangles):
                per_triangle = True
            else:
                raise ValueError(
                    f"density.values: {len(values)} values for {len(vertices)} vertices and {len(triangles)} triangles"
                    " (one per vertex or one per triangle)"
                )
        order = 3 if quadrature_order is None else int(quadrature_order)
        return ("mesh", vertices, triangles, values, per_triangle, order)
    image = _float_array(density, "density", ndim=2)
    if extent is not None:
        extent = [float(x) for x in _float_array(extent, "extent", ndim=1)]
    return ("image", image, extent, interpolation or "", 1.0)


class SolveResult:
    """The solution of one transport problem (see `sdot.solve`).

    Attributes: ``weights`` (n,), ``masses`` (n,) reached, ``target_masses`` (n,) after any
    rescaling, ``centroids`` (n, d), ``transport_cost``, ``status``, ``message``, ``iterations``,
    ``max_relative_error``, ``rms_relative_error``, ``mass_scale``, ``source_mass``, ``timings``
    (dict of seconds), ``history`` (one dict per Newton iteration), ``geometry``, ``sites``.
    The cells are ``cells`` (a list of (k, d) vertex arrays, counter-clockwise) and, in one block,
    ``cell_vertices`` with ``cell_offsets`` (cell i is rows offsets[i]:offsets[i+1]) and
    ``cell_neighbors`` (the site across each edge; negative on the domain's boundary, and
    ``BALL_ARC`` for an arc of the site's ball in a partial-transport solve, from that vertex to
    the next counter-clockwise around the site). With ``partial=True``, ``ball_radii`` holds each
    ball's (geodesic) radius. A periodic plane's result also has ``box`` (x0, y0, x1, y1) and
    ``periodic`` (x, y); its cells are polygons of the covering plane around the sites wrapped
    into the box.
    On H², points are in the hyperboloid (x, y, z), and ``centroids_poincare``,
    ``cells_poincare`` and ``cell_vertices_poincare`` give them in the Poincaré disk.
    """

    def __init__(self, fields, geometry, sites):
        self.__dict__.update(fields)
        self.geometry = geometry
        self.sites = sites
        self._cells = {}

    def _split(self, key):
        if key not in self._cells:
            self._cells[key] = np.split(self.__dict__["cell_vertices" + key], self.cell_offsets[1:-1])
        return self._cells[key]

    @property
    def cells(self):
        """One (k, d) array of vertices per site (k = 0 for an empty cell)."""
        return self._split("")

    @property
    def cells_poincare(self):
        """H² only: the cells in the Poincaré disk, one (k, 2) array per site."""
        if "cell_vertices_poincare" not in self.__dict__:
            raise AttributeError("cells_poincare exists for the hyperbolic geometry only")
        return self._split("_poincare")

    @property
    def converged(self):
        """True when the tolerance was reached."""
        return self.status == "converged"

    @property
    def usable(self):
        """Converged, or stopped at the precision floor of double arithmetic."""
        return self.status in ("converged", "precision_floor")

    def adjacency(self):
        """Sorted neighbour lists of the cells."""
        result = []
        for i in range(len(self.weights)):
            labels = self.cell_neighbors[self.cell_offsets[i] : self.cell_offsets[i + 1]]
            result.append(np.unique(labels[labels >= 0]))
        return result

    def __repr__(self):
        return (
            f"SolveResult(geometry={self.geometry!r}, n={len(self.weights)}, status={self.status!r}, "
            f"iterations={self.iterations}, max_relative_error={self.max_relative_error:.3g})"
        )


def _iteration_hook(progress, callback):
    """The per-iteration function handed to the core: prints a progress line and/or calls back."""
    if not progress and callback is None:
        return None

    def hook(iteration, max_error, rms_error, step, elapsed):
        record = {
            "iteration": iteration,
            "max_relative_error": max_error,
            "rms_relative_error": rms_error,
            "step": step,
            "elapsed_s": elapsed,
        }
        if progress:
            sys.stderr.write(
                f"\rsdot: iteration {iteration:3d}  max rel. error {max_error:9.3e}  step {step:<8g} {elapsed:8.3f} s"
            )
            sys.stderr.flush()
        if callback is not None:
            callback(record)

    return hook


def solve(
    sites,
    masses=None,
    *,
    geometry="plane",
    domain=None,
    density=None,
    tolerance=1e-9,
    max_iterations=100,
    weights=None,
    linear_solver="auto",
    rescale_masses=None,
    partial=False,
    progress=False,
    callback=None,
    model="poincare",
    builder=None,
    extent=None,
    interpolation=None,
    quadrature_order=None,
    periodic=None,
):
    """Semi-discrete optimal transport from a density to the Diracs Σ masses[i] δ(sites[i]).

    Finds the weights whose Laguerre cells carry exactly the masses, by the damped Newton method.

    Parameters
    ----------
    sites : array (n, 2) on the plane, (n, 3) unit vectors on the sphere; on H², (n, 2) in the
        Poincaré or Klein disk or (n, 3) on the hyperboloid, as `model` says.
    masses : array (n,), positive, summing to the source's mass (the domain's area for the uniform
        density). None: equal masses. With ``rescale_masses=True`` any positive masses are
        scaled to the source's mass (the factor is ``result.mass_scale``).
    geometry : "plane", "sphere", "hyperbolic", or "torus" (the plane with periodic=True).
    domain : plane: None (the unit square), a polygon (k, 2) or {"outer": ring, "holes": [...]}
        (or a list of those); sphere: None (the whole sphere), {"center": xyz, "angle": radians}
        (a cap) or a convex polygon (k, 3); H²: a convex polygon (required), in `model`'s coordinates.
    density : None (uniform); a 2-D array (an image, row 0 at the top: over `extent` = (x0, y0,
        x1, y1), default the domain's bounding box, on the plane; a longitude–latitude map of the
        whole sphere, column 0 at longitude −180°, row 0 at latitude +90°); a mesh
        (vertices, triangles, values) with one value per vertex (piecewise linear) or per triangle
        (piecewise constant); or a function taking an (m, d) array of points (in the sites'
        coordinates) and returning m values ≥ 0, called once per cell on all its quadrature points.
    tolerance : stop when max_i |mass_i − masses_i| / masses_i ≤ tolerance.
    max_iterations : Newton iterations at most.
    weights : initial weights (n,); every cell must be non-empty with them.
    partial : partial transport: each cell is its Laguerre cell cut by the site's ball
        {x : c(x, y_i) ≤ w_i} (radius √(2 w_i) on the plane, arccos e^{−w_i} on the sphere,
        arccosh e^{w_i} on H²), so the source keeps the mass farther from every site than its ball
        reaches. `masses` are then required, not rescaled, and must sum to less than the source's
        mass; uniform density only. The radii come back in ``result.ball_radii``.
    linear_solver : "auto", "ldlt", "cg", "cholmod" or "multigrid".
    progress : print one updating line per Newton iteration on stderr.
    callback : called after each iteration with a dict (iteration, max_relative_error,
        rms_relative_error, step, elapsed_s); an exception it raises stops the solve.
    model : H² only: "poincare", "klein" or "hyperboloid", for sites, domain and density points.
    builder : sphere only: "automatic", "hull" or "clipping".
    interpolation : image densities: "bilinear" or "constant" (plane), "linear" or "constant" (sphere).
    quadrature_order : points per direction of the quadrature of function (default 8) and
        piecewise-linear mesh densities (default 3).
    periodic : plane only: True (both axes), or (x, y) booleans, makes the domain periodic: a box
        whose opposite sides are identified, with the cost ½ d² for d the distance on the torus
        (docs/torus.md). `domain` is then the box, (x0, y0, x1, y1) or its 4 corners (4, 2)
        (default the unit square); sites anywhere (wrapped into the box); densities are given on
        the box. The cells are convex polygons of the covering plane around the wrapped sites
        (vertices possibly outside the box, by less than half a period), centroids are in the box,
        and the result has ``box`` and ``periodic``. geometry="torus" is the same with
        periodic=True by default.

    Returns
    -------
    SolveResult. A solve that stops without converging is reported in ``status`` and ``message``,
    not raised. Bad input raises ValueError (or TypeError for a wrong dtype) naming the field and
    index; Ctrl-C stops the solve with KeyboardInterrupt.
    """
    if geometry not in GEOMETRIES:
        raise ValueError(f"geometry: must be one of {', '.join(map(repr, GEOMETRIES))}, got {geometry!r}")
    hyperbolic_columns = (3,) if model == "hyperboloid" else (2,)
    columns = {"plane": (2,), "torus": (2,), "sphere": (3,), "hyperbolic": hyperbolic_columns}[geometry]
    sites = _float_array(sites, "sites", ndim=2, columns=columns)
    if len(sites) == 0:
        raise ValueError("sites: at least one site is needed")
    n = len(sites)
    if masses is not None:
        masses = _float_array(masses, "masses", ndim=1)
        if len(masses) != n:
            raise ValueError(f"masses: there are {len(masses)} masses for {n} sites")
    if partial and masses is None:
        raise ValueError("masses: partial transport needs the masses (summing to less than the source's mass)")
    if partial and density is not None:
        raise ValueError("density: partial transport is implemented for the uniform density only")
    if weights is not None:
        weights = _float_array(weights, "weights", ndim=1)
        if len(weights) != n:
            raise ValueError(f"weights: there are {len(weights)} weights for {n} sites")
    if not isinstance(tolerance, Real) or isinstance(tolerance, bool):
        raise TypeError(f"tolerance: must be a number, got {type(tolerance).__name__}")
    if not isinstance(max_iterations, Integral) or isinstance(max_iterations, bool):
        raise TypeError(f"max_iterations: must be an integer, got {type(max_iterations).__name__}")
    if linear_solver not in LINEAR_SOLVERS:
        raise ValueError(f"linear_solver: must be one of {', '.join(map(repr, LINEAR_SOLVERS))}, got {linear_solver!r}")
    if callback is not None and not callable(callback):
        raise TypeError("callback: must be callable")
    extra = {}
    if geometry == "hyperbolic":
        extra["model"] = model
    if builder is not None:
        if geometry != "sphere":
            raise ValueError("builder: only the sphere has a choice of builder")
        extra["builder"] = builder
    core_geometry = geometry
    periodic_box = _periodic(periodic, geometry, domain)
    if periodic_box is not None:  # the compiled core's "torus" geometry
        core_geometry = "torus"
        extra["periodic"], domain = periodic_box
    hook = _iteration_hook(progress, callback)
    try:
        fields = _sdot.solve(
            core_geometry,
            sites,
            masses,
            weights,
            domain if periodic_box is not None else _domain(domain, geometry),
            _density(density, extent, interpolation, quadrature_order),
            extra,
            float(tolerance),
            int(max_iterations),
            linear_solver,
            bool(rescale_masses) if rescale_masses is not None else False,
            bool(partial),
            hook,
        )
    finally:
        if progress:
            sys.stderr.write("\n")
    result = SolveResult(fields, geometry, sites)
    if geometry == "hyperbolic":
        result.model = model
    return result
