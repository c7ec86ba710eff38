"""sdot.batch on a LocalCluster of 2 worker processes: the same results as the sequential calls,
per-item errors, resumable file batches, and a batch that survives a killed worker."""

import json
import os
import signal
import time

import numpy as np
import pytest

distributed = pytest.importorskip("distributed", reason="sdot.batch needs Dask distributed (python3-distributed)")

import sdot  # noqa: E402
import sdot.batch  # noqa: E402
from conftest import bumpy_mesh, icosphere, sphere_sites  # noqa: E402

TIMEOUT = 120  # seconds per batch: a broken cluster fails the test instead of hanging it
# The worker processes inherit the environment, so under scripts/test-sanitized.sh (LD_PRELOAD of
# the ASan runtime) they run the sanitized module too, several times slower: smaller solves there.
SANITIZED = "libasan" in os.environ.get("LD_PRELOAD", "")


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=":0") as c:
        yield c


@pytest.fixture(scope="module")
def client(cluster):
    with distributed.Client(cluster, set_as_default=False) as c:
        c.wait_for_workers(2, timeout=TIMEOUT)
        yield c


HEXAGON = 0.85 * np.column_stack((np.cos(np.arange(6) * np.pi / 3), np.sin(np.arange(6) * np.pi / 3)))


def small_problems():
    rng = np.random.default_rng(4)
    bad = rng.random((50, 2))
    bad[7, 1] = np.nan
    return [
        {"sites": rng.random((300, 2))},
        {"sites": rng.random((200, 2)), "masses": np.full(200, 1 / 200), "tolerance": 1e-11},
        {"sites": sphere_sites(400, 1), "geometry": "sphere"},
        {"sites": sphere_sites(300, 2), "geometry": "sphere", "density": lambda p: 1 + p[:, 2] ** 2,
         "rescale_masses": True},
        {"sites": rng.uniform(-0.4, 0.4, (150, 2)), "geometry": "hyperbolic", "domain": HEXAGON},
        {"sites": bad},
    ]


def test_solve_many_matches_the_sequential_calls(client):
    problems = small_problems()
    counts = []
    results = sdot.batch.solve_many(problems, client, progress=counts.append, timeout=TIMEOUT)
    assert len(results) == len(problems)
    for problem, result in zip(problems[:-1], results[:-1]):
        assert isinstance(result, sdot.SolveResult), result
        reference = sdot.solve(**problem)
        assert result.converged and result.geometry == reference.geometry
        assert result.iterations == reference.iterations
        # Workers run one OpenMP thread (Dask sets OMP_NUM_THREADS=1), this process more: sums may
        # round differently, nothing more.
        assert np.allclose(result.weights, reference.weights, rtol=0, atol=1e-12)
        assert np.allclose(result.masses, reference.masses, rtol=1e-12, atol=0)
        assert len(result.cells) == len(reference.cells)  # the cells come back too
    error = results[-1]
    assert isinstance(error, sdot.batch.BatchError) and error.index == 5
    assert error.type == "ValueError" and error.message == "sites[7]: is not finite"
    assert "ValueError" in error.traceback
    assert counts[-1]["done"] == 6 and counts[-1]["failed"] == 1 and counts[-1]["total"] == 6


def test_solve_many_refuses_bad_arguments_before_running():
    with pytest.raises(TypeError, match="problems: must be an iterable"):
        sdot.batch.solve_many({"sites": np.zeros((3, 2))})
    with pytest.raises(TypeError, match=r"problems\[1\]: must be a dict"):
        sdot.batch.solve_many([{"sites": np.zeros((3, 2))}, np.zeros((3, 2))])
    with pytest.raises(ValueError, match=r"problems\[0\]: 'site' is not an argument of sdot.solve"):
        sdot.batch.solve_many([{"site": np.zeros((3, 2))}])
    with pytest.raises(ValueError, match=r"problems\[0\]: has no 'sites'"):
        sdot.batch.solve_many([{"geometry": "plane"}])
    with pytest.raises(TypeError, match="client: must be"):
        sdot.batch.solve_many([{"sites": np.zeros((3, 2))}], client=42)
    with pytest.raises(ValueError, match="timeout"):
        sdot.batch.solve_many([{"sites": np.zeros((3, 2))}], timeout=-1)
    assert sdot.batch.solve_many([]) == []  # nothing to do: no cluster started


def test_batch_error_pickles_and_raises():
    import pickle

    error = sdot.batch.BatchError(3, "ValueError", "sites[0]: is not finite", "Traceback ...")
    again = pickle.loads(pickle.dumps(error))
    assert (again.index, again.type, again.message, again.traceback) == (3, "ValueError", "sites[0]: is not finite",
                                                                         "Traceback ...")
    with pytest.raises(sdot.batch.BatchError, match=r"item 3: ValueError: sites\[0\]: is not finite"):
        raise again


def meshes(folder):
    """Four genus-0 meshes and an open one, written in `folder`; returns (inputs, outputs)."""
    sphere2, faces2 = icosphere(2)
    sphere3, faces3 = icosphere(3)
    ellipsoid = sphere3 * [3.0, 1.5, 0.7]
    bumpy, bumpy_faces = bumpy_mesh(3)
    open_faces = faces2[(faces2 != 0).all(axis=1)]  # the faces around vertex 0 removed: a hole
    items = [("icosphere.off", sphere2, faces2), ("ellipsoid.ply", ellipsoid, faces3), ("bumpy.obj", bumpy, bumpy_faces),
             ("lh.white", bumpy * 40, bumpy_faces), ("open.off", sphere2, open_faces)]
    inputs, outputs = [], []
    for name, vertices, faces in items:
        sdot.write_mesh(folder / name, vertices, faces)
        inputs.append(folder / name)
        outputs.append(folder / "out" / (name.replace(".", "_") + "_sphere.off"))
    return inputs, outputs


def test_sphere_parameterization_matches_the_sequential_calls_and_resumes(client, cluster, tmp_path):
    inputs, outputs = meshes(tmp_path)
    options = {"reweightings": 20}
    results = sdot.batch.sphere_parameterization(inputs, outputs, client, progress=False, timeout=TIMEOUT, **options)
    for path, output, result in zip(inputs[:-1], outputs[:-1], results[:-1]):
        assert isinstance(result, dict), result
        vertices, faces = sdot.read_mesh(path)
        sphere, report = sdot.sphere_parameterization(vertices, faces, **options)
        written, written_faces = sdot.read_mesh(output)
        assert np.array_equal(written_faces, faces)
        assert np.abs(written - sphere).max() <= 1e-12
        assert result["status"] == "ok" and result["final_map"] == pytest.approx(report["final_map"], rel=1e-9)
        assert result["batch"]["skipped"] is False and result["batch"]["output"] == str(output)
        on_disk = json.loads(open(str(output) + ".report.json").read())
        assert on_disk["final_map"] == result["final_map"] and "batch" not in on_disk
    error = results[-1]
    assert isinstance(error, sdot.batch.BatchError) and error.index == 4 and error.type == "ValueError"
    assert "not a valid closed genus-0 manifold" in error.message and "boundary edges" in error.message
    assert not os.path.exists(outputs[-1]) and not os.path.exists(str(outputs[-1]) + ".report.json")

    # A re-run skips the finished items (nothing rewritten) and redoes a deleted one; here through
    # a scheduler address instead of a Client.
    times = {str(o): os.stat(o).st_mtime_ns for o in outputs[:-1]}
    os.unlink(str(outputs[1]) + ".report.json")  # the report marks an item finished
    again = sdot.batch.sphere_parameterization(inputs, outputs, cluster.scheduler_address, progress=False,
                                               timeout=TIMEOUT, **options)
    assert [r["batch"]["skipped"] for r in again[:-1]] == [True, False, True, True]
    assert isinstance(again[-1], sdot.batch.BatchError)
    for i in (0, 2, 3):
        assert os.stat(outputs[i]).st_mtime_ns == times[str(outputs[i])]
        assert again[i]["final_map"] == results[i]["final_map"]
    assert os.path.exists(str(outputs[1]) + ".report.json")
    assert again[1]["final_map"] == pytest.approx(results[1]["final_map"], rel=1e-9)
    assert not [name for name in os.listdir(tmp_path / "out") if name.startswith(".")]  # no temporary left


def test_sphere_parameterization_refuses_bad_arguments(tmp_path):
    a, b = tmp_path / "a.off", tmp_path / "b.off"
    with pytest.raises(ValueError, match="2 outputs for 1 inputs"):
        sdot.batch.sphere_parameterization([a], [b, tmp_path / "c.off"])
    with pytest.raises(ValueError, match="says no mesh format"):
        sdot.batch.sphere_parameterization([a], [tmp_path / "b.txt"])
    with pytest.raises(ValueError, match=r"outputs\[1\]: .* is also outputs\[0\]"):
        sdot.batch.sphere_parameterization([a, b], [tmp_path / "c.off", tmp_path / "c.off"])
    with pytest.raises(ValueError, match="would be overwritten"):
        sdot.batch.sphere_parameterization([a, b], [b, tmp_path / "c.off"])
    with pytest.raises(TypeError, match="refin: not an option"):
        sdot.batch.sphere_parameterization([a], [b], refin=1)
    with pytest.raises(TypeError, match="inputs: must be a list of paths"):
        sdot.batch.sphere_parameterization(str(a), [b])


def test_local_cluster_when_no_client_is_given(tmp_path):
    vertices, faces = icosphere(2)
    sdot.write_mesh(tmp_path / "in.off", vertices, faces)
    [report] = sdot.batch.sphere_parameterization([tmp_path / "in.off"], [tmp_path / "out.ply"], progress=False,
                                                  n_workers=1, timeout=TIMEOUT)
    assert report["status"] == "ok" and os.path.exists(tmp_path / "out.ply")


def test_items_not_finished_within_the_timeout_come_back_as_errors(client):
    rng = np.random.default_rng(5)
    problems = [{"sites": rng.random((20000 if SANITIZED else 100000, 2))} for _ in range(3)]
    start = time.monotonic()
    results = sdot.batch.solve_many(problems, client, progress=False, timeout=0.2)
    assert time.monotonic() - start < 5
    assert [(r.index, r.type) for r in results] == [(0, "TimeoutError"), (1, "TimeoutError"), (2, "TimeoutError")]
    assert "timeout of 0.2 s" in results[0].message


def test_a_killed_worker_does_not_stop_the_batch(client):
    # 12 solves of about half a second each; one worker process is killed (SIGKILL) once two
    # are done, while both workers are running tasks. The nanny starts a new worker and the
    # scheduler runs the lost tasks again.
    rng = np.random.default_rng(9)
    n = 5000 if SANITIZED else 30000
    problems = [{"sites": rng.random((n, 2)), "tolerance": 1e-8} for _ in range(12)]
    pids = client.run(os.getpid)
    killed = {}

    def kill_one(counts):
        if counts["done"] == 2 and not killed:
            processing = client.processing()
            address = max(pids, key=lambda a: len(processing.get(a, ())))
            killed["address"], killed["tasks"] = address, len(processing.get(address, ()))
            os.kill(pids[address], signal.SIGKILL)

    start = time.monotonic()
    results = sdot.batch.solve_many(problems, client, progress=kill_one, timeout=TIMEOUT)
    assert killed and killed["tasks"] >= 1  # the worker died with work in hand
    assert all(isinstance(r, sdot.SolveResult) and r.converged for r in results), results
    for i in (0, 5, 11):
        assert np.allclose(results[i].weights, sdot.solve(**problems[i]).weights, rtol=0, atol=1e-12)
    for r, p in zip(results, problems):
        assert np.array_equal(r.sites, p["sites"]) and np.allclose(r.masses, 1 / n, rtol=1e-8)
    assert time.monotonic() - start < TIMEOUT
    client.wait_for_workers(2, timeout=TIMEOUT)  # the nanny restarted it


def test_a_problem_that_kills_its_worker_comes_back_as_an_error():
    # A density function that ends its process: every worker that runs it dies. The scheduler
    # gives up after allowed-failures deaths (1 here) and the item is a KilledWorker error.
    import dask

    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=":0") as c:
            with distributed.Client(c, set_as_default=False) as client:
                problems = [{"sites": np.random.default_rng(1).random((100, 2))},
                            {"sites": np.random.default_rng(2).random((100, 2)), "density": lambda x: os._exit(3)}]
                results = sdot.batch.solve_many(problems, client, progress=False, timeout=TIMEOUT)
    assert isinstance(results[0], sdot.SolveResult) and results[0].converged
    assert isinstance(results[1], sdot.batch.BatchError) and results[1].type == "KilledWorker"
