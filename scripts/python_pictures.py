"""Makes the pictures of docs/python.md by running its examples (run from the repository root
with the package importable, e.g. PYTHONPATH=build/python /usr/bin/python3 scripts/python_pictures.py)."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import sdot  # noqa: E402
import sdot.plot  # noqa: E402

OUT = "docs/images"

# --- the plane example of docs/python.md
rng = np.random.default_rng(0)
sites = rng.random((300, 2)) ** 1.5                     # clustered towards a corner
masses = np.full(300, 1 / 300)                          # equal masses, summing to the area
result = sdot.solve(sites, masses, density=lambda x: 1 + 2 * x[:, 0], rescale_masses=True)
print(result)                                           # converged in a few Newton steps
ax = sdot.plot.cells(result, color_by="weight", centroids=True)
ax.figure.savefig(f"{OUT}/python_plane.png", dpi=80, bbox_inches="tight")

# --- sphere and H²
x = rng.normal(size=(400, 3))
sphere = sdot.solve(x / np.linalg.norm(x, axis=1, keepdims=True), geometry="sphere",
                    density=lambda p: 1 + p[:, 2] ** 2, rescale_masses=True)
hexagon = 0.85 * np.column_stack((np.cos(np.arange(6) * np.pi / 3), np.sin(np.arange(6) * np.pi / 3)))
h2 = sdot.solve(rng.uniform(-0.5, 0.5, (200, 2)), geometry="hyperbolic", domain=hexagon)
fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
sdot.plot.cells(sphere, ax=axes[0], color_by="mass")
sdot.plot.cells(h2, ax=axes[1], color_by="weight")
fig.savefig(f"{OUT}/python_sphere_h2.png", dpi=70, bbox_inches="tight")
print(sphere, h2, sep="\n")

# --- docs/index.md's first picture: what the weights, the cells and the masses mean
from matplotlib.collections import PolyCollection  # noqa: E402

rng = np.random.default_rng(3)
sites = rng.random((16, 2))
bump = lambda x: 0.2 + 3.0 * np.exp(-8 * ((x[:, 0] - 0.7) ** 2 + (x[:, 1] - 0.35) ** 2))  # noqa: E731
# all weights 0 and no Newton step: the Voronoi diagram, whose cells carry unequal masses
voronoi = sdot.solve(sites, density=bump, weights=np.zeros(16), max_iterations=0, rescale_masses=True)
transport = sdot.solve(sites, density=bump, rescale_masses=True)  # every cell carries 1/16
grid = np.linspace(0, 1, 200)
gx, gy = np.meshgrid(grid, grid)
rho = bump(np.column_stack((gx.ravel(), gy.ravel()))).reshape(gx.shape)
fig, axes = plt.subplots(1, 3, figsize=(12.5, 4.6), layout="constrained")
axes[0].imshow(rho, origin="lower", extent=(0, 1, 0, 1), cmap="Greys")
axes[0].plot(sites[:, 0], sites[:, 1], "o", color="#d03020")
axes[0].set_title("source density ρ (dark: dense)\nand 16 sites")
mass_norm = matplotlib.colors.Normalize(0, max(voronoi.masses.max(), transport.masses.max()))
for ax, result, title in ((axes[1], voronoi, "all weights 0 (Voronoi cells):\nthe masses differ"),
                          (axes[2], transport, "the solved weights (printed):\nevery cell's mass is 1/16")):
    cells = PolyCollection(result.cells, array=result.masses, cmap="viridis", norm=mass_norm,
                           edgecolor="white", linewidth=1.2)
    ax.add_collection(cells)
    ax.plot(result.sites[:, 0], result.sites[:, 1], "o", color="#d03020", markersize=4)
    for site, weight in zip(result.sites, result.weights if result is transport else []):
        ax.annotate(f"{weight:+.3f}", site, textcoords="offset points", xytext=(0, 5), ha="center", fontsize=7)
    ax.set_title(title)
fig.colorbar(cells, ax=axes[2], label="mass of the cell, ∫ρ over it")
for ax in axes:
    ax.set_xlim(0, 1), ax.set_ylim(0, 1), ax.set_aspect("equal"), ax.set_xticks([]), ax.set_yticks([])
fig.savefig(f"{OUT}/concepts.png", dpi=70, bbox_inches="tight")
print(f"Voronoi masses {voronoi.masses.min():.3f}–{voronoi.masses.max():.3f};", transport)

# --- partial transport (docs/partial.md): the same masses filling 30 % and 70 % of the source
fig, axes = plt.subplots(1, 4, figsize=(22, 5))
sites = np.random.default_rng(3).random((120, 2))
for ax, fraction in zip(axes[:2], (0.3, 0.7)):
    partial = sdot.solve(sites, np.full(120, fraction / 120), partial=True)
    sdot.plot.cells(partial, ax=ax, color_by="weight")
    ax.set_title(f"plane: {fraction:.0%} of the square")
    print(partial, f"ball radii {partial.ball_radii.min():.3f}–{partial.ball_radii.max():.3f}")
x = np.random.default_rng(4).normal(size=(300, 3))
partial = sdot.solve(x / np.linalg.norm(x, axis=1, keepdims=True), np.full(300, 0.5 * 4 * np.pi / 300),
                     geometry="sphere", partial=True)
sdot.plot.cells(partial, ax=axes[2], color_by="weight")
axes[2].set_title("sphere: half the area")
partial = sdot.solve(rng.uniform(-0.5, 0.5, (80, 2)), np.full(80, 0.6 * h2.source_mass / 80), geometry="hyperbolic",
                     domain=hexagon, partial=True)
sdot.plot.cells(partial, ax=axes[3], color_by="weight")
axes[3].set_title("H²: 60 % of the hexagon")
fig.savefig(f"{OUT}/partial.png", dpi=60, bbox_inches="tight")
print(partial)
