"""Partial transport (cells cut by the sites' balls) through sdot.solve, sdot.plot and the command."""

import json

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import sdot  # noqa: E402
import sdot.plot  # noqa: E402
from conftest import run, sphere_sites  # noqa: E402

SQUARE = np.array([[-0.6, -0.6], [0.6, -0.6], [0.6, 0.6], [-0.6, 0.6]])


def problems():
    rng = np.random.default_rng(5)
    return {
        "plane": (rng.random((60, 2)), np.full(60, 0.4 / 60), {}),
        "sphere": (sphere_sites(150, 2), np.full(150, 0.5 * 4 * np.pi / 150), {"geometry": "sphere"}),
        "hyperbolic": (
            rng.uniform(-0.5, 0.5, (50, 2)),
            np.full(50, 0.02),
            {"geometry": "hyperbolic", "domain": SQUARE, "model": "klein"},
        ),
    }


def radius_of(geometry, weights):
    return {
        "plane": lambda w: np.sqrt(2 * w),
        "sphere": lambda w: np.arccos(np.exp(-w)),
        "hyperbolic": lambda w: np.arccosh(np.exp(w)),
    }[geometry](weights)


@pytest.fixture(scope="module")
def results():
    return {name: sdot.solve(sites, masses, partial=True, **kw) for name, (sites, masses, kw) in problems().items()}


@pytest.mark.parametrize("geometry", ["plane", "sphere", "hyperbolic"])
def test_partial_solve_reaches_the_masses_inside_the_balls(results, geometry):
    result = results[geometry]
    _, masses, _ = problems()[geometry]
    assert result.converged, result.message
    assert result.mass_scale == 1
    np.testing.assert_allclose(result.masses, masses, rtol=1e-8)
    assert result.masses.sum() < result.source_mass
    np.testing.assert_allclose(result.ball_radii, radius_of(geometry, result.weights), rtol=1e-12)
    arcs = np.count_nonzero(result.cell_neighbors == sdot.BALL_ARC)
    assert arcs > len(result.weights)
    # Every adjacency is between real sites: the arcs' label is not a neighbour.
    assert all((a >= 0).all() for a in result.adjacency())


def test_plane_cells_lie_in_their_balls(results):
    result = results["plane"]
    for i, cell in enumerate(result.cells):
        distances = np.linalg.norm(cell - result.sites[i], axis=1)
        assert distances.max() <= result.ball_radii[i] * (1 + 1e-9)


def test_partial_pictures_draw_the_arcs(tmp_path, results):
    for geometry, result in results.items():
        fig, ax = plt.subplots()
        sdot.plot.cells(result, ax=ax, color_by="mass")
        path = tmp_path / f"{geometry}.png"
        fig.savefig(path, dpi=60)
        plt.close(fig)
        assert path.stat().st_size > 2000
    # A lone site's cell is its disc: the drawn outline is round, not the 4-vertex polygon.
    lone = sdot.solve(np.array([[0.5, 0.5]]), np.array([0.1]), partial=True)
    curve = sdot.plot._curved_cells(lone, 16)[0]
    radius = np.linalg.norm(curve - [0.5, 0.5], axis=1)
    np.testing.assert_allclose(radius, np.sqrt(0.1 / np.pi), rtol=1e-12)
    assert len(curve) == 4 * 15


def test_partial_bad_input_is_named():
    sites = np.random.default_rng(0).random((10, 2))
    with pytest.raises(ValueError, match="masses: partial transport needs the masses"):
        sdot.solve(sites, partial=True)
    with pytest.raises(ValueError, match="masses: partial transport needs masses that sum to less than the source"):
        sdot.solve(sites, np.full(10, 0.2), partial=True)
    with pytest.raises(ValueError, match="density: partial transport"):
        sdot.solve(sites, np.full(10, 0.05), partial=True, density=lambda x: 1 + x[:, 0])
    with pytest.raises(ValueError, match=r"weights\[0\]"):
        sdot.solve(sites, np.full(10, 0.05), partial=True, weights=np.full(10, -1.0))


def test_command_reads_partial_and_writes_radii(tmp_path, sdot_command):
    sites, masses, _ = problems()["plane"]
    problem = {"geometry": "plane", "sites": sites.tolist(), "masses": masses.tolist(), "partial": True}
    (tmp_path / "p.json").write_text(json.dumps(problem))
    run(sdot_command, "solve", tmp_path / "p.json", "-o", tmp_path / "r.json", "--svg", tmp_path / "p.svg", "--quiet")
    result = json.loads((tmp_path / "r.json").read_text())
    assert result["status"] == "converged"
    np.testing.assert_allclose(result["ball_radii"], np.sqrt(2 * np.array(result["weights"])), rtol=1e-12)
    assert (tmp_path / "p.svg").stat().st_size > 1000
    problem["partial"] = "yes"
    (tmp_path / "p.json").write_text(json.dumps(problem))
    completed = run(sdot_command, "solve", tmp_path / "p.json", "-o", tmp_path / "r.json", "--quiet", check=False)
    assert completed.returncode == 2
    assert "partial: must be true or false" in completed.stderr
