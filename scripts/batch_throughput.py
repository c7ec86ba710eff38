#!/usr/bin/env python3
"""Throughput of sdot.batch on this machine: a LocalCluster of 1 and of 2 worker processes
against a plain loop in one process. Prints the markdown table of docs/scaling.md.

    PYTHONPATH=build/python /usr/bin/python3 scripts/batch_throughput.py [--repeats 3]
        [--problems 40] [--sites 10000] [--meshes 8] [--mesh-level 5] [--workers 1 2]

(a) solve_many: `--problems` plane problems of `--sites` uniform random sites (equal masses,
uniform density on the unit square, default tolerance). (b) sphere_parameterization: `--meshes`
bumpy icospheres (10·4^level + 2 vertices: 10,242 at level 5; each with its own bumps) written as
OFF files in a temporary folder, mapped with the default options (outputs deleted between runs,
so that nothing is skipped). Each time is the median of `--repeats` runs of the whole batch on a
cluster started beforehand (the start-up is timed separately); the loop runs the single-machine
calls one after the other in this process (the library's OpenMP loops may use every core there,
while each Dask worker runs one thread: Dask sets OMP_NUM_THREADS=1 in its workers). Exit status
77 when Dask distributed is missing.
"""

import argparse
import os
import statistics
import sys
import tempfile
import time

import numpy as np

import sdot
import sdot.batch


def icosphere(levels):
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


def bumpy(levels, seed):
    """An icosphere pushed into a lumpy, elongated shape, different for each seed."""
    vertices, faces = icosphere(levels)
    rng = np.random.default_rng(seed)
    a, b, c = rng.uniform(2, 4, 3)
    x, y, z = vertices.T
    radius = 1 + 0.3 * np.sin(a * x) * np.cos(b * y) + 0.2 * np.sin(c * z) ** 2
    shaped = vertices * radius[:, None]
    shaped[:, 0] *= rng.uniform(1.2, 2.0)
    return shaped, faces


def median_time(run, repeats, before=None):
    times = []
    for _ in range(repeats):
        if before:
            before()
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main():
    try:
        import distributed
    except ImportError:
        print("batch_throughput.py: needs Dask distributed (Debian: python3-dask python3-distributed)", file=sys.stderr)
        sys.exit(77)  # ctest's SKIP_RETURN_CODE

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--problems", type=int, default=40)
    parser.add_argument("--sites", type=int, default=10000)
    parser.add_argument("--meshes", type=int, default=8)
    parser.add_argument("--mesh-level", type=int, default=5)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()

    rng = np.random.default_rng(1)
    problems = [{"sites": rng.random((args.sites, 2))} for _ in range(args.problems)]
    folder = tempfile.mkdtemp(prefix="sdot-batch-throughput-")
    inputs, outputs = [], []
    for i in range(args.meshes):
        vertices, faces = bumpy(args.mesh_level, i)
        inputs.append(os.path.join(folder, f"mesh{i}.off"))
        outputs.append(os.path.join(folder, f"mesh{i}_sphere.off"))
        sdot.write_mesh(inputs[-1], vertices, faces)
    n_vertices = len(vertices)

    def clean():
        for o in outputs:
            for path in (o, o + ".report.json"):
                if os.path.exists(path):
                    os.unlink(path)

    def loop_solve():
        results = [sdot.solve(**p) for p in problems]
        assert all(r.converged for r in results)

    def loop_param():
        for i, o in zip(inputs, outputs):
            vertices, faces = sdot.read_mesh(i)
            sphere, _ = sdot.sphere_parameterization(vertices, faces)
            sdot.write_mesh(o, sphere, faces)

    rows = []  # (case, how, start-up, time)
    load = os.getloadavg()[0]
    rows.append(("solve", "loop in one process", None, median_time(loop_solve, args.repeats)))
    rows.append(("param", "loop in one process", None, median_time(loop_param, args.repeats, clean)))
    for workers in args.workers:
        start = time.perf_counter()
        cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0")
        client = distributed.Client(cluster, set_as_default=False)
        client.wait_for_workers(workers)
        startup = time.perf_counter() - start

        def batch_solve():
            results = sdot.batch.solve_many(problems, client, progress=False)
            assert all(isinstance(r, sdot.SolveResult) and r.converged for r in results), results

        def batch_param():
            reports = sdot.batch.sphere_parameterization(inputs, outputs, client, progress=False)
            assert all(isinstance(r, dict) and not r["batch"]["skipped"] for r in reports), reports

        rows.append(("solve", f"LocalCluster, {workers} worker{'s' if workers > 1 else ''}", startup,
                     median_time(batch_solve, args.repeats)))
        rows.append(("param", f"LocalCluster, {workers} worker{'s' if workers > 1 else ''}", startup,
                     median_time(batch_param, args.repeats, clean)))
        client.close()
        cluster.close()
    clean()
    for path in inputs:
        os.unlink(path)
    os.rmdir(folder)

    cases = {
        "solve": (f"solve_many: {args.problems} plane problems, {args.sites:,} sites", args.problems, "problems"),
        "param": (f"sphere_parameterization: {args.meshes} meshes, {n_vertices:,} vertices", args.meshes, "meshes"),
    }
    print(f"<!-- {os.cpu_count()} cores, 1-minute load average {load:.2f} at the start and {os.getloadavg()[0]:.2f} at"
          f" the end, median of {args.repeats} runs -->")
    print("| batch | run by | cluster start-up (s) | time (s) | items per second | against 1 worker |")
    print("|---|---|---|---|---|---|")
    for case, (title, count, _) in cases.items():
        one = next((t for c, how, _, t in rows if c == case and how.endswith(" 1 worker")), None)
        for c, how, startup, seconds in rows:
            if c != case:
                continue
            speedup = f"{one / seconds:.2f}×" if one else ""
            print(f"| {title} | {how} | {'' if startup is None else f'{startup:.2f}'} | {seconds:.2f} | "
                  f"{count / seconds:.2f} | {speedup} |")


if __name__ == "__main__":
    main()
