"""Many problems at once on Dask distributed: `solve_many` and `sphere_parameterization`.

    >>> import numpy as np, sdot.batch
    >>> rng = np.random.default_rng(0)
    >>> problems = [{"sites": rng.random((1000, 2))} for _ in range(8)]
    >>> results = sdot.batch.solve_many(problems)        # a local cluster, one worker per core
    >>> [r.status for r in results][:2]
    ['converged', 'converged']

Each item runs as one Dask task, on a `distributed.LocalCluster` started for the call or on the
cluster of a given `distributed.Client` (or scheduler address). Results come back in input order
and are the objects the single-machine calls return; an item that fails comes back as a
`BatchError` in its place, so that one bad item never stops the batch. A task whose worker dies is
run again on another worker by the Dask scheduler. Needs python3-dask and python3-distributed
(`import sdot` does not import them).
"""

import json
import os
import sys
import tempfile
import time
import traceback as _traceback
import warnings
from inspect import signature

from . import _sdot
from ._mesh import read_mesh, write_mesh
from ._mesh import sphere_parameterization as _sphere_parameterization
from ._solve import solve as _solve

__all__ = ["solve_many", "sphere_parameterization", "BatchError"]

# Retries of a task that raised outside the item's own code (the item's exceptions are caught and
# returned). A task whose worker died is rescheduled by the scheduler, not counted here: up to
# distributed.scheduler.allowed-failures deaths (3 by default), then it comes back as a
# BatchError of type KilledWorker.
_RETRIES = 1
_POLL_S = (0.002, 0.1)  # the client looks for finished tasks this often (backing off when none)


class BatchError(Exception):
    """One failed item of a batch, returned in the item's place (never raised by the batch).

    Attributes: ``index`` (the item's position in the input), ``type`` (the exception's class
    name, e.g. "ValueError", or "KilledWorker" when workers kept dying while running it),
    ``message`` and ``traceback`` (text, from the worker). ``raise result`` re-raises it."""

    def __init__(self, index, type, message, traceback=""):
        super().__init__(f"item {index}: {type}: {message}")
        self.index = index
        self.type = type
        self.message = message
        self.traceback = traceback

    def __reduce__(self):
        return (BatchError, (self.index, self.type, self.message, self.traceback))

    def __repr__(self):
        return f"BatchError(index={self.index}, type={self.type!r}, message={self.message!r})"

    @classmethod
    def from_exception(cls, index, error, text=None):
        if text is None:
            text = "".join(_traceback.format_exception(type(error), error, error.__traceback__))
        return cls(index, type(error).__name__, str(error), text)


# ---------------------------------------------------------------------------------------------
# Task functions: top-level, so that workers import them from sdot.batch.


def _solve_task(index, problem):
    """One item of solve_many: the SolveResult, or a BatchError."""
    try:
        return _solve(**problem)
    except Exception as error:  # noqa: BLE001 - every failure of one item is that item's result
        return BatchError.from_exception(index, error)


def _write_json_atomically(path, value):
    folder = os.path.dirname(path) or "."
    descriptor, temporary = tempfile.mkstemp(prefix=".tmp-", suffix=".json", dir=folder)
    try:
        with os.fdopen(descriptor, "w") as file:
            json.dump(value, file, indent=2)
            file.write("\n")
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, path)
    except BaseException:
        try:
            os.unlink(temporary)
        except OSError:
            pass
        raise


def _finished_report(report_path):
    try:
        with open(report_path) as file:
            report = json.load(file)
    except (OSError, ValueError):
        return None
    return report if isinstance(report, dict) else None


def _sphere_task(index, input_path, output_path, report_path, options, skip_existing):
    """One item of sphere_parameterization: the report (as written next to the output, plus a
    "batch" entry), or a BatchError."""
    start = time.monotonic()
    try:
        if skip_existing and os.path.exists(output_path):
            report = _finished_report(report_path)
            if report is not None:
                report["batch"] = {"input": input_path, "output": output_path, "report": report_path,
                                   "skipped": True, "seconds": time.monotonic() - start}
                return report
        vertices, faces = read_mesh(input_path)
        sphere, report = _sphere_parameterization(vertices, faces, **options)
        report.pop("area_distortion", None)  # per-face arrays: not kept (see the docstring)
        os.makedirs(os.path.dirname(output_path) or ".", exist_ok=True)
        write_mesh(output_path, sphere, faces)
        _write_json_atomically(report_path, report)  # after the mesh: its presence marks the item done
        report["batch"] = {"input": input_path, "output": output_path, "report": report_path,
                           "skipped": False, "seconds": time.monotonic() - start}
        return report
    except Exception as error:  # noqa: BLE001
        return BatchError.from_exception(index, error)


# ---------------------------------------------------------------------------------------------
# The client side.


class _Connection:
    """The client to use: a LocalCluster started here (closed at the end), a connection to a
    scheduler address (closed at the end), or the caller's client (left open)."""

    def __init__(self, client, n_workers):
        self.client, self.owned = client, []
        try:
            import distributed
        except ImportError as error:
            raise ImportError(
                "sdot.batch needs Dask distributed (Debian: apt-get install python3-dask python3-distributed)"
            ) from error
        if client is None:
            if n_workers is not None and (not isinstance(n_workers, int) or isinstance(n_workers, bool) or n_workers < 1):
                raise ValueError(f"n_workers: must be a positive integer, got {n_workers!r}")
            cluster = distributed.LocalCluster(
                n_workers=n_workers or os.cpu_count() or 1,
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",  # any free port (the HTTP server starts even without bokeh)
            )
            self.owned.append(cluster)
            self.client = distributed.Client(cluster, set_as_default=False)
            self.owned.append(self.client)
        elif isinstance(client, str):
            if n_workers is not None:
                raise ValueError("n_workers: sizes the local cluster; a scheduler address brings its own workers")
            self.client = distributed.Client(client, set_as_default=False)
            self.owned.append(self.client)
        elif not isinstance(client, distributed.Client):
            raise TypeError(f"client: must be None, a distributed.Client or a scheduler address, got {type(client).__name__}")
        elif n_workers is not None:
            raise ValueError("n_workers: sizes the local cluster; a client brings its own workers")

    def __enter__(self):
        return self.client

    def __exit__(self, *exc):
        for thing in reversed(self.owned):
            thing.close()


class _Progress:
    """done/failed/skipped/total on one updating stderr line, or a callable given the counts."""

    def __init__(self, progress, total, label):
        if progress is not None and not isinstance(progress, bool) and not callable(progress):
            raise TypeError("progress: must be True, False or a callable")
        self.progress, self.total, self.label = progress, total, label
        self.done = self.failed = self.skipped = 0
        self.start = time.monotonic()
        self.drawn = 0.0

    def counts(self):
        return {"done": self.done, "failed": self.failed, "skipped": self.skipped, "total": self.total,
                "elapsed_s": time.monotonic() - self.start}

    def item(self, result):
        self.done += 1
        if isinstance(result, BatchError):
            self.failed += 1
        elif isinstance(result, dict) and result.get("batch", {}).get("skipped"):
            self.skipped += 1
        if callable(self.progress):
            self.progress(self.counts())
        self.draw(every=0.1)

    def draw(self, every=1.0, end=False):
        if self.progress is not True:
            return
        now = time.monotonic()
        if not end and now - self.drawn < every:
            return
        self.drawn = now
        c = self.counts()
        extra = f", {c['skipped']} skipped" if c["skipped"] else ""
        sys.stderr.write(
            f"\r{self.label}: {c['done']}/{c['total']} done, {c['failed']} failed{extra}, {c['elapsed_s']:.1f} s"
            + ("\n" if end else "")
        )
        sys.stderr.flush()


def _run(tasks, client, n_workers, progress, timeout, label):
    """Runs tasks [(function, args), ...] on the cluster and returns their results in order.

    At most about twice as many tasks as the cluster has threads are submitted at a time, so that
    a batch of thousands of items does not hold all their inputs on the scheduler at once;
    finished results are fetched and released as they come."""
    if timeout is not None and (isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or timeout <= 0):
        raise ValueError(f"timeout: must be a positive number of seconds, got {timeout!r}")
    meter = _Progress(progress, len(tasks), label)
    results = [None] * len(tasks)
    if not tasks:
        return results
    from distributed import as_completed

    with _Connection(client, n_workers) as dask_client:
        meter.start = time.monotonic()
        deadline = None if timeout is None else meter.start + timeout
        pending = {}  # future -> index
        completed = as_completed(loop=dask_client.loop, with_results=False)
        next_task, threads, counted, pause = 0, 0, 0.0, _POLL_S[0]
        try:
            while next_task < len(tasks) or pending:
                if next_task < len(tasks) and time.monotonic() - counted > 1.0:  # workers come and go
                    workers = dask_client.scheduler_info().get("workers", {}).values()
                    threads, counted = sum(w.get("nthreads", 1) for w in workers), time.monotonic()
                while next_task < len(tasks) and len(pending) < max(8, 2 * threads):
                    function, args = tasks[next_task]
                    with warnings.catch_warnings():
                        # The problem's arrays travel inside the task on purpose (not scattered to
                        # one worker first): a task whose worker dies is rerun from them elsewhere.
                        warnings.filterwarnings("ignore", message="Large object of size", category=UserWarning)
                        future = dask_client.submit(function, next_task, *args, pure=False, retries=_RETRIES)
                    pending[future] = next_task
                    completed.add(future)
                    next_task += 1
                finished = completed.next_batch(block=False) if completed.has_ready() else []
                for future in finished:
                    if future.status in ("lost", "pending"):
                        # Its result was lost with its worker before it was fetched: the scheduler
                        # computes it again, and it comes back through `completed`.
                        completed.add(future)
                        continue
                    index = pending.pop(future)
                    results[index] = _collect(future, index)
                    future.release()
                    meter.item(results[index])
                if finished:
                    pause = _POLL_S[0]
                else:
                    if deadline is not None and time.monotonic() > deadline:
                        break
                    meter.draw()
                    time.sleep(pause)
                    pause = min(2 * pause, _POLL_S[1])
        finally:
            for future in pending:
                future.cancel()
    for index, result in enumerate(results):
        if result is None:  # the timeout came first
            results[index] = BatchError(index, "TimeoutError", f"not finished within the batch's timeout of {timeout} s")
            meter.done += 1
            meter.failed += 1
    meter.draw(end=True)
    return results


def _collect(future, index):
    """The task's return value, or a BatchError for a task that erred outside the item's code
    (KilledWorker when workers kept dying while running it) or was cancelled."""
    if future.status == "finished":
        try:
            return future.result()
        except Exception as error:  # noqa: BLE001 - e.g. a result that cannot be unpickled here
            return BatchError.from_exception(index, error)
    if future.status == "error":
        error = future.exception()
        text = "".join(_traceback.format_tb(future.traceback())) if future.traceback() is not None else ""
        return BatchError(index, type(error).__name__, str(error), text)
    return BatchError(index, "CancelledError", f"the task was {future.status}")


def solve_many(problems, client=None, *, progress=True, n_workers=None, timeout=None):
    """Solves many transport problems on a Dask cluster, one task per problem.

    Parameters
    ----------
    problems : iterable of dicts, each the keyword arguments of one `sdot.solve` call, e.g.
        ``{"sites": array, "geometry": "sphere", "density": ..., "tolerance": 1e-9}``. Every value
        travels to a worker (pickled; density functions by cloudpickle).
    client : None (start a `distributed.LocalCluster` with `n_workers` single-threaded worker
        processes, one per core by default, and close it at the end), a `distributed.Client`
        (used and left open) or a scheduler address such as ``"tcp://scheduler:8786"``.
    progress : True: one updating line on stderr (done, failed, elapsed); False: nothing; a
        callable: called after each finished item with a dict (done, failed, skipped, total,
        elapsed_s).
    n_workers : worker processes of the local cluster (client=None only).
    timeout : seconds for the whole batch; items not finished by then are cancelled and come back
        as BatchError of type "TimeoutError". None: no limit.

    Returns
    -------
    A list in the order of `problems`: the `SolveResult` of each problem (the class `sdot.solve`
    returns), or a `BatchError` for a problem whose solve raised (its message is the one
    `sdot.solve` gives, naming the field and index) or whose workers kept dying. A problem that
    stops without converging is a SolveResult with its status, as with `sdot.solve`.

    Raises TypeError or ValueError, before anything runs, when `problems` is not an iterable of
    dicts or a dict has no "sites" or a key that `sdot.solve` does not take.
    """
    if isinstance(problems, (dict, str, bytes)) or not hasattr(problems, "__iter__"):
        raise TypeError(f"problems: must be an iterable of dicts of sdot.solve arguments, got {type(problems).__name__}")
    problems = list(problems)
    accepted = set(signature(_solve).parameters)
    for i, problem in enumerate(problems):
        if not isinstance(problem, dict):
            raise TypeError(f"problems[{i}]: must be a dict of sdot.solve arguments, got {type(problem).__name__}")
        unknown = sorted(set(problem) - accepted, key=str)
        if unknown:
            raise ValueError(f"problems[{i}]: {unknown[0]!r} is not an argument of sdot.solve")
        if "sites" not in problem:
            raise ValueError(f"problems[{i}]: has no 'sites'")
    return _run([(_solve_task, (problem,)) for problem in problems], client, n_workers, progress, timeout,
                "sdot.batch.solve_many")


def _report_path(output):
    return output + ".report.json"


def sphere_parameterization(inputs, outputs, client=None, *, progress=True, skip_existing=True, n_workers=None,
                            timeout=None, **options):
    """Maps many meshes onto the sphere (`sdot.sphere_parameterization`) on a Dask cluster, from
    files to files, one task per mesh.

    Each task reads ``inputs[i]`` (any format `sdot.read_mesh` reads), computes the map, writes
    the sphere mesh to ``outputs[i]`` (format by the name, as `sdot.write_mesh`; missing folders
    are created) and then the report to ``outputs[i] + ".report.json"``, both atomically (a
    temporary file in the same folder, renamed). The report is written last, so its presence
    marks the item finished: with `skip_existing`, a re-run skips the items whose output and
    report both exist and returns the report read from disk. A killed batch is resumed by
    running it again.

    Parameters
    ----------
    inputs, outputs : lists of paths, of the same length; outputs distinct and none an input.
        Workers open them: on a real cluster use absolute paths on a file system that every
        worker sees (relative paths are made absolute here, from the current folder).
    client, progress, n_workers, timeout : as in `solve_many`.
    skip_existing : skip the items already finished (see above); False recomputes every item.
    options : the options of `sdot.sphere_parameterization` (refine, reweightings, optimize,
        ot_tolerance, ...), the same for every mesh.

    Returns
    -------
    A list in the order of `inputs`: per item, the report dict of `sdot.sphere_parameterization`
    as written to the report file (the per-face ``area_distortion`` arrays are not kept: they
    are as large as the mesh), plus ``report["batch"]`` = {"input", "output", "report",
    "skipped", "seconds"}; or a `BatchError` for an item that failed (e.g. a ValueError naming
    the defects of a mesh that is not a closed genus-0 manifold, or a file that cannot be
    read). A failed item writes nothing.

    Raises TypeError or ValueError, before anything runs, for lists of different lengths, an
    output whose name says no mesh format, repeated outputs, an output that is an input, or an
    option that `sdot.sphere_parameterization` does not take.
    """
    def paths(value, name):
        if isinstance(value, (str, bytes, os.PathLike)) or not hasattr(value, "__iter__"):
            raise TypeError(f"{name}: must be a list of paths, got {type(value).__name__}")
        result = []
        for i, path in enumerate(value):
            if not isinstance(path, (str, os.PathLike)):
                raise TypeError(f"{name}[{i}]: must be a path, got {type(path).__name__}")
            result.append(os.path.abspath(os.fspath(path)))
        return result

    inputs, outputs = paths(inputs, "inputs"), paths(outputs, "outputs")
    if len(inputs) != len(outputs):
        raise ValueError(f"outputs: there are {len(outputs)} outputs for {len(inputs)} inputs")
    seen = {}
    for i, output in enumerate(outputs):
        if not _sdot.mesh_format(output):
            raise ValueError(f"outputs[{i}]: {output}: the name says no mesh format (use .off, .obj, .ply or a FreeSurfer name)")
        if output in seen:
            raise ValueError(f"outputs[{i}]: {output} is also outputs[{seen[output]}]")
        seen[output] = i
    for i, path in enumerate(inputs):
        if path in seen:
            raise ValueError(f"outputs[{seen[path]}]: {path} is inputs[{i}]; it would be overwritten")
    accepted = set(signature(_sphere_parameterization).parameters) - {"vertices", "faces", "progress"}
    for name in options:
        if name not in accepted:
            raise TypeError(f"{name}: not an option of sdot.sphere_parameterization ({', '.join(sorted(accepted))})")
    tasks = [(_sphere_task, (i, o, _report_path(o), options, bool(skip_existing))) for i, o in zip(inputs, outputs)]
    return _run(tasks, client, n_workers, progress, timeout, "sdot.batch.sphere_parameterization")
