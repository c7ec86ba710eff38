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
