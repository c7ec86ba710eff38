"""scripts/loop_subdivide.py: the Loop subdivision that makes the brain-scale input of
sdot-sphere-param (docs/spherical_parameterization.md, "Brain scale")."""

import importlib.util
import pathlib
import subprocess
import sys

import numpy as np
import pytest

SCRIPT = pathlib.Path(__file__).resolve().parents[2] / "scripts" / "loop_subdivide.py"
_spec = importlib.util.spec_from_file_location("loop_subdivide", SCRIPT)
loop = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(loop)


def octahedron():
    vertices = np.array([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)], float)
    faces = np.array([(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)])
    return vertices, faces


def icosahedron():
    t = (1 + 5**0.5) / 2
    vertices = np.array([(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
                         (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)], float)
    faces = np.array([(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
                      (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5),
                      (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)])
    return vertices, faces


def edge_count(faces):
    sides = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return len(np.unique(sides, axis=0))


def signed_volume(vertices, faces):
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6


def assert_closed_oriented_manifold(faces, vertex_count):
    directed = {}
    for f in faces:
        for k in range(3):
            a, b = int(f[k]), int(f[(k + 1) % 3])
            assert a != b
            assert (a, b) not in directed, "an edge traversed twice in one direction"
            directed[(a, b)] = 1
    # every edge in exactly two faces, once in each direction
    assert all((b, a) in directed for a, b in directed)
    assert len(np.unique(faces)) == vertex_count  # no unreferenced vertex
    euler = vertex_count - len(directed) // 2 + len(faces)
    assert euler == 2


@pytest.mark.parametrize("make", [octahedron, icosahedron])
def test_counts_topology_and_orientation(make):
    vertices, faces = make()
    for level in range(3):
        new_vertices, new_faces = loop.loop_subdivide(vertices, faces)
        assert len(new_vertices) == len(vertices) + edge_count(faces)  # V' = V + E
        assert len(new_faces) == 4 * len(faces)  # F' = 4 F
        assert_closed_oriented_manifold(new_faces, len(new_vertices))
        assert signed_volume(new_vertices, new_faces) > 0  # still outward
        vertices, faces = new_vertices, new_faces
    assert len(vertices) == 2 + 4 ** 3 * (len(make()[0]) - 2)


def test_rules_on_the_octahedron():
    # valence 4: β = (5/8 − (3/8 + cos(π/2)/4)²)/4 = 31/256, and the four neighbours of ±e_i
    # sum to 0, so an old vertex moves to (1 − 4β) v = 33/64 v; the edge point of e_x e_y (opposite
    # corners ±e_z) is 3/8 (e_x + e_y).
    vertices, faces = octahedron()
    new_vertices, new_faces = loop.loop_subdivide(vertices, faces)
    assert np.allclose(new_vertices[:6], 33 / 64 * vertices, atol=1e-15)
    edge_points = new_vertices[6:]
    assert len(edge_points) == 12
    for p in edge_points:
        assert sorted(np.abs(p)) == pytest.approx([0, 3 / 8, 3 / 8], abs=1e-15)
    # the corner triangle (0, ab, ca) of face (e_x, e_y, e_z) has the expected new points
    ab, ca = new_faces[0, 1], new_faces[0, 2]
    assert new_faces[0, 0] == 0
    assert new_vertices[ab] == pytest.approx([3 / 8, 3 / 8, 0])
    assert new_vertices[ca] == pytest.approx([3 / 8, 0, 3 / 8])


def test_rules_on_an_irregular_mesh():
    # every old and new point against Loop's masks written out face by face
    vertices, faces = icosahedron()
    vertices = vertices + np.random.default_rng(3).normal(scale=0.1, size=vertices.shape)
    new_vertices, new_faces = loop.loop_subdivide(vertices, faces)
    for v in range(len(vertices)):
        neighbours = sorted({int(w) for f in faces if v in f for w in f if w != v})
        n = len(neighbours)
        beta = (5 / 8 - (3 / 8 + np.cos(2 * np.pi / n) / 4) ** 2) / n
        expected = (1 - n * beta) * vertices[v] + beta * vertices[neighbours].sum(axis=0)
        assert np.allclose(new_vertices[v], expected, atol=1e-14)
    for f, face in enumerate(faces):
        for k in range(3):
            a, b = face[k], face[(k + 1) % 3]
            c = face[(k + 2) % 3]
            (other,) = [g for g in faces if a in g and b in g and c not in g]
            (d,) = [w for w in other if w not in (a, b)]
            expected = 3 / 8 * (vertices[a] + vertices[b]) + 1 / 8 * (vertices[c] + vertices[d])
            # the new point of side k of face f: corner triangles (a, ab, ca), (ab, b, bc), (ca, bc, c)
            middle = new_faces[4 * f + 3]  # (ab, bc, ca)
            assert np.allclose(new_vertices[middle[k]], expected, atol=1e-14)


def test_command_round_trip_and_refusals(tmp_path):
    vertices, faces = icosahedron()
    source = tmp_path / "ico.off"
    loop.write_off(source, vertices, faces)
    target = tmp_path / "ico2.off"
    done = subprocess.run([sys.executable, str(SCRIPT), str(source), str(target), "--levels", "2"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    read_vertices, read_faces = loop.read_off(target)
    expected_vertices, expected_faces = loop.loop_subdivide(*loop.loop_subdivide(vertices, faces))
    assert np.array_equal(read_vertices, expected_vertices)  # coordinates round-trip exactly
    assert np.array_equal(read_faces, expected_faces)
    assert (len(read_vertices), len(read_faces)) == (162, 320)
    # an open mesh (one face removed) and an inconsistently oriented one are refused
    loop.write_off(source, vertices, faces[1:])
    done = subprocess.run([sys.executable, str(SCRIPT), str(source), str(target)], capture_output=True, text=True)
    assert done.returncode == 2 and "boundary" in done.stderr
    flipped = faces.copy()
    flipped[0] = flipped[0, ::-1]
    loop.write_off(source, vertices, flipped)
    done = subprocess.run([sys.executable, str(SCRIPT), str(source), str(target)], capture_output=True, text=True)
    assert done.returncode == 2 and "direction" in done.stderr
