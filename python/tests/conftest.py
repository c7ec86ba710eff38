"""Shared fixtures: the sdot command (for the Python-against-command tests) and small problems."""

import os
import shutil
import subprocess

import numpy as np
import pytest


@pytest.fixture(scope="session")
def sdot_command():
    """Path of the sdot command: $SDOT_COMMAND (set by ctest), else `sdot` on PATH."""
    path = os.environ.get("SDOT_COMMAND") or shutil.which("sdot")
    if not path or not os.path.exists(path):
        pytest.skip("the sdot command is not built (set SDOT_COMMAND)")
    return path


@pytest.fixture(scope="session")
def sphere_param_command(sdot_command):
    path = os.path.join(os.path.dirname(sdot_command), "sdot-sphere-param")
    if not os.path.exists(path):
        pytest.skip("sdot-sphere-param is not built")
    return path


def run(command, *args, check=True):
    return subprocess.run([command, *map(str, args)], capture_output=True, text=True, check=check)


def sphere_sites(n, seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 3))
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def icosphere(levels):
    """A unit icosahedron subdivided `levels` times (vertices on the sphere), outward oriented."""
    t = (1 + 5**0.5) / 2
    vertices = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
                (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    vertices = [np.array(v, float) / np.linalg.norm(v) for v in vertices]
    for _ in range(levels):
        midpoint, new_faces = {}, []

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in midpoint:
                m = vertices[a] + vertices[b]
                vertices.append(m / np.linalg.norm(m))
                midpoint[key] = len(vertices) - 1
            return midpoint[key]

        for a, b, c in faces:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            new_faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new_faces
    return np.array(vertices), np.array(faces, dtype=np.int64)


def bumpy_mesh(levels=3):
    """A genus-0 test surface with uneven areas: an icosphere pushed out into a lumpy,
    elongated shape (radius 1 + 0.35 sin(3x) cos(2y) + 0.25 z², stretched 2× along x)."""
    vertices, faces = icosphere(levels)
    x, y, z = vertices.T
    radius = 1 + 0.35 * np.sin(3 * x) * np.cos(2 * y) + 0.25 * z**2
    shaped = vertices * radius[:, None]
    shaped[:, 0] *= 2
    return shaped, faces
