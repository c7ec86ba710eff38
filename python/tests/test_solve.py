"""sdot.solve on every geometry: worked examples with known answers, densities from numpy, the
same weights as the sdot command, progress and callbacks, the GIL and Ctrl-C."""

import json
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import sdot
from conftest import run, sphere_sites


# ---- worked examples (pysdot style) ---------------------------------------------------------


def test_pysdot_style_three_lines():
    # pysdot: ot = OptimalTransport(positions); ot.adjust_weights(). Here: one call.
    positions = np.random.default_rng(0).random((200, 2))
    result = sdot.solve(positions)
    assert result.converged, result.message
    assert np.allclose(result.masses, 1 / 200, rtol=1e-9)
    assert result.weights.shape == (200,)
    assert result.centroids.shape == (200, 2)
    assert np.all((result.centroids > 0) & (result.centroids < 1))
    assert len(result.cells) == 200 and all(c.shape[1] == 2 for c in result.cells)
    # The cells tile the square: their areas (shoelace) sum to 1.
    area = sum(0.5 * abs(np.dot(c[:, 0], np.roll(c[:, 1], -1)) - np.dot(c[:, 1], np.roll(c[:, 0], -1))) for c in result.cells)
    assert area == pytest.approx(1, abs=1e-12)


def test_grid_sites_give_the_grid_squares_and_the_closed_form_cost():
    k = 8
    centres = (np.arange(k) + 0.5) / k
    sites = np.array([(x, y) for y in centres for x in centres])
    result = sdot.solve(sites, np.full(k * k, 1 / k**2))
    assert result.converged
    assert np.allclose(result.weights, 0, atol=1e-12)
    # each cell is a square of side 1/k around its site: cost ∫|x − y|²/2 = h⁴/12 per cell
    assert result.transport_cost == pytest.approx(k * k * (1 / k) ** 4 / 12, rel=1e-12)
    assert np.allclose(result.centroids, sites, atol=1e-14)
    for cell, site in zip(result.cells, sites):
        assert np.allclose(np.abs(cell - site).max(axis=0), 0.5 / k)


def test_two_sites_split_the_square_where_the_masses_say():
    sites = np.array([[0.25, 0.5], [0.75, 0.5]])
    result = sdot.solve(sites, [0.3, 0.7], tolerance=1e-13)
    assert result.usable
    assert result.cells[0][:, 0].max() == pytest.approx(0.3, abs=1e-12)
    # on the boundary x = 0.3: |x − y0|²/2 − w0 = |x − y1|²/2 − w1, so w0 − w1 = −0.1
    assert result.weights[0] - result.weights[1] == pytest.approx(-0.1, abs=1e-12)


def test_sphere_equal_masses_and_centroids_on_the_sphere():
    sites = sphere_sites(500, 3)
    result = sdot.solve(sites, geometry="sphere")
    assert result.converged
    assert result.source_mass == pytest.approx(4 * np.pi, rel=1e-12)
    assert np.allclose(result.masses, 4 * np.pi / 500, rtol=1e-9)
    assert np.allclose(np.linalg.norm(np.vstack(result.cells), axis=1), 1, atol=1e-12)


def test_hyperbolic_results_in_both_models():
    angles = np.linspace(0, 2 * np.pi, 7)[:-1] + 0.2
    hexagon = 0.8 * np.column_stack((np.cos(angles), np.sin(angles)))
    rng = np.random.default_rng(5)
    sites = rng.uniform(-0.5, 0.5, size=(150, 2))
    result = sdot.solve(sites, geometry="hyperbolic", domain=hexagon)
    assert result.converged
    assert result.centroids.shape == (150, 3) and result.centroids_poincare.shape == (150, 2)
    # hyperboloid: z² − x² − y² = 1; Poincaré: (x, y) / (1 + z)
    hyperboloid = np.vstack(result.cells)
    assert np.allclose(hyperboloid[:, 2] ** 2 - hyperboloid[:, 0] ** 2 - hyperboloid[:, 1] ** 2, 1, atol=1e-9)
    assert np.allclose(np.vstack(result.cells_poincare), hyperboloid[:, :2] / (1 + hyperboloid[:, 2:3]), atol=1e-14)
    # the same problem with the sites given on the hyperboloid
    z = (1 + np.sum(sites**2, axis=1)) / (1 - np.sum(sites**2, axis=1))
    lifted = np.column_stack((sites * (1 + z)[:, None], z))
    domain = np.column_stack((hexagon * (1 + ((1 + np.sum(hexagon**2, 1)) / (1 - np.sum(hexagon**2, 1))))[:, None],
                              (1 + np.sum(hexagon**2, 1)) / (1 - np.sum(hexagon**2, 1))))
    again = sdot.solve(lifted, geometry="hyperbolic", domain=domain, model="hyperboloid")
    assert np.allclose(again.weights, result.weights, atol=1e-9)


# ---- densities and domains from numpy --------------------------------------------------------


def test_function_density_agrees_with_the_same_linear_mesh_density():
    rng = np.random.default_rng(1)
    sites = rng.random((120, 2))
    calls = []

    def rho(points):
        calls.append(len(points))
        return 1 + points[:, 0]

    by_function = sdot.solve(sites, density=rho, rescale_masses=True)
    vertices = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    mesh = (vertices, np.array([[0, 1, 2], [0, 2, 3]]), 1 + vertices[:, 0])
    by_mesh = sdot.solve(sites, density=mesh, rescale_masses=True)
    assert by_function.converged and by_mesh.converged
    assert by_function.source_mass == pytest.approx(1.5, rel=1e-12)
    assert np.allclose(by_function.weights, by_mesh.weights, atol=1e-10)
    # vectorized: one call per cell (or facet) with many points, not one call per point
    assert len(calls) > 0 and np.mean(calls) > 20


def test_function_density_on_a_holed_domain():
    domain = {"outer": [[0, 0], [2, 0], [2, 1], [0, 1]], "holes": [[[0.8, 0.3], [1.2, 0.3], [1.2, 0.7], [0.8, 0.7]]]}
    rng = np.random.default_rng(2)
    sites = rng.random((200, 2)) * [2, 1]
    sites = sites[~((sites[:, 0] > 0.8) & (sites[:, 0] < 1.2) & (sites[:, 1] > 0.3) & (sites[:, 1] < 0.7))]
    result = sdot.solve(sites, domain=domain, density=lambda p: np.ones(len(p)), rescale_masses=True)
    assert result.converged
    assert result.source_mass == pytest.approx(2 - 0.16, rel=1e-12)


def test_image_density_on_the_plane_and_the_sphere():
    image = np.ones((4, 6))
    image[:, 3:] = 3  # right half three times as dense
    sites = np.random.default_rng(4).random((100, 2))
    plane = sdot.solve(sites, density=image, interpolation="constant", rescale_masses=True)
    assert plane.converged and plane.source_mass == pytest.approx(2, rel=1e-12)
    stretched = sdot.solve(sites * 2, density=image, interpolation="constant", extent=(0, 0, 2, 2),
                           domain=[[0, 0], [2, 0], [2, 2], [0, 2]], rescale_masses=True)
    assert stretched.source_mass == pytest.approx(8, rel=1e-12)
    lonlat = np.ones((18, 36))
    lonlat[:9] = 2  # northern hemisphere twice as dense
    sphere = sdot.solve(sphere_sites(300, 1), geometry="sphere", density=lonlat, interpolation="constant",
                        rescale_masses=True)
    assert sphere.converged and sphere.source_mass == pytest.approx(6 * np.pi, rel=1e-12)


def test_sphere_cap_domain():
    sites = sphere_sites(2000, 8)
    sites = sites[sites[:, 2] > 0.55][:100]
    result = sdot.solve(sites, geometry="sphere", domain={"center": [0, 0, 1], "angle": 1.0})
    assert result.converged
    assert result.source_mass == pytest.approx(2 * np.pi * (1 - np.cos(1.0)), rel=1e-12)


def test_non_contiguous_and_integer_arrays_are_accepted():
    sites = np.random.default_rng(6).random((60, 4))[:, ::2]  # a strided view
    assert not sites.flags.c_contiguous
    a = sdot.solve(sites)
    b = sdot.solve(np.ascontiguousarray(sites))
    assert np.array_equal(a.weights, b.weights)
    grid = sdot.solve(np.array([[0, 0], [1, 1], [1, 0]]) * 0.5 + 0.25)  # int64 sites
    assert grid.converged


def test_never_nan_when_stopped_early():
    sites = np.random.default_rng(7).random((300, 2)) ** 3  # clustered
    result = sdot.solve(sites, max_iterations=1)
    assert result.status == "iteration_limit"
    for name in ("weights", "masses", "centroids", "cell_vertices"):
        assert np.isfinite(getattr(result, name)).all(), name


# ---- the same weights as the sdot command ----------------------------------------------------


def solve_with_command(sdot_command, tmp_path, problem):
    problem_file = tmp_path / "problem.json"
    problem_file.write_text(json.dumps(problem))
    result_file = tmp_path / "result.json"
    run(sdot_command, "solve", problem_file, "-o", result_file, "--quiet")
    return json.loads(result_file.read_text())


def test_plane_matches_the_command(sdot_command, tmp_path):
    rng = np.random.default_rng(11)
    domain = {"outer": [[0, 0], [3, 0], [3, 2], [0, 2]], "holes": [[[1, 0.5], [2, 0.5], [1.5, 1.5]]]}
    sites = rng.random((250, 2)) * [3, 2]
    vertices = np.array([[0, 0], [3, 0], [3, 2], [0, 2], [1.5, 1]])
    triangles = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    values = np.array([1, 2, 3, 1, 0.5])
    masses = rng.uniform(1, 2, 250)
    problem = {"geometry": "plane", "sites": sites.tolist(), "masses": masses.tolist(), "domain": domain,
               "density": {"type": "mesh", "vertices": vertices.tolist(), "triangles": triangles.tolist(),
                           "values": values.tolist()}, "tolerance": 1e-11}
    command = solve_with_command(sdot_command, tmp_path, problem)
    python = sdot.solve(sites, masses, domain=domain, density=(vertices, triangles, values), tolerance=1e-11,
                        rescale_masses=True)
    assert command["status"] == python.status == "converged"
    assert np.abs(np.array(command["weights"]) - python.weights).max() <= 1e-12
    assert np.abs(np.array(command["centroids"]) - python.centroids).max() <= 1e-12


def test_sphere_matches_the_command(sdot_command, tmp_path):
    # an image density: a 16-bit PGM for the command, the same values (v / 65535) for Python
    rows, columns = 20, 40
    levels = (np.add.outer(np.arange(rows) * 3000, np.arange(columns) * 800) % 65536).astype(np.uint16) + 1
    pgm = tmp_path / "rho.pgm"
    pgm.write_bytes(f"P5 {columns} {rows} 65535\n".encode() + levels.astype(">u2").tobytes())
    sites = sphere_sites(400, 12)
    problem = {"geometry": "sphere", "sites": sites.tolist(), "tolerance": 1e-11,
               "density": {"type": "image", "file": str(pgm), "interpolation": "linear"}}
    command = solve_with_command(sdot_command, tmp_path, problem)
    python = sdot.solve(sites, geometry="sphere", density=levels / 65535.0, interpolation="linear", tolerance=1e-11)
    assert command["status"] == python.status == "converged"
    assert np.abs(np.array(command["weights"]) - python.weights).max() <= 1e-12


def test_hyperbolic_matches_the_command(sdot_command, tmp_path):
    domain = [[-0.6, -0.5], [0.7, -0.4], [0.5, 0.6], [-0.5, 0.7]]
    sites = np.random.default_rng(13).uniform(-0.45, 0.45, size=(200, 2))
    masses = np.random.default_rng(14).uniform(1, 3, 200)
    problem = {"geometry": "hyperbolic", "domain": {"model": "klein", "vertices": domain}, "sites": sites.tolist(),
               "masses": masses.tolist(), "tolerance": 1e-11}
    command = solve_with_command(sdot_command, tmp_path, problem)
    python = sdot.solve(sites, masses, geometry="hyperbolic", model="klein", domain=domain, tolerance=1e-11,
                        rescale_masses=True)
    assert command["status"] == python.status == "converged"
    assert np.abs(np.array(command["weights"]) - python.weights).max() <= 1e-12


# ---- progress, callbacks, threads, Ctrl-C ----------------------------------------------------


def test_progress_line_and_callback(capsys):
    records = []
    result = sdot.solve(np.random.default_rng(9).random((300, 2)), progress=True, callback=records.append)
    err = capsys.readouterr().err
    assert err.count("\r") == len(result.history) and "max rel. error" in err
    assert [r["iteration"] for r in records] == [h["iteration"] for h in result.history]
    assert records[-1]["max_relative_error"] == result.max_relative_error


def test_an_exception_in_the_callback_stops_the_solve():
    class Stop(Exception):
        pass

    def callback(record):
        if record["iteration"] == 1:
            raise Stop()

    with pytest.raises(Stop):
        sdot.solve(np.random.default_rng(9).random((300, 2)), callback=callback)


def test_the_gil_is_released_during_a_solve():
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(1)
            time.sleep(0.001)

    thread = threading.Thread(target=count)
    thread.start()
    try:
        start = time.perf_counter()
        sdot.solve(sphere_sites(40000, 2), geometry="sphere", tolerance=1e-8)
        elapsed = time.perf_counter() - start
    finally:
        done.set()
        thread.join()
    # a thread that needs the GIL every millisecond kept running through the solve
    assert elapsed > 0.2 and len(ticks) > 0.3 * elapsed / 0.0011


def test_ctrl_c_stops_a_long_solve():
    script = (
        "import os, signal, threading, numpy as np, sdot\n"
        "threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()\n"
        "sites = np.random.default_rng(0).random((300000, 2)) ** 2\n"
        "try:\n"
        "    sdot.solve(sites, tolerance=1e-14, max_iterations=1000, linear_solver='cg')\n"
        "    print('finished')\n"
        "except KeyboardInterrupt:\n"
        "    print('interrupted')\n"
    )
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                         env=dict(os.environ))
    assert out.stdout.strip() == "interrupted", out.stderr
    assert time.perf_counter() - start < 120
