"""The pictures of docs/gallery.md, made with the public API of the `sdot` Python package.

Every picture has its own function below, which doubles as example code: an image density on
the plane, a domain with holes, a longitude–latitude density on the sphere, the hyperbolic plane
in the Poincaré disk, a spherical parameterization, and the convergence rates printed by the
cross-geometry tests. Inputs are generated with fixed seeds, so every run draws the same pictures.

Run from the repository root with the package importable (scripts/gallery.sh does this):

    PYTHONPATH=build/python MPLBACKEND=Agg /usr/bin/python3 scripts/gallery.py [--build build]
        [--out docs/images/gallery] [--mesh FILE.off | --mesh generated] [NAME ...]

NAME: one or more of image, holes, sphere, hyperbolic, parameterization, convergence (default all).
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import Normalize  # noqa: E402
from matplotlib.patches import PathPatch  # noqa: E402
from matplotlib.path import Path  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

import sdot  # noqa: E402
import sdot.plot  # noqa: E402

DPI = 90
SHARED_MESH = "/work/shared/meshes/spot.off"


def save(fig, out, name):
    """Writes `fig` as out/name (PNG without a timestamp, so reruns give the same file)."""
    path = os.path.join(out, name)
    fig.savefig(path, dpi=DPI, bbox_inches="tight", metadata={"Software": None})
    plt.close(fig)
    print(f"  {path}: {os.path.getsize(path) / 1024:.0f} KB")


def colorbar(fig, ax, values, cmap, label):
    """A colour bar for cells drawn by sdot.plot.cells(color_by=values): it scales the values
    linearly from their minimum to their maximum."""
    mappable = plt.cm.ScalarMappable(norm=Normalize(np.min(values), np.max(values)), cmap=cmap)
    fig.colorbar(mappable, ax=ax, shrink=0.8, label=label)


def polygon_areas(cells):
    """Areas of plane polygons (k, 2) by the shoelace formula (0 for an empty cell)."""
    return np.array([0.5 * abs(np.dot(c[:, 0], np.roll(c[:, 1], -1)) - np.dot(c[:, 1], np.roll(c[:, 0], -1)))
                     if len(c) >= 3 else 0.0 for c in cells])


def spherical_areas(cells):
    """Areas of spherical polygons (k, 3) with geodesic edges: a fan of triangles from the first
    vertex, each by the Van Oosterom–Strackee formula."""
    areas = []
    for c in cells:
        if len(c) < 3:
            areas.append(0.0)
            continue
        a, b, d = c[0], c[1:-1], c[2:]
        det = np.einsum("ij,ij->i", np.cross(b, d), np.broadcast_to(a, b.shape))
        den = 1 + b @ a + d @ a + np.einsum("ij,ij->i", b, d)
        areas.append(float(np.sum(2 * np.arctan2(det, den))))
    return np.abs(np.array(areas))


# --- 1. an image density on the plane ------------------------------------------------------------

def synthetic_image(size=160):
    """A grayscale picture made with numpy: four Gaussian blobs and a ring on a dim background
    (row 0 is the top of the picture, as in an image file)."""
    row, col = np.mgrid[0:size, 0:size] / (size - 1)
    x, y = col, 1 - row
    image = np.full((size, size), 0.05)
    for (cx, cy), sigma, height in [((0.3, 0.7), 0.12, 1.0), ((0.7, 0.35), 0.08, 1.5),
                                    ((0.68, 0.76), 0.05, 0.8), ((0.25, 0.25), 0.1, 0.6)]:
        image += height * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * sigma**2))
    image += 0.5 * np.exp(-((np.hypot(x - 0.5, y - 0.5) - 0.44) / 0.03) ** 2)
    return image


def image_density(out):
    """Laguerre cells of equal mass for an image density on the unit square, after a few Lloyd
    steps (sites moved to their cells' centroids), next to the image."""
    image = synthetic_image()
    sites = np.random.default_rng(1).random((600, 2))
    for _ in range(10):  # Lloyd steps, each solve to a loose tolerance
        result = sdot.solve(sites, density=image, rescale_masses=True, tolerance=1e-6)
        sites = result.centroids
    result = sdot.solve(sites, density=image, rescale_masses=True)  # final diagram, to 1e-9
    print(f"  image: {result}")

    fig, axes = plt.subplots(1, 2, figsize=(11.5, 5))
    shown = axes[0].imshow(image, extent=(0, 1, 0, 1), cmap="gray_r")
    fig.colorbar(shown, ax=axes[0], shrink=0.8, label="density (pixel value)")
    axes[0].set_title("density: a 160 × 160 pixel array")
    log_area = np.log10(polygon_areas(result.cells))
    sdot.plot.cells(result, ax=axes[1], color_by=log_area, cmap="magma", edgecolor="#202020", sites=False)
    axes[1].scatter(sites[:, 0], sites[:, 1], s=2, color="#30c0ff", linewidths=0)  # the sites
    colorbar(fig, axes[1], log_area, "magma", "log10(cell area)")
    axes[1].set_title(f"{len(sites)} cells of equal mass (after 10 Lloyd steps)")
    for ax in axes:
        ax.set(xlim=(0, 1), ylim=(0, 1), xlabel="x", ylabel="y")
        ax.set_aspect("equal")
    save(fig, out, "plane_image_density.png")


# --- 2. a domain with holes ----------------------------------------------------------------------

def region_path(outer, holes):
    """A matplotlib path of a polygon with holes (outer ring counter-clockwise, holes clockwise)."""
    def ring(points, counter_clockwise):
        points = np.asarray(points, dtype=float)
        signed = np.dot(points[:, 0], np.roll(points[:, 1], -1)) - np.dot(points[:, 1], np.roll(points[:, 0], -1))
        if (signed > 0) != counter_clockwise:
            points = points[::-1]
        return Path(np.vstack((points, points[:1])), closed=True)

    return Path.make_compound_path(ring(outer, True), *[ring(h, False) for h in holes])


def holed_domain(out):
    """Uniform density on a non-convex polygon with three polygonal holes; masses grow from left
    to right; the sites are random in the bounding box, so some lie in the holes or outside."""
    outer = np.array([[0, 0], [4, 0], [4, 3], [2.6, 3], [2, 2.3], [1.4, 3], [0, 3]], dtype=float)
    holes = [np.array([[0.6, 0.6], [1.4, 0.5], [1.5, 1.3], [0.7, 1.4]]),
             np.array([[2.4, 0.5], [3.5, 0.9], [2.8, 1.6]]),
             [3.3, 2.2] + 0.4 * np.column_stack((np.cos(np.arange(6) * np.pi / 3), np.sin(np.arange(6) * np.pi / 3)))]
    rng = np.random.default_rng(2)
    sites = rng.random((250, 2)) * [4, 3]
    masses = 1 + sites[:, 0] / 2  # 1 on the left edge, 3 on the right: rescaled to the area
    result = sdot.solve(sites, masses, domain={"outer": outer, "holes": holes}, rescale_masses=True)
    print(f"  holes: {result}; {result.message}")

    fig, ax = plt.subplots(figsize=(8.5, 6))
    sdot.plot.cells(result, ax=ax, color_by=masses, cmap="viridis", edgecolor="#202020", sites=False)
    path = region_path(outer, holes)
    region = PathPatch(path, facecolor="none", edgecolor="black", linewidth=1.5, zorder=5)
    ax.add_patch(region)
    # result.cells are the Laguerre cells of the region's bounding box: show their part in the region.
    ax.collections[0].set_clip_path(region)
    for hole in holes:
        ax.fill(hole[:, 0], hole[:, 1], facecolor="#e4e4e4", linewidth=0)
    inside = Path(outer).contains_points(sites)  # contains_points ignores holes: test them one by one
    for hole in holes:
        inside &= ~Path(hole).contains_points(sites)
    ax.scatter(*sites[inside].T, s=4, color="#d03020", linewidths=0, zorder=6, label="sites")
    ax.scatter(*sites[~inside].T, s=30, marker="x", color="#d03020", zorder=6, label="sites outside the region")
    ax.legend(loc="upper left", bbox_to_anchor=(0, -0.08), ncol=2, frameon=False, markerscale=1.5)
    colorbar(fig, ax, masses, "viridis", "target mass (before rescaling)")
    ax.set(xlim=(-0.1, 4.1), ylim=(-0.1, 3.1), xlabel="x", ylabel="y",
           title=f"{len(sites)} cells on a polygon with 3 holes (grey)")
    ax.set_aspect("equal")
    save(fig, out, "plane_holed_domain.png")


# --- 3. a longitude–latitude density on the sphere -----------------------------------------------

def lonlat_density(rows=90):
    """An equirectangular map (rows × 2·rows pixels; column 0 at longitude −180°, row 0 at
    latitude +90°): a band along the equator modulated in longitude, and a spot at 60° N, 100° W."""
    lat = np.radians(90 - (np.arange(rows) + 0.5) * 180 / rows)[:, None]
    lon = np.radians(-180 + (np.arange(2 * rows) + 0.5) * 180 / rows)[None, :]
    band = (1 + np.sin(3 * lon)) * np.exp(-(np.degrees(lat) / 25) ** 2)
    spot_center = np.radians([-100, 60])
    cos_distance = (np.sin(lat) * np.sin(spot_center[1])
                    + np.cos(lat) * np.cos(spot_center[1]) * np.cos(lon - spot_center[0]))
    spot = 3 * np.exp(-(np.arccos(np.clip(cos_distance, -1, 1)) / 0.25) ** 2)
    return 0.15 + band + spot, lon[0], lat[:, 0]


def sphere_lonlat(out):
    """Equal-mass cells on the sphere for a longitude–latitude density, in the Mollweide
    (equal-area) projection of sdot.plot, next to the density in the same projection."""
    density, lon, lat = lonlat_density()
    x = np.random.default_rng(3).normal(size=(800, 3))
    sites = x / np.linalg.norm(x, axis=1, keepdims=True)
    for _ in range(5):  # Lloyd steps on the sphere: centroids projected back to the sphere
        result = sdot.solve(sites, geometry="sphere", density=density, rescale_masses=True, tolerance=1e-6)
        sites = result.centroids / np.linalg.norm(result.centroids, axis=1, keepdims=True)
    result = sdot.solve(sites, geometry="sphere", density=density, rescale_masses=True)
    print(f"  sphere: {result}")

    fig = plt.figure(figsize=(13, 4.4))
    left = fig.add_subplot(1, 2, 1, projection="mollweide")
    shown = left.pcolormesh(lon, lat, density, cmap="gray_r", shading="nearest", rasterized=True)
    left.set_xticklabels([])
    left.set_yticklabels([])
    left.grid(True, linewidth=0.3)
    fig.colorbar(shown, ax=left, orientation="horizontal", shrink=0.6, pad=0.05, label="density (pixel value)")
    left.set_title("density: a 90 × 180 longitude–latitude array")
    right = fig.add_subplot(1, 2, 2)
    log_area = np.log10(spherical_areas(result.cells))
    sdot.plot.cells(result, ax=right, color_by=log_area, cmap="magma", edgecolor="#202020")
    mappable = plt.cm.ScalarMappable(norm=Normalize(log_area.min(), log_area.max()), cmap="magma")
    fig.colorbar(mappable, ax=right, orientation="horizontal", shrink=0.6, pad=0.05, label="log10(cell area, sr)")
    right.set(xlim=(-2.85, 2.85), ylim=(-1.43, 1.43))  # the map's ellipse, |x| ≤ 2√2, |y| ≤ √2
    right.set_title(f"{len(sites)} cells of equal mass (after 5 Lloyd steps)")
    save(fig, out, "sphere_lonlat_density.png")


# --- 4. the hyperbolic plane in the Poincaré disk ------------------------------------------------

def hyperbolic_uniform(count, radius, rng):
    """Points uniform in hyperbolic area in the disk of hyperbolic radius `radius` about the
    origin, in Poincaré coordinates (area ∝ cosh r − 1 inside radius r)."""
    r = np.arccosh(1 + rng.random(count) * (np.cosh(radius) - 1))
    theta = rng.random(count) * 2 * np.pi
    return np.tanh(r / 2)[:, None] * np.column_stack((np.cos(theta), np.sin(theta)))


def hyperbolic_disk(out):
    """Equal-area (hyperbolic) cells on a regular octagon of circumradius 2.6, after Lloyd steps,
    in the Poincaré disk."""
    radius, sides = 2.6, 8
    angles = (np.arange(sides) + 0.5) * 2 * np.pi / sides
    octagon = np.tanh(radius / 2) * np.column_stack((np.cos(angles), np.sin(angles)))  # Poincaré
    rng = np.random.default_rng(4)
    sites = hyperbolic_uniform(3000, radius, rng)
    klein = 2 * sites / (1 + np.sum(sites**2, axis=1, keepdims=True))  # the domain is straight in Klein
    octagon_klein = 2 * octagon / (1 + np.sum(octagon**2, axis=1, keepdims=True))
    inside = np.ones(len(klein), dtype=bool)
    for a, b in zip(octagon_klein, np.roll(octagon_klein, -1, axis=0)):
        inside &= (b[0] - a[0]) * (klein[:, 1] - a[1]) - (b[1] - a[1]) * (klein[:, 0] - a[0]) > 0
    sites = sites[inside][:400]
    for _ in range(8):  # Lloyd steps: the centroids in the Poincaré disk are the next sites
        result = sdot.solve(sites, geometry="hyperbolic", domain=octagon, tolerance=1e-6)
        sites = result.centroids_poincare
    result = sdot.solve(sites, geometry="hyperbolic", domain=octagon)
    print(f"  hyperbolic: {result}")

    distance = 2 * np.arctanh(np.linalg.norm(result.centroids_poincare, axis=1))
    fig, ax = plt.subplots(figsize=(7, 6))
    sdot.plot.cells(result, ax=ax, color_by=distance, cmap="viridis", edgecolor="#202020")
    colorbar(fig, ax, distance, "viridis", "hyperbolic distance of the centroid from the centre")
    ax.set_title(f"H²: {len(sites)} cells of equal hyperbolic area, Poincaré disk")
    ax.set(xlim=(-1.02, 1.02), ylim=(-1.02, 1.02))
    save(fig, out, "hyperbolic_poincare.png")


# --- 5. spherical parameterization of a mesh -----------------------------------------------------

def bumpy_sphere(subdivisions=4):
    """A closed genus-0 mesh: an icosphere subdivided `subdivisions` times, stretched into an
    ellipsoid and given a few bumps (fixed, no randomness)."""
    t = (1 + 5**0.5) / 2
    vertices = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
                [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    faces = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
             [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
             [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    vertices = [np.array(v, dtype=float) / np.linalg.norm(v) for v in vertices]
    for _ in range(subdivisions):
        midpoint, refined = {}, []

        def middle(i, j):
            key = (min(i, j), max(i, j))
            if key not in midpoint:
                m = vertices[i] + vertices[j]
                vertices.append(m / np.linalg.norm(m))
                midpoint[key] = len(vertices) - 1
            return midpoint[key]

        for a, b, c in faces:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            refined += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        faces = refined
    v = np.array(vertices)
    bumps = 1 + 0.35 * np.exp(-8 * (1 - v @ [0, 0, 1.0])) + 0.25 * np.exp(-10 * (1 - v @ [0.8, 0.6, 0]))
    return v * bumps[:, None] * [1.6, 1.0, 0.8], np.array(faces)


def draw_mesh(ax, vertices, faces, colors, title, azimuth, elevation=15):
    """A triangle mesh with matplotlib's 3-D axes (the mesh's y axis up, as in most mesh files),
    lit from the viewer, equal aspect, no axes."""
    points = vertices[:, [0, 2, 1]] * [1, -1, 1]  # (x, y, z) -> (x, -z, y): a rotation, y up
    a, e = np.radians(azimuth), np.radians(elevation)
    eye = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    normal = np.cross(points[faces[:, 1]] - points[faces[:, 0]], points[faces[:, 2]] - points[faces[:, 0]])
    lambert = np.abs(normal @ eye) / np.linalg.norm(normal, axis=1)
    lit = colors.copy()
    lit[:, :3] *= (0.5 + 0.5 * lambert)[:, None]  # Lambert shading, so the shape reads in a flat picture
    # Without antialiasing the seams between faces vanish, and the PNG file is 2–3× smaller.
    ax.add_collection3d(Poly3DCollection(points[faces], facecolors=lit, edgecolors=lit, linewidths=0.1,
                                         antialiased=False))
    low, high = points.min(axis=0), points.max(axis=0)
    center, half = (low + high) / 2, (high - low).max() / 2
    ax.set(xlim=(center[0] - half, center[0] + half), ylim=(center[1] - half, center[1] + half),
           zlim=(center[2] - half, center[2] + half))
    ax.set_box_aspect((1, 1, 1), zoom=1.35)
    ax.view_init(elev=elevation, azim=azimuth)
    ax.set_axis_off()
    ax.set_title(title)


def parameterization(out, mesh_path, build):
    """A closed genus-0 mesh, its area-preserving map onto the sphere by `sdot-sphere-param`, and
    the histogram of the per-face area distortion of the initial (Tutte) and final maps."""
    with tempfile.TemporaryDirectory() as scratch:
        if mesh_path is None:
            mesh_path = os.path.join(scratch, "bumpy_sphere.off")
            sdot.write_mesh(mesh_path, *bumpy_sphere())
        vertices, faces = sdot.read_mesh(mesh_path)
        sphere_path, report_path = os.path.join(scratch, "sphere.off"), os.path.join(scratch, "report.json")
        subprocess.run([os.path.join(build, "bin", "sdot-sphere-param"), mesh_path, "-o", sphere_path,
                        "--report", report_path, "--quiet"], check=True)
        sphere, _ = sdot.read_mesh(sphere_path)  # same vertices and faces, in the same order
        with open(report_path) as file:
            final = json.load(file)["final_map"]
    # The command's report holds summary figures only; the Python function runs the same library
    # code and also returns the per-face distortion of both maps, which the histogram needs.
    python_sphere, report = sdot.sphere_parameterization(vertices, faces)
    name = os.path.splitext(os.path.basename(mesh_path))[0]
    print(f"  parameterization of {name}: {len(vertices)} vertices, area mean|d| {final['area_mean_abs']:.4f}, "
          f"flips {final['flips']}; sdot.sphere_parameterization differs from the command by "
          f"{np.abs(python_sphere - sphere).max():.1e}")

    # Colour the mesh in patches around 10 far-apart points (farthest-point sampling, from the
    # highest point): the same colours on the sphere show where each part of the mesh went.
    centers = vertices[faces].mean(axis=1)
    seeds = [int(np.argmax(centers[:, 1]))]
    distance = np.linalg.norm(centers - centers[seeds[0]], axis=1)
    for _ in range(9):
        seeds.append(int(np.argmax(distance)))
        distance = np.minimum(distance, np.linalg.norm(centers - centers[seeds[-1]], axis=1))
    patch = np.argmin(np.linalg.norm(centers[:, None, :] - centers[seeds][None, :, :], axis=2), axis=1)
    colors = plt.get_cmap("tab10")(patch)

    fig = plt.figure(figsize=(13, 7))
    views = [(vertices, f"{name}: {len(vertices)} vertices, {len(faces)} faces", -60, (0, 0.5)),
             (vertices, "the other side", 120, (0.25, 0.5)),
             (sphere, "its map to the sphere", -60, (0, 0)),
             (sphere, f"the other side ({final['flips']} flipped faces)", 120, (0.25, 0))]
    for surface, title, azimuth, (left, bottom) in views:
        draw_mesh(fig.add_axes((left, bottom, 0.25, 0.47), projection="3d"), surface, faces, colors, title, azimuth)
    ax = sdot.plot.distortion_histogram(report, ax=fig.add_axes((0.58, 0.25, 0.41, 0.5)), bins=60)
    ax.set_yscale("log")
    ax.set_title("per-face area distortion d")
    save(fig, out, "sphere_parameterization.png")


# --- 6. convergence figures printed by the cross-geometry tests ----------------------------------

def run_cross_geometry_test(build):
    """Runs the cross-geometry tests whose figures are plotted and returns what they print."""
    binary = os.path.join(build, "bin", "cross_geometry_test")
    tests = "SmallRegionLimit.*:Refinement.*:CrossGeometry/*.NewtonConvergesQuadratically"
    return subprocess.run([binary, f"--gtest_filter={tests}"], check=True, capture_output=True, text=True).stdout


def parse_cross_geometry(text):
    """The tables the tests print, as lists of rows (the first number of each '|'-separated
    column, NaN where there is none), and the rates they fit:
    {"small": {density: rows (ε, e_S², e_H², e_avg)}, "small_rates": {density: {"sphere": rate, ...}},
     "refinement": {geometry: rows (N, cost, rate)}, "refinement_rate": {geometry: rate},
     "newton": {geometry: rows (k, e_k, step, e_{k+1}/e_k²)}}."""
    tables = {"small": {}, "small_rates": {}, "refinement": {}, "refinement_rate": {}, "newton": {}}
    current = key = None
    for line in text.splitlines():
        if m := re.match(r"\s*small-region limit, (.+?) \(", line):
            key, current = m.group(1), tables["small"].setdefault(m.group(1), [])
        elif m := re.match(r"\s*(plane|sphere): N sites sampled", line):
            key, current = m.group(1), tables["refinement"].setdefault(m.group(1), [])
        elif m := re.match(r"\s*(plane|sphere|hyperbolic), N = \d+: iteration", line):
            key, current = m.group(1), tables["newton"].setdefault(m.group(1), [])
        elif m := re.match(r"\s*observed rates: (.*)", line):
            pairs = re.findall(r"(\w+) ([-\d.]+)", m.group(1))  # "sphere 1.929, hyperbolic 2.087, average 4.017"
            tables["small_rates"][key] = {name: float(value) for name, value in pairs}
        elif m := re.match(r"\s*observed rate \(cost ~ N\^-rate\): ([-\d.]+)", line):
            tables["refinement_rate"][key] = float(m.group(1))
        elif current is not None and re.match(r"\s*\d", line) and "|" in line:
            current.append([float(field.split()[0]) if field.split() else float("nan") for field in line.split("|")])
        elif line.startswith("["):  # gtest's own lines end a table
            current = None
    return tables


COLORS = {"plane": "#20a040", "sphere": "#d03020", "hyperbolic": "#3060a0", "average": "#8040a0"}


def convergence(out, build):
    """Log–log plots of the small-region limit (error against ε, reference slopes 2 and 4), the
    transport cost against N (slope −1), and Newton's max relative mass error per iteration."""
    tables = parse_cross_geometry(run_cross_geometry_test(build))
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))

    ax = axes[0]
    for density, style in [("uniform density", "-"), ("smooth non-uniform density", "--")]:
        rows, rates = np.array(tables["small"][density]), tables["small_rates"][density]
        for column, geometry, label in [(1, "sphere", "S²"), (2, "hyperbolic", "H²"),
                                        (3, "average", "(S² + H²)/2")]:
            ax.loglog(rows[:, 0], rows[:, column], style, marker="o", markersize=4, color=COLORS[geometry],
                      label=f"{label}, {density.split()[0]}: rate {rates[geometry]:.2f}")
    eps = np.array([0.025, 0.4])
    ax.loglog(eps, 0.5 * eps**2, color="gray", linewidth=0.8)
    ax.loglog(eps, 0.06 * eps**4, color="gray", linewidth=0.8)
    ax.text(0.1, 0.5 * 0.1**2 * 1.5, "slope 2", color="gray", ha="right", va="bottom")
    ax.text(0.1, 0.06 * 0.1**4 / 1.5, "slope 4", color="gray", ha="left", va="top")
    ax.set_xticks(rows[:, 0], [f"{e:g}" for e in rows[:, 0]])
    ax.minorticks_off()
    ax.set(xlabel="ε (size of the region)", ylabel="max |h/ε² − ψ| (against the plane's ψ)",
           title="small-region limit (N = 12)")
    ax.legend(fontsize=7.5, loc="lower right")

    ax = axes[1]
    for geometry in ("plane", "sphere"):
        rows = np.array(tables["refinement"][geometry])
        ax.loglog(rows[:, 0], rows[:, 1], marker="o", color=COLORS[geometry],
                  label=f"{geometry}: rate {tables['refinement_rate'][geometry]:.2f}")
    n = np.array([250, 16000])
    ax.loglog(n, 0.6 * 250 / n, color="gray", linewidth=0.8)
    ax.text(2000, 0.6 * 250 / 2000 * 1.3, "slope −1", color="gray")
    ax.set_xticks(rows[:, 0], [f"{n:g}" for n in rows[:, 0]])
    ax.minorticks_off()
    ax.set(xlabel="N (sites sampled from the source, equal masses)", ylabel="transport cost",
           title="refinement: transport cost against N")
    ax.legend()

    ax = axes[2]
    for geometry in ("plane", "sphere", "hyperbolic"):
        rows = np.array(tables["newton"][geometry])
        ax.semilogy(rows[:, 0], rows[:, 1], marker="o", markersize=4, color=COLORS[geometry], label=geometry)
    ax.axhline(1e-13, color="gray", linewidth=0.8, linestyle=":")
    ax.text(0, 0.7e-13, "tolerance 1e-13", color="gray", ha="left", va="top")
    ax.set(xlabel="Newton iteration k", ylabel="max relative mass error e_k", title="Newton's method (N = 400)")
    ax.legend()
    fig.tight_layout()
    save(fig, out, "cross_geometry_convergence.png")


PICTURES = ["image", "holes", "sphere", "hyperbolic", "parameterization", "convergence"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--build", default="build",
                        help="build directory (bin/sdot-sphere-param, bin/cross_geometry_test)")
    parser.add_argument("--out", default=os.path.join("docs", "images", "gallery"))
    parser.add_argument("--mesh", help=f"mesh to parameterize, or 'generated' for a generated one "
                        f"(default {SHARED_MESH} if it exists, else a generated one)")
    parser.add_argument("names", nargs="*", metavar="NAME",
                        help=f"pictures to make: {', '.join(PICTURES)} (default all)")
    args = parser.parse_args()
    unknown = set(args.names) - set(PICTURES)
    if unknown:
        parser.error(f"unknown picture {sorted(unknown)[0]!r}; choose from {', '.join(PICTURES)}")
    os.makedirs(args.out, exist_ok=True)
    mesh = args.mesh or (SHARED_MESH if os.path.exists(SHARED_MESH) else "generated")
    mesh = None if mesh == "generated" else mesh
    make = {
        "image": lambda: image_density(args.out),
        "holes": lambda: holed_domain(args.out),
        "sphere": lambda: sphere_lonlat(args.out),
        "hyperbolic": lambda: hyperbolic_disk(args.out),
        "parameterization": lambda: parameterization(args.out, mesh, args.build),
        "convergence": lambda: convergence(args.out, args.build),
    }
    for name in args.names or PICTURES:
        start = time.monotonic()
        print(f"{name}:")
        make[name]()
        print(f"  {time.monotonic() - start:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
