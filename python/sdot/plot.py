"""Pictures with matplotlib: Laguerre cells on the plane, on the sphere (Mollweide projection)
and in the Poincaré disk; the distortion histogram of a spherical parameterization.

matplotlib is imported here only, so `import sdot` works without it.
"""

import numpy as np

import matplotlib.pyplot as plt
from matplotlib.collections import LineCollection, PolyCollection


def _colors(result, color_by, cmap):
    """Face colours of the cells: None (no fill), "mass" / "weight" / "target_mass" / "error"
    (relative mass error), or an array with one value per cell."""
    if color_by is None:
        return None
    named = {
        "mass": lambda: result.masses,
        "masses": lambda: result.masses,
        "weight": lambda: result.weights,
        "weights": lambda: result.weights,
        "target_mass": lambda: result.target_masses,
        "error": lambda: (result.masses - result.target_masses) / result.target_masses,
    }
    if isinstance(color_by, str):
        if color_by not in named:
            raise ValueError(f"color_by: must be one of {sorted(named)} or an array, got {color_by!r}")
        values = np.asarray(named[color_by](), dtype=float)
    else:
        values = np.asarray(color_by, dtype=float)
        if values.shape != (len(result.weights),):
            raise ValueError(f"color_by: needs one value per cell ({len(result.weights)}), got shape {values.shape}")
    low, high = np.nanmin(values), np.nanmax(values)
    # Values equal up to rounding (converged masses) get one colour, not rounding noise stretched.
    spread = high - low > 1e-9 * max(abs(high), abs(low))
    scaled = (values - low) / (high - low) if spread else np.full_like(values, 0.5)
    return plt.get_cmap(cmap)(scaled)


def _geodesic_samples(a, b, count, geometry):
    """`count` points on the geodesic from a to b (straight in the chart: linear interpolation,
    then back to the surface)."""
    t = np.linspace(0.0, 1.0, count)[:, None]
    p = (1 - t) * a + t * b
    if geometry == "sphere":
        return p / np.linalg.norm(p, axis=1, keepdims=True)
    # hyperboloid: x / sqrt(−<x, x>) (Minkowski), positive last coordinate
    return p / np.sqrt(p[:, 2] ** 2 - p[:, 0] ** 2 - p[:, 1] ** 2)[:, None]


def _site_native(result, i):
    """Site i in the cells' coordinates: the plane, the unit sphere, or the hyperboloid."""
    y = np.asarray(result.sites[i], dtype=float)
    if result.geometry == "plane":
        return y
    if result.geometry == "sphere":
        return y / np.linalg.norm(y)
    model = getattr(result, "model", "poincare")
    if model == "hyperboloid":
        return y
    r2 = y @ y
    if model == "klein":
        return np.append(y, 1.0) / np.sqrt(1 - r2)
    return np.append(2 * y, 1 + r2) / (1 - r2)


def _arc_samples(site, a, b, count, geometry):
    """`count` points on the arc of the ball around `site` from a to b, counter-clockwise
    (partial transport): a turned about the site, in the plane, on the sphere or on the hyperboloid."""
    t = np.linspace(0.0, 1.0, count)[:, None]
    if geometry == "plane":
        u, v = a - site, b - site
        sweep = np.arctan2(u[0] * v[1] - u[1] * v[0], u @ v) % (2 * np.pi)
        c, s = np.cos(t * sweep), np.sin(t * sweep)
        return site + np.hstack((c * u[0] - s * u[1], s * u[0] + c * u[1]))
    if geometry == "sphere":
        along = a @ site
        u = a - along * site
        turned = np.cross(site, u)
        sweep = np.arctan2(site @ np.cross(a, b), a @ b - along * (b @ site)) % (2 * np.pi)
        return along * site + np.cos(t * sweep) * u + np.sin(t * sweep) * turned
    j = np.array([1.0, 1.0, -1.0])
    mink = lambda x, y: x @ (j * y)  # noqa: E731
    u, v = a + mink(a, site) * site, b + mink(b, site) * site
    turned = j * np.cross(site, u)
    sweep = np.arctan2(site @ np.cross(u, v), mink(u, v)) % (2 * np.pi)
    return -mink(a, site) * site + np.cos(t * sweep) * u + np.sin(t * sweep) * turned


def _edge_samples(result, i, cell, k, count):
    """Points along edge k of cell i: its ball arc (partial transport) or its geodesic."""
    from ._solve import BALL_ARC

    a, b = cell[k], cell[(k + 1) % len(cell)]
    if result.cell_neighbors[result.cell_offsets[i] + k] == BALL_ARC:
        return _arc_samples(_site_native(result, i), a, b, count, result.geometry)
    if result.geometry == "plane":
        return np.vstack((a, b))
    return _geodesic_samples(a, b, count, result.geometry)


def _mollweide_xy(longitude, latitude):
    """Mollweide (equal-area) projection of longitudes and latitudes in radians: x in
    [−2√2, 2√2] and y in [−√2, √2] for longitudes in [−π, π] (larger longitudes go beyond)."""
    theta = np.array(latitude, dtype=float)
    target = np.pi * np.sin(latitude)
    for _ in range(50):
        f = 2 * theta + np.sin(2 * theta) - target
        df = 2 + 2 * np.cos(2 * theta)
        step = np.where(np.abs(df) > 1e-12, f / np.where(df == 0, 1, df), 0)
        theta -= step
        if np.all(np.abs(step) < 1e-12):
            break
    return np.column_stack((2 * np.sqrt(2) / np.pi * longitude * np.cos(theta), np.sqrt(2) * np.sin(theta)))


def _mollweide(points):
    """Mollweide projection of unit vectors, and their longitudes."""
    longitude = np.arctan2(points[:, 1], points[:, 0])
    latitude = np.arcsin(np.clip(points[:, 2], -1, 1))
    return _mollweide_xy(longitude, latitude), longitude


def _sphere_fill(curve):
    """A cell's outline as projected polygons: longitudes unwrapped along the outline, a cell
    around a pole closed along that pole's edge of the map, and copies shifted by ±2π for a cell
    that crosses the ±180° meridian (the caller clips them to the map's ellipse)."""
    longitude = np.unwrap(np.arctan2(curve[:, 1], curve[:, 0]))
    latitude = np.arcsin(np.clip(curve[:, 2], -1, 1))
    winding = np.unwrap(np.r_[longitude, np.arctan2(curve[0, 1], curve[0, 0])])[-1] - longitude[0]
    if abs(winding) > np.pi:  # the cell contains a pole
        pole = np.pi / 2 if curve[:, 2].mean() > 0 else -np.pi / 2
        end = longitude[0] + winding
        longitude = np.r_[longitude, end, end, longitude[0]]
        latitude = np.r_[latitude, latitude[0], pole, pole]
    polygons = []
    for shift in (-2 * np.pi, 0.0, 2 * np.pi):
        shifted = longitude + shift
        if shifted.max() > -np.pi and shifted.min() < np.pi:
            polygons.append(_mollweide_xy(shifted, latitude))
    return polygons


def _curved_cells(result, samples_per_edge):
    """Each cell's boundary sampled along its edges: geodesics, and the balls' arcs of partial transport."""
    curves = []
    for i, cell in enumerate(result.cells):
        if len(cell) < 3:
            curves.append(None)
            continue
        pieces = [_edge_samples(result, i, cell, k, samples_per_edge)[:-1] for k in range(len(cell))]
        curves.append(np.vstack(pieces))
    return curves


def _wrapped_cells(result):
    """A periodic plane's cells where they show in the box: each moved by the periods that make
    it overlap the box (drawn clipped to it). Returns the cell index of each polygon and the polygons."""
    x0, y0, x1, y1 = result.box
    period = np.array([x1 - x0, y1 - y0])
    steps = [(-1, 0, 1) if axis else (0,) for axis in result.periodic]
    keep, polygons = [], []
    for i, cell in enumerate(result.cells):
        if len(cell) < 3:
            continue
        low, high = cell.min(axis=0), cell.max(axis=0)
        for sx in steps[0]:
            for sy in steps[1]:
                shift = np.array([sx, sy]) * period
                if (low + shift < [x1, y1]).all() and (high + shift > [x0, y0]).all():
                    keep.append(i)
                    polygons.append(cell + shift)
    return keep, polygons


def _add_cells(ax, polygons, keep, colors, edgecolor, linewidth):
    """The non-empty cells `polygons` (cells `keep`), filled with their colours when given."""
    facecolors = colors[keep] if colors is not None else "none"
    ax.add_collection(PolyCollection(polygons, facecolors=facecolors, edgecolors=edgecolor, linewidths=linewidth))


def cells(result, ax=None, color_by=None, cmap="viridis", sites=True, centroids=False, edgecolor="#3060a0",
          linewidth=None, samples_per_edge=12):
    """Draws the Laguerre cells of a `SolveResult` and returns the axes.

    Plane: the cells in the plane (periodic: wrapped into the box). Sphere: the Mollweide (equal-area) projection, edges cut at
    the ±180° meridian. H²: the Poincaré disk, edges drawn as geodesic arcs.

    color_by : None (outlines only), "mass", "weight", "target_mass", "error" (relative mass
        error) or an array of one value per cell.
    sites, centroids : also draw the sites (red) and the cells' centroids (green).
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 4.5) if result.geometry == "sphere" else (6, 6))
    n = len(result.weights)
    if linewidth is None:
        linewidth = float(np.clip(3.0 / np.sqrt(max(n, 1)), 0.2, 1.0))
    colors = _colors(result, color_by, cmap)
    dot = float(np.clip(400.0 / max(n, 1), 0.5, 20.0))

    if result.geometry in ("plane", "torus") and getattr(result, "periodic", None) is not None:
        keep, polygons = _wrapped_cells(result)
        _add_cells(ax, polygons, keep, colors, edgecolor, linewidth)
        x0, y0, x1, y1 = result.box
        ax.collections[-1].set_clip_path(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, transform=ax.transData))
        ax.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, color="black", linewidth=1.0))
        period = np.array([x1 - x0, y1 - y0])
        site_xy = np.array([x0, y0]) + np.mod(result.sites - np.array([x0, y0]), period)
        centroid_xy = result.centroids
    elif result.geometry == "plane":
        keep = [i for i, c in enumerate(result.cells) if len(c) >= 3]
        _add_cells(ax, [c for c in _curved_cells(result, samples_per_edge) if c is not None], keep, colors, edgecolor,
                   linewidth)
        site_xy, centroid_xy = result.sites, result.centroids
    elif result.geometry == "hyperbolic":
        disk = plt.Circle((0, 0), 1, fill=False, color="black", linewidth=1.0)
        ax.add_patch(disk)
        polygons, keep = [], []
        for i, curve in enumerate(_curved_cells(result, samples_per_edge)):
            if curve is not None:
                polygons.append(curve[:, :2] / (1 + curve[:, 2:3]))
                keep.append(i)
        _add_cells(ax, polygons, keep, colors, edgecolor, linewidth)
        site_xy, centroid_xy = _sites_in_poincare(result), result.centroids_poincare
    else:
        outline = np.linspace(0, 2 * np.pi, 200)
        ax.plot(2 * np.sqrt(2) * np.cos(outline), np.sqrt(2) * np.sin(outline), color="black", linewidth=1.0)
        segments, fills, fill_colors = [], [], []
        for i, curve in enumerate(_curved_cells(result, samples_per_edge)):
            if curve is None:
                continue
            xy, longitude = _mollweide(np.vstack((curve, curve[:1])))
            start = 0
            for cut in np.flatnonzero(np.abs(np.diff(longitude)) > np.pi):
                segments.append(xy[start : cut + 1])
                start = cut + 1
            segments.append(xy[start:])
            if colors is not None:
                for polygon in _sphere_fill(curve):
                    fills.append(polygon)
                    fill_colors.append(colors[i])
        if fills:
            ellipse = plt.Polygon(np.column_stack((2 * np.sqrt(2) * np.cos(outline), np.sqrt(2) * np.sin(outline))),
                                  transform=ax.transData, visible=False)
            ax.add_patch(ellipse)
            collection = PolyCollection(fills, facecolors=fill_colors, edgecolors="none")
            ax.add_collection(collection)
            collection.set_clip_path(ellipse)
        ax.add_collection(LineCollection(segments, colors=edgecolor, linewidths=linewidth))
        site_xy = _mollweide(result.sites / np.linalg.norm(result.sites, axis=1, keepdims=True))[0]
        centroid_xy = _mollweide(result.centroids / np.linalg.norm(result.centroids, axis=1, keepdims=True))[0]
    if centroids:
        ax.scatter(centroid_xy[:, 0], centroid_xy[:, 1], s=dot * 0.6, color="#20a040", zorder=3, linewidths=0)
    if sites:
        ax.scatter(site_xy[:, 0], site_xy[:, 1], s=dot, color="#d03020", zorder=4, linewidths=0)
    ax.set_aspect("equal")
    ax.autoscale_view()
    if result.geometry not in ("plane", "torus"):
        ax.set_axis_off()
    return ax


def _sites_in_poincare(result):
    """H² sites (given in `result.model`'s coordinates) in the Poincaré disk."""
    sites = result.sites
    if result.model == "hyperboloid":
        return sites[:, :2] / (1 + sites[:, 2:3])
    if result.model == "klein":
        return sites / (1 + np.sqrt(1 - np.sum(sites**2, axis=1, keepdims=True)))
    return sites


def distortion_histogram(report, ax=None, bins=80):
    """Histogram of the per-face area distortion d = log(spherical area share / mesh area
    share) of the initial and final maps, from the report of `sdot.sphere_parameterization`."""
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 4))
    distortion = report.get("area_distortion")
    if distortion is None:
        raise ValueError("report: has no 'area_distortion' (it comes from sdot.sphere_parameterization)")
    initial = np.asarray(distortion["initial"], dtype=float)
    final = np.asarray(distortion["final"], dtype=float)
    initial, final = initial[np.isfinite(initial)], final[np.isfinite(final)]
    both = np.concatenate((initial, final)) if initial.size else final
    low, high = (float(both.min()), float(both.max())) if both.size else (-1.0, 1.0)
    edges = np.linspace(low, high if high > low else low + 1, bins + 1)
    if initial.size:
        ax.hist(initial, bins=edges, alpha=0.6, color="#d08030", label=f"initial map (mean |d| {np.abs(initial).mean():.3f})")
    ax.hist(final, bins=edges, alpha=0.7, color="#3060a0", label=f"final map (mean |d| {np.abs(final).mean():.3f})")
    ax.set_xlabel("d = log(area share on the sphere / area share on the mesh)")
    ax.set_ylabel("faces")
    ax.legend()
    return ax
