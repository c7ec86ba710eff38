"""sdot.solve on the periodic plane (geometry="plane", periodic=...): the torus's invariances,
boxes and periodic axes, densities on the box, the same answer as the sdot command, bad input."""

import json

import numpy as np
import pytest

import sdot
from conftest import run


def random_sites(n, seed):
    return np.random.default_rng(seed).random((n, 2))


def random_masses(n, seed, ratio=10.0):
    masses = ratio ** np.random.default_rng(seed).random(n)
    return masses / masses.sum()


def torus_distance(a, b, period=(1.0, 1.0)):
    difference = np.asarray(a) - np.asarray(b)
    difference -= np.asarray(period) * np.round(difference / np.asarray(period))
    return np.linalg.norm(difference, axis=-1)


def shoelace(cell):
    return 0.5 * (np.dot(cell[:, 0], np.roll(cell[:, 1], -1)) - np.dot(cell[:, 1], np.roll(cell[:, 0], -1)))


def test_unit_square_both_axes():
    sites = random_sites(300, 1)
    result = sdot.solve(sites, random_masses(300, 2), geometry="plane", periodic=True, tolerance=1e-11)
    assert result.converged, result.message
    assert result.geometry == "plane" and result.periodic == (True, True) and result.box == (0, 0, 1, 1)
    assert result.masses.sum() == pytest.approx(1, abs=1e-12)
    assert np.all((result.centroids >= 0) & (result.centroids < 1))
    # The cells are polygons of the covering plane (some cross the box's sides) tiling an area 1.
    assert sum(shoelace(c) for c in result.cells) == pytest.approx(1, abs=1e-12)
    assert any((c < 0).any() or (c > 1).any() for c in result.cells)
    # Every cell is within half a period of its site.
    assert all(np.abs(c - s).max() <= 0.5 + 1e-12 for c, s in zip(result.cells, sites))


def test_translation_modulo_the_period_changes_nothing_else():
    sites, masses = random_sites(200, 3), random_masses(200, 4)
    reference = sdot.solve(sites, masses, periodic=True, tolerance=1e-11)
    for shift in ([0.37, 0.81], [-2.5, 1.25]):
        moved = sdot.solve(sites + shift, masses, periodic=True, tolerance=1e-11)
        assert moved.converged
        np.testing.assert_allclose(moved.weights, reference.weights, atol=1e-9)
        assert torus_distance(moved.centroids, reference.centroids + shift).max() < 1e-9
        assert moved.transport_cost == pytest.approx(reference.transport_cost, abs=1e-12)


def test_one_periodic_axis_and_a_box():
    sites = random_sites(150, 5) * [2, 1] + [3, -1]
    box = (3, -1, 5, 0)
    result = sdot.solve(sites, 2 * random_masses(150, 6), periodic=(True, False), domain=box)
    assert result.converged, result.message
    assert result.periodic == (True, False) and result.box == box
    assert result.masses.sum() == pytest.approx(2, abs=1e-12)
    assert np.all((result.centroids[:, 0] >= 3) & (result.centroids[:, 0] < 5))
    vertices = np.vstack(result.cells)
    assert vertices[:, 1].min() >= -1 - 1e-12 and vertices[:, 1].max() <= 1e-12  # clipped along y
    # The same box given by its corners.
    corners = [[3, -1], [3, 0], [5, 0], [5, -1]]
    again = sdot.solve(sites, 2 * random_masses(150, 6), periodic=(True, False), domain=corners)
    np.testing.assert_array_equal(again.weights, result.weights)


def test_torus_is_the_periodic_plane():
    sites = random_sites(100, 7)
    a = sdot.solve(sites, geometry="torus")
    b = sdot.solve(sites, geometry="plane", periodic=True)
    assert a.geometry == "torus" and a.periodic == (True, True)
    np.testing.assert_array_equal(a.weights, b.weights)
    # periodic=False on the torus: the box without wrapping, which is the plane's unit square.
    c = sdot.solve(sites, geometry="torus", periodic=False, tolerance=1e-11)
    d = sdot.solve(sites, geometry="plane", tolerance=1e-11)
    assert c.periodic == (False, False)
    np.testing.assert_allclose(c.weights, d.weights, atol=1e-9)


def test_sites_outside_the_box_are_wrapped_and_tiny_problems_work():
    one = sdot.solve([[3.25, -0.5]], periodic=True)
    assert one.converged and one.masses[0] == pytest.approx(1, abs=1e-14)
    assert torus_distance(one.centroids[0], [0.25, 0.5]) < 1e-14
    assert one.transport_cost == pytest.approx(1 / 12, abs=1e-14)
    two = sdot.solve([[0.1, 0.5], [1.6, 0.5]], [0.3, 0.7], periodic=True, tolerance=1e-13)
    assert two.usable
    assert torus_distance(two.centroids, [[0.1, 0.5], [0.6, 0.5]]).max() < 1e-12
    assert two.adjacency()[0].tolist() == [0, 1]  # touches its own image above and below


def test_densities_given_on_the_box():
    sites = random_sites(120, 8)
    seen = []

    def rho(points):
        seen.append(points.copy())
        return 1 + points[:, 0]

    result = sdot.solve(sites, periodic=True, density=rho)
    assert result.converged, result.message
    assert result.source_mass == pytest.approx(1.5, abs=1e-12)
    points = np.vstack(seen)
    assert np.all((points >= 0) & (points <= 1))  # read in the box only
    image = np.random.default_rng(9).random((16, 24)) + 0.2
    for interpolation in ("constant", "bilinear"):
        result = sdot.solve(sites, periodic=True, density=image, interpolation=interpolation)
        assert result.converged, result.message
        if interpolation == "constant":
            assert result.source_mass == pytest.approx(image.mean(), rel=1e-12)
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    mesh = (square, np.array([[0, 1, 2], [0, 2, 3]]), np.array([1.0, 2.0, 1.0, 0.5]))
    result = sdot.solve(sites, periodic=(False, True), density=mesh)
    assert result.converged, result.message
    assert result.source_mass == pytest.approx(13 / 12, abs=1e-12)


def test_the_command_gives_the_same_solution(sdot_command, tmp_path):
    sites = random_sites(80, 10) * [2, 1]
    masses = random_masses(80, 11)
    problem = {"geometry": "torus", "sites": sites.tolist(), "masses": masses.tolist(), "domain": [0, 0, 2, 1],
               "periodic": [True, False], "tolerance": 1e-12}
    (tmp_path / "problem.json").write_text(json.dumps(problem))
    run(sdot_command, "solve", tmp_path / "problem.json", "-o", tmp_path / "result.json", "--svg",
        tmp_path / "cells.svg", "--quiet")
    command = json.loads((tmp_path / "result.json").read_text())
    python = sdot.solve(sites, masses * 2, periodic=(True, False), domain=(0, 0, 2, 1), tolerance=1e-12)
    assert command["geometry"] == "torus" and command["status"] == "converged"
    np.testing.assert_allclose(command["weights"], python.weights, atol=1e-10)
    np.testing.assert_allclose(command["centroids"], python.centroids, atol=1e-10)
    assert (tmp_path / "cells.svg").read_text().startswith("<svg")


def test_the_periodic_plot_renders(tmp_path):
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import sdot.plot

    result = sdot.solve(random_sites(60, 12), periodic=True)
    ax = sdot.plot.cells(result, color_by="weight", centroids=True)
    ax.figure.savefig(tmp_path / "torus.png")
    assert (tmp_path / "torus.png").stat().st_size > 0
    # More polygons than cells: those crossing a side are drawn on both sides.
    assert len(ax.collections[0].get_paths()) > 60


@pytest.mark.parametrize(
    "arguments, message",
    [
        (dict(periodic="yes"), r"periodic: must be True, False or two booleans"),
        (dict(periodic=(True,)), r"periodic: must be True, False or two booleans"),
        (dict(periodic=(1, 0)), r"periodic: must be True, False or two booleans"),
        (dict(periodic=True, domain=[[0, 0], [1, 0], [0, 1]]), r"domain: a periodic problem needs a rectangular box"),
        (dict(periodic=True, domain=[[0, 0], [1, 0], [1.5, 1], [0, 1]]), r"domain\[1\]: .*axis-aligned"),
        (dict(periodic=True, domain={"outer": [[0, 0], [1, 0], [1, 1]]}), r"domain: a periodic problem needs"),
        (dict(periodic=True, domain=(0, 0, 0, 1)), r"domain: the box must be finite with positive size"),
        (dict(periodic=True, domain=(0, 0, 1, np.inf)), r"domain\[3\]: is not finite"),
    ],
)
def test_bad_input(arguments, message):
    with pytest.raises(ValueError, match=message):
        sdot.solve(random_sites(10, 13), **arguments)


def test_duplicates_modulo_the_period_name_both_sites():
    sites = random_sites(10, 14)
    sites[7] = sites[2] + [1, -3]
    with pytest.raises(ValueError, match=r"sites\[7\]: duplicate of sites\[2\] modulo the period"):
        sdot.solve(sites, periodic=True)
    sites[7, 1] += 0.5  # not periodic along y: a different point
    assert sdot.solve(sites, periodic=(True, False), domain=(0, -3, 1, 1)).converged


def test_periodic_needs_the_plane():
    with pytest.raises(ValueError, match="periodic: only the plane"):
        sdot.solve(np.eye(3), geometry="sphere", periodic=True)
